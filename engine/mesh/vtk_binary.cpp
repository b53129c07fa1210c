#include "engine/mesh/vtk_binary.h"

#include <zlib.h>

#include <cmath>
#include <cstring>
#include <limits>

#include "engine/util/error.h"
#include "engine/util/file_io.h"

namespace incise::meshio {

namespace {

int b64(char c) {
  if (c >= 'A' && c <= 'Z') return c - 'A';
  if (c >= 'a' && c <= 'z') return c - 'a' + 26;
  if (c >= '0' && c <= '9') return c - '0' + 52;
  if (c == '+') return 62;
  if (c == '/') return 63;
  return -1;
}

template <class T>
T load(std::string_view in, size_t pos) {
  T v;
  std::memcpy(&v, in.data() + pos, sizeof(T));
  return v;
}

uint64_t header_int(std::string_view in, size_t pos, bool u64) {
  return u64 ? load<uint64_t>(in, pos) : load<uint32_t>(in, pos);
}

}  // namespace

std::string decode_vtk_base64(std::string_view text, const std::string& context) {
  std::string out;
  out.reserve(text.size() / 4 * 3);
  int group[4];
  int n = 0, pad = 0;
  for (char c : text) {
    if (c == ' ' || c == '\n' || c == '\r' || c == '\t') continue;
    if (c == '=') {
      if (n < 2) throw Error(context + ": misplaced '=' in the base64 data");
      group[n++] = 0;
      ++pad;
    } else {
      const int v = b64(c);
      if (v < 0 || pad > 0)
        throw Error(context + ": the base64 data holds " + (v < 0 ? "a character outside its alphabet" : "data after '='"));
      group[n++] = v;
    }
    if (n == 4) {
      const uint32_t w = (static_cast<uint32_t>(group[0]) << 18) | (static_cast<uint32_t>(group[1]) << 12) |
                         (static_cast<uint32_t>(group[2]) << 6) | static_cast<uint32_t>(group[3]);
      out.push_back(static_cast<char>((w >> 16) & 0xff));
      if (pad < 2) out.push_back(static_cast<char>((w >> 8) & 0xff));
      if (pad < 1) out.push_back(static_cast<char>(w & 0xff));
      n = pad = 0;  // the next group may start a new, separately encoded segment
    }
  }
  if (n != 0) throw Error(context + ": the base64 data ends inside a 4-character group (truncated?)");
  return out;
}

std::string read_vtk_block(std::string_view in, size_t& pos, const VtkBlockFormat& fmt, const std::string& context) {
  const size_t hs = fmt.uint64_header ? 8 : 4;
  auto need = [&](uint64_t bytes, const char* what) {
    if (bytes > in.size() || pos > in.size() - bytes)
      throw Error(context + ": " + what + " needs " + std::to_string(bytes) + " bytes at offset " + std::to_string(pos) +
                  " but the data has " + std::to_string(in.size() - std::min(pos, in.size())) + " left (truncated?)");
  };
  if (!fmt.zlib) {
    need(hs, "the block header");
    const uint64_t n = header_int(in, pos, fmt.uint64_header);
    pos += hs;
    need(n, "the block");
    std::string out(in.substr(pos, n));
    pos += n;
    return out;
  }
  need(3 * hs, "the compressed block header");
  const uint64_t nblocks = header_int(in, pos, fmt.uint64_header);
  const uint64_t bsize = header_int(in, pos + hs, fmt.uint64_header);
  const uint64_t last = header_int(in, pos + 2 * hs, fmt.uint64_header);
  if (nblocks > (in.size() - pos) / hs) throw Error(context + ": the compressed header claims " + std::to_string(nblocks) + " blocks, more than the data holds");
  need((3 + nblocks) * hs, "the compressed block header");
  const uint64_t total = nblocks == 0 ? 0 : (nblocks - 1) * bsize + (last == 0 ? bsize : last);
  if (nblocks > 0 && (bsize == 0 || total / nblocks > bsize)) throw Error(context + ": inconsistent compressed block sizes");
  if (total > kMaxMeshBytes)
    throw Error(context + ": a block of " + std::to_string(total) + " bytes is beyond the limit of " +
                std::to_string(kMaxMeshBytes >> 30) + " GiB for mesh data");
  std::vector<uint64_t> csize(nblocks);
  uint64_t compressed = 0;
  for (uint64_t b = 0; b < nblocks; ++b) {
    csize[b] = header_int(in, pos + (3 + b) * hs, fmt.uint64_header);
    if (csize[b] > in.size()) throw Error(context + ": a compressed block of " + std::to_string(csize[b]) + " bytes is larger than the data");
    compressed += csize[b];
  }
  // zlib expands at most about 1032:1: a header that claims more is wrong,
  // and is refused before anything that large is allocated.
  if (total > 1100 * compressed + 1024)
    throw Error(context + ": the header claims " + std::to_string(total) + " bytes from " + std::to_string(compressed) +
                " compressed, more than zlib can expand");
  pos += (3 + nblocks) * hs;
  // Grown block by block, each checked against its own compressed size, so
  // memory follows the data actually there, not what the header claims.
  std::string out;
  size_t at = 0;
  for (uint64_t b = 0; b < nblocks; ++b) {
    need(csize[b], "a compressed block");
    const uint64_t want = b + 1 == nblocks && last != 0 ? last : bsize;
    if (want > 1100 * csize[b] + 1024)
      throw Error(context + ": zlib block " + std::to_string(b) + " claims " + std::to_string(want) + " bytes from " +
                  std::to_string(csize[b]) + " compressed, more than zlib can expand");
    out.resize(at + want);
    uLongf len = static_cast<uLongf>(want);
    const int rc = uncompress(reinterpret_cast<Bytef*>(&out[at]), &len, reinterpret_cast<const Bytef*>(in.data() + pos),
                              static_cast<uLong>(csize[b]));
    if (rc != Z_OK || len != (b + 1 == nblocks && last != 0 ? last : bsize))
      throw Error(context + ": zlib block " + std::to_string(b) + " does not decompress to its stated size (zlib error " +
                  std::to_string(rc) + ")");
    pos += csize[b];
    at += len;
  }
  return out;
}

std::string decode_inline_block(std::string_view text, const VtkBlockFormat& fmt, const std::string& context) {
  // The whole text decodes as concatenated padded segments (decode_vtk_base64),
  // however the writer split header and data; the block must fill it.
  const std::string bytes = decode_vtk_base64(text, context);
  size_t pos = 0;
  std::string out = read_vtk_block(bytes, pos, fmt, context);
  if (pos != bytes.size())
    throw Error(context + ": " + std::to_string(bytes.size() - pos) + " bytes after the block its header describes");
  return out;
}

namespace {

template <class T, class Out>
void convert(const std::string& bytes, std::vector<Out>& out) {
  const size_t n = bytes.size() / sizeof(T);
  out.resize(n);
  for (size_t i = 0; i < n; ++i) out[i] = static_cast<Out>(load<T>(bytes, i * sizeof(T)));
}

template <class Out>
std::vector<Out> values(const std::string& bytes, const std::string& type, const std::string& context) {
  struct Kind {
    const char* name;
    size_t size;
  };
  static const Kind kinds[] = {{"Int8", 1},  {"UInt8", 1},  {"Int16", 2},  {"UInt16", 2},  {"Int32", 4},
                               {"UInt32", 4}, {"Int64", 8},  {"UInt64", 8}, {"Float32", 4}, {"Float64", 8}};
  size_t size = 0;
  for (const Kind& k : kinds)
    if (type == k.name) size = k.size;
  if (size == 0) throw Error(context + ": DataArray type \"" + type + "\" is not supported; allowed: Int8-64, UInt8-64, Float32, Float64");
  if (bytes.size() % size) throw Error(context + ": " + std::to_string(bytes.size()) + " bytes is not a whole number of " + type);
  std::vector<Out> out;
  if (type == "Int8") convert<int8_t>(bytes, out);
  else if (type == "UInt8") convert<uint8_t>(bytes, out);
  else if (type == "Int16") convert<int16_t>(bytes, out);
  else if (type == "UInt16") convert<uint16_t>(bytes, out);
  else if (type == "Int32") convert<int32_t>(bytes, out);
  else if (type == "UInt32") convert<uint32_t>(bytes, out);
  else if (type == "Int64") convert<int64_t>(bytes, out);
  else if (type == "UInt64") convert<uint64_t>(bytes, out);
  else if (type == "Float32") convert<float>(bytes, out);
  else convert<double>(bytes, out);
  return out;
}

}  // namespace

std::vector<double> vtk_values_as_double(const std::string& bytes, const std::string& type, const std::string& context) {
  return values<double>(bytes, type, context);
}

std::vector<long long> vtk_values_as_int(const std::string& bytes, const std::string& type, const std::string& context) {
  if (type == "Float32" || type == "Float64") throw Error(context + ": an integer DataArray has type " + type);
  if (type == "UInt64") {
    std::vector<long long> out = values<long long>(bytes, "Int64", context);
    for (long long v : out)
      if (v < 0) throw Error(context + ": a UInt64 value beyond the range of a signed 64-bit integer");
    return out;
  }
  return values<long long>(bytes, type, context);
}

}  // namespace incise::meshio
