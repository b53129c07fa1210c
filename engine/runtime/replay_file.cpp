#include "engine/runtime/replay_file.h"

#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <limits>

#include <nlohmann/json.hpp>

#include "engine/util/error.h"
#include "engine/util/fnv.h"
#include "engine/util/json_depth.h"

namespace incise {

namespace {

constexpr char kMagic[8] = {'I', 'N', 'C', 'R', 'E', 'P', 'L', 'Y'};
constexpr size_t kHeader = sizeof kMagic + 4;
constexpr size_t kChunkOverhead = 4 + 8 + 8;  // tag, length, checksum
constexpr std::uint64_t kMaxFileBytes = 16ULL << 30;
constexpr std::uint64_t kMaxMetaBytes = 64ULL << 20;  // a scene's text is kilobytes; JSON parsing takes ~10x the bytes

template <class T>
void put(std::string& b, const T& v) {
  b.append(reinterpret_cast<const char*>(&v), sizeof v);
}

void put_pose(std::string& b, const ToolPose& p) {
  for (double x : p.p) put(b, x);
  for (double x : p.q) put(b, x);
  put(b, p.jaw);
}

std::string at_offset(size_t off) { return "offset " + std::to_string(off); }

// Bounds-checked reads from one chunk's payload; errors name the file, the
// chunk's offset and (in a frame) the frame.
class Cursor {
 public:
  Cursor(const std::string& what, const char* data, size_t n, size_t file_off, std::string context)
      : what_(what), p_(data), n_(n), off_(file_off), context_(std::move(context)) {}
  template <class T>
  T get(const char* field) {
    T v{};
    need(sizeof v, field);
    std::memcpy(&v, p_ + pos_, sizeof v);
    pos_ += sizeof v;
    return v;
  }
  double finite(const char* field) {
    const double x = get<double>(field);
    if (!std::isfinite(x)) fail(std::string(field) + " is not finite");
    return x;
  }
  ToolPose pose(const char* field, bool require_finite) {
    ToolPose p;
    for (double& x : p.p) x = require_finite ? finite(field) : get<double>(field);
    for (double& x : p.q) x = require_finite ? finite(field) : get<double>(field);
    p.jaw = require_finite ? finite(field) : get<double>(field);
    return p;
  }
  // A count of records of `record_bytes` each: refused before anything is
  // allocated when the payload left cannot hold them.
  size_t count(const char* field, size_t record_bytes) {
    const std::uint64_t n = get<std::uint64_t>(field);
    if (record_bytes > 0 && n > left() / record_bytes)
      fail(std::string(field) + " claims " + std::to_string(n) + " records, the chunk holds at most " +
           std::to_string(left() / record_bytes));
    return static_cast<size_t>(n);
  }
  std::string bytes(size_t n, const char* field) {
    need(n, field);
    std::string s(p_ + pos_, n);
    pos_ += n;
    return s;
  }
  size_t left() const { return n_ - pos_; }
  void done() const {
    if (pos_ != n_) fail(std::to_string(n_ - pos_) + " bytes left over at the end of the chunk");
  }
  [[noreturn]] void fail(const std::string& msg) const {
    throw Error(what_ + ": " + context_ + " (chunk at " + at_offset(off_) + "): " + msg);
  }

 private:
  void need(size_t k, const char* field) const {
    if (k > n_ - pos_) fail(std::string("ends inside ") + field);
  }
  const std::string& what_;
  const char* p_;
  size_t n_, pos_ = 0, off_;
  std::string context_;
};

ReplayMeta parse_meta(const Cursor& c, const std::string& text) {
  if (json_too_deep(text)) c.fail("META nests deeper than " + std::to_string(kMaxJsonDepth) + " levels");
  ReplayMeta m;
  try {
    const nlohmann::json j = nlohmann::json::parse(text);
    // nlohmann converts a double to an integer without a range check (undefined behaviour out of range).
    for (const char* key : {"mesh_hash", "snapshot_every"})
      if (!j.is_object() || !j.contains(key) || !j[key].is_number_integer())
        c.fail(std::string("META ") + key + " must be an integer");
    if (!j["mesh_hash"].is_number_unsigned()) c.fail("META mesh_hash must be an unsigned integer");
    const auto every = j["snapshot_every"].get<std::int64_t>();
    if (every < 0 || every > std::numeric_limits<int>::max()) c.fail("META snapshot_every must be in [0, 2^31)");
    m.engine_version = j.at("engine_version").get<std::string>();
    m.build = j.at("build").get<std::string>();
    m.scene_path = j.at("scene_path").get<std::string>();
    m.scene_text = j.at("scene_text").get<std::string>();
    for (const auto& p : j.at("patches")) m.patches.push_back(p.get<std::array<std::string, 3>>());
    m.mesh_file = j.at("mesh_file").get<std::string>();
    m.mesh_hash = j.at("mesh_hash").get<std::uint64_t>();
    m.compliance = j.at("compliance").get<std::vector<double>>();
    for (const auto& f : j.at("files")) {
      if (!f.is_array() || f.size() != 2 || !f[1].is_number_unsigned()) c.fail("META files must be [path, hash] pairs");
      m.files.emplace_back(f[0].get<std::string>(), f[1].get<std::uint64_t>());
    }
    m.snapshot_every = j.at("snapshot_every").get<int>();
  } catch (const nlohmann::json::exception& e) {
    c.fail(std::string("META is not the expected JSON: ") + e.what());
  }
  for (double x : m.compliance)
    if (!std::isfinite(x) || x < 0) c.fail("META compliance values must be finite and >= 0");
  if (m.snapshot_every < 0) c.fail("META snapshot_every must be >= 0");
  return m;
}

constexpr size_t kToolBytes = 16 * sizeof(double);
constexpr size_t kTickBytes = 4 + 8 + 8 * 8 + 4 + 1 + 3 * 8;

ReplayFrame parse_frame(Cursor& c, int expected) {
  ReplayFrame f;
  f.frame = c.get<std::int32_t>("frame");
  if (f.frame != expected) c.fail("frame " + std::to_string(f.frame) + " where frame " + std::to_string(expected) + " belongs");
  f.time = c.finite("time");
  f.late_factor_call = c.get<std::int32_t>("late_factor_call");
  if (f.late_factor_call < -1) c.fail("late_factor_call " + std::to_string(f.late_factor_call) + " (allowed: -1 or a call index)");
  f.cut_frame = c.get<std::uint8_t>("cut_frame") != 0;
  f.contacts = c.get<std::int32_t>("contacts");
  f.grasp_rows = c.get<std::int32_t>("grasp_rows");
  f.swept_triangles = c.get<std::int32_t>("swept_triangles");
  if (f.contacts < 0 || f.grasp_rows < 0 || f.swept_triangles < 0) c.fail("negative event count");
  f.tools.resize(c.count("instruments", kToolBytes));
  for (ToolFrame& t : f.tools) {
    t.before = c.pose("instrument pose", true);
    t.after = c.pose("instrument pose", true);
  }
  for (auto& h : f.hashes) h = c.get<std::uint64_t>("state hash");
  f.snapshot = c.bytes(c.count("snapshot", 1), "snapshot");
  c.done();
  return f;
}

}  // namespace

ReplayFile parse_replay(const std::string& b, const std::string& what) {
  ReplayFile r;
  r.bytes = b.size();
  if (b.size() < sizeof kMagic || std::memcmp(b.data(), kMagic, sizeof kMagic) != 0)
    throw Error(what + ": not an incise replay (it does not start with 'INCREPLY')");
  if (b.size() < kHeader) throw Error(what + ": truncated in the header (" + std::to_string(b.size()) + " bytes)");
  std::uint32_t version = 0;
  std::memcpy(&version, b.data() + sizeof kMagic, 4);
  if (version != kReplayVersion)
    throw Error(what + ": replay format version " + std::to_string(version) + "; this build reads version " +
                std::to_string(kReplayVersion));
  size_t off = kHeader;
  bool have_meta = false, ended = false;
  while (off < b.size()) {
    const std::string context = r.frames.empty() ? "before frame 1" : "after frame " + std::to_string(r.frames.size());
    if (ended) throw Error(what + ": " + std::to_string(b.size() - off) + " bytes after the END record at " + at_offset(off));
    if (b.size() - off < 12)
      throw Error(what + ": truncated at " + at_offset(off) + " (" + context + "): a chunk header needs 12 bytes, " +
                  std::to_string(b.size() - off) + " are left");
    char tag[5] = {0, 0, 0, 0, 0};
    std::memcpy(tag, b.data() + off, 4);
    std::uint64_t len = 0;
    std::memcpy(&len, b.data() + off + 4, 8);
    const size_t left = b.size() - off - 12;
    if (left < 8 || len > left - 8)
      throw Error(what + ": truncated at " + at_offset(off) + " (" + context + "): chunk '" + std::string(tag, strnlen(tag, 4)) +
                  "' declares " + std::to_string(len) + " bytes, " + std::to_string(left < 8 ? 0 : left - 8) + " are left");
    std::uint64_t sum = 0;
    std::memcpy(&sum, b.data() + off + 12 + len, 8);
    if (sum != fnv1a(b.data() + off, 12 + len))
      throw Error(what + ": checksum mismatch in the chunk at " + at_offset(off) + " (" + context +
                  "): the file is corrupted");
    const std::string t(tag, 4);
    Cursor c(what, b.data() + off + 12, len, off, t == "FRAM" ? "frame " + std::to_string(r.frames.size() + 1) : t);
    if (!have_meta && t != "META") c.fail("the first chunk must be META");
    if (t == "META") {
      if (have_meta) c.fail("a second META");
      if (len > kMaxMetaBytes) c.fail(std::to_string(len) + " bytes of META; at most 64 MiB is read");
      r.meta = parse_meta(c, c.bytes(len, "META"));
      have_meta = true;
    } else if (t == "FRAM") {
      r.frames.push_back(parse_frame(c, static_cast<int>(r.frames.size()) + 1));
      if (r.frames.back().tools.size() != r.meta.compliance.size())
        c.fail(std::to_string(r.frames.back().tools.size()) + " instrument poses for " +
               std::to_string(r.meta.compliance.size()) + " instruments");
    } else if (t == "TICK") {
      const size_t n = c.count("ticks", kTickBytes);
      for (size_t i = 0; i < n; ++i) {
        ReplayTick k;
        k.frame = c.get<std::int32_t>("tick frame");
        k.t = c.finite("tick time");
        k.raw = c.pose("tick pose", false);  // a device may report nan (haptics/input_guard.h)
        k.buttons = c.get<std::uint32_t>("buttons");
        k.have_reading = c.get<std::uint8_t>("have_reading") != 0;
        for (double& x : k.force) x = c.finite("tick force");
        r.ticks.push_back(k);
      }
      c.done();
    } else if (t == "END ") {
      const std::int32_t frames = c.get<std::int32_t>("frame count");
      if (frames != static_cast<std::int32_t>(r.frames.size()))
        c.fail("END counts " + std::to_string(frames) + " frames, the file holds " + std::to_string(r.frames.size()));
      r.end_status = c.bytes(c.count("status", 1), "status");
      c.done();
      ended = true;
    } else {
      c.fail("unknown chunk type (allowed: META, FRAM, TICK, END)");
    }
    off += kChunkOverhead + len;
  }
  if (!have_meta) throw Error(what + ": truncated after the header: no META record");
  if (!ended)
    throw Error(what + ": truncated at " + at_offset(b.size()) + " after frame " + std::to_string(r.frames.size()) +
                ": no END record (the recording was cut off)");
  return r;
}

namespace {

std::string read_regular_file(const std::string& path, const char* what) {
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) throw Error(path + ": no such " + std::string(what) + " file");
  if (!std::filesystem::is_regular_file(path, ec))
    throw Error(path + ": not a regular file (a " + what + " must be a file, not a folder, device or pipe)");
  const std::uint64_t size = std::filesystem::file_size(path, ec);
  if (ec) throw Error(path + ": cannot read its size: " + ec.message());
  if (size > kMaxFileBytes) throw Error(path + ": " + std::to_string(size) + " bytes; a " + what + " may have at most 16 GiB");
  std::ifstream is(path, std::ios::binary);
  if (!is) throw Error(path + ": cannot open");
  std::string b(static_cast<size_t>(size), '\0');
  if (!is.read(b.data(), static_cast<std::streamsize>(size))) throw Error(path + ": read failed");
  return b;
}

}  // namespace

ReplayFile read_replay(const std::string& path) { return parse_replay(read_regular_file(path, "replay"), path); }

std::uint64_t replay_file_hash(const std::string& path, const char* what) {
  const std::string b = read_regular_file(path, what);
  return fnv1a(b.data(), b.size());
}

ReplayWriter::ReplayWriter(std::string path, const ReplayMeta& m) : path_(std::move(path)), tmp_(path_ + ".tmp") {
  os_.open(tmp_, std::ios::binary | std::ios::trunc);
  if (!os_) throw Error(path_ + ": cannot write the replay (" + tmp_ + ")");
  os_.write(kMagic, sizeof kMagic);
  const std::uint32_t version = kReplayVersion;
  os_.write(reinterpret_cast<const char*>(&version), 4);
  bytes_ = kHeader;
  nlohmann::json patches = nlohmann::json::array();
  for (const auto& p : m.patches) patches.push_back(p);
  const nlohmann::json j = {{"engine_version", m.engine_version}, {"build", m.build},
                            {"scene_path", m.scene_path},         {"scene_text", m.scene_text},
                            {"patches", patches},                 {"mesh_file", m.mesh_file},
                            {"mesh_hash", m.mesh_hash},           {"compliance", m.compliance},
                            {"files", m.files},                   {"snapshot_every", m.snapshot_every}};
  buf_ = j.dump();
  try {
    chunk("META");
  } catch (...) {  // no destructor runs for a constructor that throws
    os_.close();
    std::remove(tmp_.c_str());
    throw;
  }
}

ReplayWriter::~ReplayWriter() {
  if (finished_) return;
  os_.close();
  std::remove(tmp_.c_str());
}

void ReplayWriter::chunk(const char tag[4]) {
  std::string head(tag, 4);
  put<std::uint64_t>(head, buf_.size());
  const std::uint64_t sum = fnv1a(buf_.data(), buf_.size(), fnv1a(head.data(), head.size()));
  os_.write(head.data(), static_cast<std::streamsize>(head.size()));
  os_.write(buf_.data(), static_cast<std::streamsize>(buf_.size()));
  os_.write(reinterpret_cast<const char*>(&sum), sizeof sum);
  if (!os_) throw Error(path_ + ": replay write failed (" + tmp_ + ")");
  bytes_ += kChunkOverhead + buf_.size();
}

void ReplayWriter::add_frame(const ReplayFrame& f) {
  buf_.clear();
  put<std::int32_t>(buf_, f.frame);
  put(buf_, f.time);
  put<std::int32_t>(buf_, f.late_factor_call);
  put<std::uint8_t>(buf_, f.cut_frame ? 1 : 0);
  put<std::int32_t>(buf_, f.contacts);
  put<std::int32_t>(buf_, f.grasp_rows);
  put<std::int32_t>(buf_, f.swept_triangles);
  put<std::uint64_t>(buf_, f.tools.size());
  for (const ToolFrame& t : f.tools) {
    put_pose(buf_, t.before);
    put_pose(buf_, t.after);
  }
  for (std::uint64_t h : f.hashes) put(buf_, h);
  put<std::uint64_t>(buf_, f.snapshot.size());
  buf_ += f.snapshot;
  chunk("FRAM");
  ++frames_;
}

void ReplayWriter::add_ticks(const std::vector<ReplayTick>& ticks) {
  if (ticks.empty()) return;
  buf_.clear();
  put<std::uint64_t>(buf_, ticks.size());
  for (const ReplayTick& k : ticks) {
    put<std::int32_t>(buf_, k.frame);
    put(buf_, k.t);
    put_pose(buf_, k.raw);
    put(buf_, k.buttons);
    put<std::uint8_t>(buf_, k.have_reading ? 1 : 0);
    for (double x : k.force) put(buf_, x);
  }
  chunk("TICK");
}

void ReplayWriter::finish(const std::string& status) {
  buf_.clear();
  put<std::int32_t>(buf_, frames_);
  put<std::uint64_t>(buf_, status.size());
  buf_ += status;
  chunk("END ");
  os_.close();
  if (!os_) throw Error(path_ + ": replay write failed (" + tmp_ + ")");
  std::error_code ec;
  std::filesystem::rename(tmp_, path_, ec);
  if (ec) throw Error(path_ + ": cannot move the replay into place: " + ec.message());
  finished_ = true;
}

}  // namespace incise
