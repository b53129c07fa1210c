#pragma once
// Stage timers: each frame records milliseconds per stage, so a scene shows
// exactly what it spends where (and that stages it does not need cost 0).
#include <array>
#include <chrono>

namespace incise {

// render: offscreen drawing and read-back of the frame, only when asked
// (`run --render`, `bench --render`); step() itself never renders.
enum Stage { kStageAssembly, kStageFactorization, kStageSolve, kStageRender, kStageOther, kNumStages };
inline constexpr std::array<const char*, kNumStages> kStageNames = {"assembly", "factorization", "solve", "render",
                                                                    "other"};

struct FrameTiming {
  std::array<double, kNumStages> ms{};  // per stage
  double frame_ms = 0.0;                // whole step, wall clock
};

class Stopwatch {
 public:
  Stopwatch() : t0_(std::chrono::steady_clock::now()) {}
  double ms() const {
    return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0_).count();
  }
  // Milliseconds since construction or the last lap.
  double lap() {
    const auto now = std::chrono::steady_clock::now();
    const double d = std::chrono::duration<double, std::milli>(now - t0_).count();
    t0_ = now;
    return d;
  }

 private:
  std::chrono::steady_clock::time_point t0_;
};

}  // namespace incise
