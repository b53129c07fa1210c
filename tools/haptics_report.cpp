#include "tools/haptics_report.h"

#include <cstdio>
#include <map>
#include <string>

#include "haptics/tick_stats.h"

namespace incise {

nlohmann::json report_haptic_loop(const HapticLoop& loop, const TickStats& st, const std::vector<HapticEvent>& events) {
  std::printf("%s", format_tick_stats(st).c_str());
  if (loop.dropped() > 0)
    std::printf("haptics: %llu records or events dropped (the main loop drained too late)\n",
                static_cast<unsigned long long>(loop.dropped()));
  std::map<std::string, int> counts;
  for (const HapticEvent& e : events) ++counts[event_name(e.kind)];
  for (const auto& [name, n] : counts) std::printf("haptics: %d %s event%s\n", n, name.c_str(), n == 1 ? "" : "s");
  return {{"device", loop.device().describe()},
          {"scheduling", loop.scheduling()},
          {"rate_hz", loop.settings().rate_hz},
          {"force_limit_n", loop.force_limit()},
          {"ticks", st.ticks},
          {"period_ms", {{"median", st.period_median_ms}, {"p99", st.period_p99_ms}, {"max", st.period_max_ms}}},
          {"late_us", {{"median", st.late_median_us}, {"p99", st.late_p99_us}, {"max", st.late_max_us}}},
          {"late_over_0_5_ms", st.late_over_half_ms},
          {"compute_us", {{"median", st.compute_median_us}, {"p99", st.compute_p99_us}, {"max", st.compute_max_us}}},
          {"allocations", st.allocations},
          {"force_max_n", st.force_max},
          {"force_jump_max_n", st.jump_max},
          {"clamped_ticks", st.clamped},
          {"events", counts},
          {"dropped", loop.dropped()}};
}

}  // namespace incise
