// Fuzzes the CSV readers: probe points (tools/probe_points.cpp,
// read_probe_points: a path, so the text is written to a private folder) and
// instrument trajectories (engine/runtime/trajectory.cpp, Trajectory::parse,
// then sample() at a few times).
//
// Input: one selector byte ('p' probe, 't' trajectory; others: value mod 2),
// then the file's text. Only incise::Error may escape; what is returned must
// be finite (points; sampled poses with unit quaternions).
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>

#include "engine/runtime/trajectory.h"
#include "engine/util/error.h"
#include "fuzz/fuzz_tmp.h"
#include "tools/probe_points.h"

namespace {

[[noreturn]] void bad(const char* what) {
  std::fprintf(stderr, "fuzz_csv: an accepted file gave inconsistent data: %s\n", what);
  std::abort();
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  fuzz_tmp::init("incise-fuzz-csv.", {"in.csv"});
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size < 1) return 0;
  const bool probe = data[0] == 'p' || (data[0] != 't' && data[0] % 2 == 0);
  const char* text = reinterpret_cast<const char*>(data + 1);
  try {
    if (probe) {
      for (const auto& p : incise::read_probe_points(fuzz_tmp::put("in.csv", text, size - 1)))
        for (double x : p)
          if (!std::isfinite(x)) bad("a non-finite probe coordinate");
    } else {
      const incise::Trajectory tr = incise::Trajectory::parse(std::string(text, size - 1), "in.csv");
      for (double t : {-1.0, 0.0, 0.5, 1.0, 1e9, static_cast<double>(NAN)}) {
        const incise::ToolPose p = tr.sample(t);
        double q2 = 0;
        for (double x : p.q) q2 += x * x;
        for (double x : p.p)
          if (!std::isfinite(x)) bad("a non-finite sampled position");
        if (!(std::abs(q2 - 1.0) < 1e-6)) bad("a sampled quaternion without unit norm");
      }
    }
  } catch (const incise::Error&) {
    // the documented failure: "FILE:LINE: what was wrong"
  }
  return 0;
}
