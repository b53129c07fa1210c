// Tick statistics (haptics/tick_stats.h) on records whose figures are known:
// periods, lateness, compute time, allocations, force jumps and clamping;
// and the force log's columns.
#include <fstream>
#include <sstream>

#include <gtest/gtest.h>

#include "haptics/tick_stats.h"
#include "tests/tools/temp_dir_test.h"

namespace incise {
namespace {

// 100 ticks, 1 ms apart except tick 50, which woke 0.7 ms late (and the next
// on time); compute time i us; the force steps by 0.01 N per tick up to 1 N;
// tick 10 allocated twice.
std::vector<TickRecord> known() {
  std::vector<TickRecord> r(100);
  for (int i = 0; i < 100; ++i) {
    r[i].deadline = 1e-3 * (i + 1);
    r[i].t = r[i].deadline + (i == 50 ? 0.7e-3 : 0.0);
    r[i].compute_us = static_cast<float>(i + 1);
    r[i].force = {0.0, 0.0, 0.01 * (i + 1)};
    r[i].allocations = i == 10 ? 2 : 0;
    r[i].have_reading = r[i].raw.fresh = i % 2 == 0;
  }
  return r;
}

TEST(TickStats, FiguresOfKnownRecords) {
  const TickStats s = summarize_ticks(known(), 0.95);
  EXPECT_EQ(s.ticks, 100);
  EXPECT_NEAR(s.period_median_ms, 1.0, 1e-9);
  EXPECT_NEAR(s.period_max_ms, 1.7, 1e-9);
  EXPECT_EQ(s.late_over_half_ms, 1);
  EXPECT_NEAR(s.late_max_us, 700.0, 1e-6);
  EXPECT_NEAR(s.compute_median_us, 50.0, 1e-9);
  EXPECT_NEAR(s.compute_p99_us, 99.0, 1e-9);
  EXPECT_NEAR(s.compute_max_us, 100.0, 1e-9);
  EXPECT_EQ(s.allocations, 2u);
  EXPECT_EQ(s.max_allocations, 2u);
  EXPECT_NEAR(s.force_max, 1.0, 1e-12);
  EXPECT_NEAR(s.jump_max, 0.01, 1e-12);
  EXPECT_EQ(s.clamped, 6) << "0.95 .. 1.00 N";
  EXPECT_EQ(s.readings, 50);
  EXPECT_NE(format_tick_stats(s).find("late > 0.5 ms: 1 (1.000%)"), std::string::npos) << format_tick_stats(s);
}

class ForceLog : public test::TempDirTest {};

TEST_F(ForceLog, HasTheDocumentedColumns) {
  write_force_log(path("f.csv"), known());
  std::ifstream in(path("f.csv"));
  std::string header, line;
  std::getline(in, header);
  EXPECT_EQ(header, "t,fx,fy,fz,tick_us,late_us");
  int rows = 0;
  std::string row51;
  while (std::getline(in, line))
    if (++rows == 51) row51 = line;
  EXPECT_EQ(rows, 100);
  EXPECT_EQ(row51, "0.051700,0,0,0.51,51.00,700.00");
}

}  // namespace
}  // namespace incise
