// Tick statistics (haptics/tick_stats.h) on records whose figures are known:
// periods, lateness, compute time, allocations, force jumps and clamping;
// and the force log's columns.
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <random>
#include <sstream>

#include <gtest/gtest.h>

#include "haptics/tick_log.h"
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
  // percentiles from 0.1%-wide bins: within 0.05%; maxima exact
  EXPECT_NEAR(s.period_median_ms, 1.0, 5e-4);
  EXPECT_NEAR(s.period_max_ms, 1.7, 1e-9);
  EXPECT_EQ(s.late_over_half_ms, 1);
  EXPECT_NEAR(s.late_max_us, 700.0, 1e-6);
  EXPECT_NEAR(s.compute_median_us, 50.0, 50.0 * 5e-4);
  EXPECT_NEAR(s.compute_p99_us, 99.0, 99.0 * 5e-4);
  EXPECT_NEAR(s.compute_max_us, 100.0, 1e-9);
  EXPECT_EQ(s.allocations, 2u);
  EXPECT_EQ(s.max_allocations, 2u);
  EXPECT_NEAR(s.force_max, 1.0, 1e-12);
  EXPECT_NEAR(s.jump_max, 0.01, 1e-12);
  EXPECT_EQ(s.clamped, 6) << "0.95 .. 1.00 N";
  EXPECT_EQ(s.readings, 50);
  EXPECT_NE(format_tick_stats(s).find("late > 0.5 ms: 1 (1.000%)"), std::string::npos) << format_tick_stats(s);
}

TEST(TickStats, PercentilesOfAMillionTicksAreWithinTheBinWidthOfTheExactOnes) {
  // Periods, lateness and compute times spread over six decades, as a run
  // with stalls has: the running summary (constant memory) against the exact
  // nearest-rank order statistics of the kept values.
  std::mt19937 rng(3);
  std::lognormal_distribution<double> late(3.0, 2.0), compute(1.5, 0.8);
  TickSummary sum(1.0);
  std::vector<double> L, C, P;
  TickRecord r;
  double t = 0.0;
  for (int i = 0; i < 1000000; ++i) {
    r.deadline = 1e-3 * (i + 1);
    const double l = i % 1000 == 7 ? 0.0 : late(rng);  // some ticks exactly on time
    r.t = r.deadline + 1e-6 * l;
    r.compute_us = static_cast<float>(compute(rng));
    if (i > 0) P.push_back(1e3 * (r.t - t));
    t = r.t;
    L.push_back(1e6 * (r.t - r.deadline));
    C.push_back(r.compute_us);
    sum.add(r);
  }
  const TickStats s = sum.stats();
  const auto exact = [](std::vector<double> v, double p) {
    std::sort(v.begin(), v.end());
    return v[static_cast<size_t>(std::ceil(p * static_cast<double>(v.size()))) - 1];
  };
  for (double p : {0.5, 0.99}) {
    const double e_late = exact(L, p), e_comp = exact(C, p), e_per = exact(P, p);
    EXPECT_NEAR((p == 0.5 ? s.late_median_us : s.late_p99_us) / e_late, 1.0, 5e-4) << p;
    EXPECT_NEAR((p == 0.5 ? s.compute_median_us : s.compute_p99_us) / e_comp, 1.0, 5e-4) << p;
    EXPECT_NEAR((p == 0.5 ? s.period_median_ms : s.period_p99_ms) / e_per, 1.0, 5e-4) << p;
  }
  EXPECT_EQ(s.late_max_us, *std::max_element(L.begin(), L.end()));
  EXPECT_EQ(s.ticks, 1000000);
}

class ForceLog : public test::TempDirTest {};

TEST_F(ForceLog, WrittenInChunksEqualsWrittenWholeAndAnUnfinishedLogLeavesNoFile) {
  const std::vector<TickRecord> all = known();
  write_force_log(path("whole.csv"), all);
  write_device_stream(path("whole_dev.csv"), all);
  {
    TickLogWriter w(path("chunks.csv"), path("chunks_dev.csv"));
    for (size_t i = 0; i < all.size(); i += 33)  // a frame's ticks at a time
      w.append(std::vector<TickRecord>(all.begin() + i, all.begin() + std::min(all.size(), i + 33)));
    w.finish();
  }
  const auto text = [&](const std::string& f) {
    std::ifstream in(path(f));
    return std::string(std::istreambuf_iterator<char>(in), {});
  };
  EXPECT_EQ(text("chunks.csv"), text("whole.csv"));
  EXPECT_EQ(text("chunks_dev.csv"), text("whole_dev.csv"));
  const std::string dev = text("whole_dev.csv");
  EXPECT_EQ(std::count(dev.begin(), dev.end(), '\n'), 2 + 50);  // header lines + the fresh readings
  {
    TickLogWriter w(path("failed.csv"), "");
    w.append(all);
  }  // a run that failed before finish()
  int files = 0;
  for (const auto& e : std::filesystem::directory_iterator(dir_)) files += e.path().filename().string().rfind("failed", 0) == 0;
  EXPECT_EQ(files, 0);
}

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
