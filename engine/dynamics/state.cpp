#include "engine/dynamics/state.h"

#include <cmath>
#include <cstring>
#include <istream>
#include <limits>
#include <ostream>

#include "engine/model/model.h"
#include "engine/fem/polar.h"
#include "engine/util/error.h"
#include "engine/util/fnv.h"

namespace incise {

namespace {

// A field's hash: FNV-1a steps over whole 64-bit values rather than bytes,
// in four interleaved lanes folded at the end, so the record stage's hashes
// cost 0.1 ms, not 1 ms, per 10k-DOF frame. Every step is a bijection of its
// lane, so a change in any one value always changes the hash.
std::uint64_t fnv(const std::vector<double>& x, std::uint64_t h = kFnvOffset) {
  const std::uint64_t n = x.size();
  std::uint64_t lane[4] = {kFnvOffset, kFnvOffset ^ 1, kFnvOffset ^ 2, kFnvOffset ^ 3};
  size_t i = 0;
  for (; i + 4 <= x.size(); i += 4)
    for (int k = 0; k < 4; ++k) {
      std::uint64_t w;
      std::memcpy(&w, &x[i + k], sizeof w);
      lane[k] = (lane[k] ^ w) * kFnvPrime;
    }
  for (; i < x.size(); ++i) {
    std::uint64_t w;
    std::memcpy(&w, &x[i], sizeof w);
    lane[0] = (lane[0] ^ w) * kFnvPrime;
  }
  return fnv1a(lane, sizeof lane, fnv1a(&n, sizeof n, h));
}

// Format version 6 (5: no blade_done, read as empty; 4: no recovery flag
// either, read as false; 3: no du either, read as empty; 2: the byte-wise
// field hash; 1: no swept cuts).
constexpr char kMagic[8] = {'I', 'N', 'C', 'S', 'T', 'A', 'T', '6'};

template <class T>
void put(std::ostream& os, const T& v) {
  os.write(reinterpret_cast<const char*>(&v), sizeof v);
}

template <class T>
T get(std::istream& is, const std::string& what, const char* field) {
  T v{};
  const long long at = static_cast<long long>(is.tellg());
  if (!is.read(reinterpret_cast<char*>(&v), sizeof v))
    throw Error(what + ": state truncated in " + field + " (at byte " + std::to_string(at) + ")");
  return v;
}

}  // namespace

std::array<std::uint64_t, kNumStateFields> state_field_hashes(const State& s) {
  std::array<std::uint64_t, kNumStateFields> h{};
  h[kFieldClock] = fnv1a(&s.frame, sizeof s.frame, fnv1a(&s.time, sizeof s.time));
  // The recovery flag with the clock, only when set: states without it hash
  // as they did before the flag existed (recorded runs keep their hashes).
  if (s.recovery) {
    const unsigned char one = 1;
    h[kFieldClock] = fnv1a(&one, sizeof one, h[kFieldClock]);
  }
  h[kFieldU] = fnv(s.u);
  h[kFieldV] = fnv(s.du, fnv(s.v));
  h[kFieldA] = fnv(s.a);
  h[kFieldR] = fnv(s.R);
  h[kFieldTopology] = fnv(s.swept_frame, fnv(s.swept_tool, fnv(s.swept, fnv(s.cut_progress))));
  // blade_done likewise only when there is one (cut_front "enriched" with a scalpel).
  if (!s.blade_done.empty()) h[kFieldTopology] = fnv(s.blade_done, h[kFieldTopology]);
  return h;
}

std::uint64_t state_hash(const State& s) {
  const auto h = state_field_hashes(s);
  return fnv1a(h.data(), sizeof h);
}

void write_state(std::ostream& os, const State& s) {
  os.write(kMagic, sizeof kMagic);
  put(os, s.time);
  put<std::int64_t>(os, s.frame);
  for (const std::vector<double>* f :
       {&s.u, &s.v, &s.a, &s.R, &s.cut_progress, &s.swept, &s.swept_tool, &s.swept_frame, &s.du, &s.blade_done}) {
    put<std::uint64_t>(os, f->size());
    os.write(reinterpret_cast<const char*>(f->data()), static_cast<std::streamsize>(f->size() * sizeof(double)));
  }
  put<std::uint8_t>(os, s.recovery ? 1 : 0);
  put<std::uint64_t>(os, state_hash(s));
}

State read_state(std::istream& is, const std::string& what) {
  char magic[sizeof kMagic];
  // Version 3 files (no du), 4 (no recovery flag) and 5 (no blade_done) are
  // read too: the next step then starts from the velocity predictor, or as
  // an ordinary step, and scalpels' fronts stay on faces until a blade moves.
  const bool read = static_cast<bool>(is.read(magic, sizeof magic));
  const bool v3 = read && std::memcmp(magic, "INCSTAT3", 8) == 0;
  const bool v4 = read && std::memcmp(magic, "INCSTAT4", 8) == 0;
  const bool v5 = read && std::memcmp(magic, "INCSTAT5", 8) == 0;
  if (!read || (!v3 && !v4 && !v5 && std::memcmp(magic, kMagic, sizeof kMagic) != 0))
    throw Error(what + ": not an incise state file of version 3 to 6 (header 'INCSTAT6' expected)");
  // Bytes left, so a corrupted length is refused before anything is allocated.
  const auto here = is.tellg();
  is.seekg(0, std::ios::end);
  const long long left = static_cast<long long>(is.tellg() - here);
  is.seekg(here);
  State s;
  s.time = get<double>(is, what, "time");
  const std::int64_t frame = get<std::int64_t>(is, what, "frame");
  if (!std::isfinite(s.time) || frame < 0 || frame > std::numeric_limits<int>::max())
    throw Error(what + ": state time or frame out of range (time " + std::to_string(s.time) + ", frame " +
                std::to_string(frame) + ")");
  s.frame = static_cast<int>(frame);
  const char* names[] = {"u", "v", "a", "R", "cut_progress", "swept", "swept_tool", "swept_frame", "du", "blade_done"};
  std::vector<double>* fields[] = {&s.u,     &s.v,          &s.a,           &s.R,  &s.cut_progress,
                                   &s.swept, &s.swept_tool, &s.swept_frame, &s.du, &s.blade_done};
  for (int k = 0; k < (v3 ? 8 : v4 || v5 ? 9 : 10); ++k) {
    const std::uint64_t n = get<std::uint64_t>(is, what, names[k]);
    if (n > static_cast<std::uint64_t>(left) / sizeof(double))
      throw Error(what + ": state field " + names[k] + " claims " + std::to_string(n) + " values, more than the file holds");
    fields[k]->resize(n);
    if (!is.read(reinterpret_cast<char*>(fields[k]->data()), static_cast<std::streamsize>(n * sizeof(double))))
      throw Error(what + ": state truncated in " + names[k]);
    for (std::uint64_t i = 0; i < n; ++i)
      if (!std::isfinite((*fields[k])[i]))
        throw Error(what + ": state field " + names[k] + "[" + std::to_string(i) + "] is not finite");
  }
  if (!v3 && !v4) {
    const std::uint8_t flag = get<std::uint8_t>(is, what, "recovery");
    if (flag > 1) throw Error(what + ": state field recovery is " + std::to_string(flag) + ", not 0 or 1");
    s.recovery = flag == 1;
  }
  const std::uint64_t stored = get<std::uint64_t>(is, what, "hash");
  if (stored != state_hash(s)) throw Error(what + ": state hash mismatch (the file is corrupted)");
  return s;
}

void size_state(const Model& m, State& s) {
  const size_t n = static_cast<size_t>(m.ndof());
  s.u.assign(n, 0.0);
  s.v.assign(n, 0.0);
  s.a.assign(n, 0.0);
  s.du.clear();
  s.R = identity_rotations(m.nrot);
}

}  // namespace incise
