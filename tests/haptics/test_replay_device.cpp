// The replay device (haptics/replay_device.h): a recorded stream plays back
// sample and hold, fresh once per sample; each malformed stream is an error
// naming the file, the line and what is allowed; the stream `incise run
// --haptics` writes (haptics/tick_stats.h) reads back as the readings it
// recorded, bit for bit.
#include <cmath>

#include <gtest/gtest.h>

#include "engine/util/error.h"
#include "haptics/replay_device.h"
#include "haptics/tick_stats.h"
#include "tests/tools/temp_dir_test.h"

namespace incise {
namespace {

const char* kHeader = "t,x,y,z,qw,qx,qy,qz,jaw,buttons\n";

TEST(ReplayDevice, PlaysSamplesAndHoldsThem) {
  ReplayDevice d = ReplayDevice::parse(std::string("# a comment\n\n") + kHeader +
                                           "0.010,1,2,3,1,0,0,0,0.5,3\n0.020,4,5,6,0,1,0,0,1,0\n0.030,nan,0,0,1,0,0,0,0,0\n",
                                       "rec.csv", 4.0);
  EXPECT_EQ(d.samples(), 3);
  EXPECT_EQ(d.max_force(), 4.0);
  d.start();
  DeviceSample s;
  EXPECT_FALSE(d.read(0.005, s)) << "nothing before the first sample";
  ASSERT_TRUE(d.read(0.010, s));
  EXPECT_TRUE(s.fresh);
  EXPECT_EQ(s.pose.p, (std::array<double, 3>{1, 2, 3}));
  EXPECT_EQ(s.pose.jaw, 0.5);
  EXPECT_EQ(s.buttons, 3u);
  ASSERT_TRUE(d.read(0.015, s));
  EXPECT_FALSE(s.fresh) << "held, not new";
  EXPECT_EQ(s.pose.p[0], 1.0);
  ASSERT_TRUE(d.read(0.025, s));
  EXPECT_TRUE(s.fresh);
  EXPECT_EQ(s.pose.q, (std::array<double, 4>{0, 1, 0, 0}));
  ASSERT_TRUE(d.read(1.0, s));
  EXPECT_TRUE(std::isnan(s.pose.p[0])) << "recorded bad readings come back for the loop's checks";
  d.start();
  EXPECT_FALSE(d.read(0.0, s)) << "start() rewinds";
}

TEST(ReplayDevice, MalformedStreamsNameTheLine) {
  auto error = [](const std::string& text) {
    try {
      ReplayDevice::parse(text, "rec.csv", 3.0);
    } catch (const Error& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_EQ(error(""), "rec.csv:1: no header: expected t,x,y,z,qw,qx,qy,qz,jaw,buttons");
  EXPECT_EQ(error("t,x,y,z\n"), "rec.csv:1: the header must be t,x,y,z,qw,qx,qy,qz,jaw,buttons, got 't,x,y,z'");
  EXPECT_EQ(error(kHeader), "rec.csv:1: no sample after the header; at least one is needed");
  EXPECT_EQ(error(std::string(kHeader) + "0,1,2,3,1,0,0,0,0\n"),
            "rec.csv:2: expected 10 values (t,x,y,z,qw,qx,qy,qz,jaw,buttons), got 9");
  EXPECT_EQ(error(std::string(kHeader) + "0,1,2,x3,1,0,0,0,0,0\n"), "rec.csv:2: z must be a number (nan and inf allowed), got 'x3'");
  EXPECT_EQ(error(std::string(kHeader) + "nan,1,2,3,1,0,0,0,0,0\n"), "rec.csv:2: t must be a finite number, got 'nan'");
  EXPECT_EQ(error(std::string(kHeader) + "0,1,2,3,1,0,0,0,0,-1\n"), "rec.csv:2: buttons must be an integer in [0, 2147483647], got '-1'");
  EXPECT_EQ(error(std::string(kHeader) + "0,1,2,3,1,0,0,0,0,1.5\n"), "rec.csv:2: buttons must be an integer in [0, 2147483647], got '1.5'");
  EXPECT_EQ(error(std::string(kHeader) + "0.2,1,2,3,1,0,0,0,0,0\n0.2,1,2,3,1,0,0,0,0,0\n"),
            "rec.csv:3: time must increase strictly: t = 0.2 follows t = 0.2");
  EXPECT_THROW(ReplayDevice::parse(std::string(kHeader) + "0,1,2,3,1,0,0,0,0,0\n", "rec.csv", 0.0), Error);
  try {
    ReplayDevice::read_file("/nonexistent/rec.csv", 3.0);
    ADD_FAILURE() << "no error";
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()).rfind("/nonexistent/rec.csv: cannot open", 0), 0u) << e.what();
  }
}

class RecordedStream : public test::TempDirTest {};

TEST_F(RecordedStream, TheWrittenStreamReadsBackAsRecorded) {
  std::vector<TickRecord> records(4);
  for (int i = 0; i < 4; ++i) {
    TickRecord& r = records[i];
    r.t = r.deadline = 1e-3 * (i + 1);
    r.have_reading = i != 1;   // tick 2: the device had nothing
    r.raw.fresh = i != 3;      // tick 4: nothing new
    r.raw.pose.p = {0.1 / 3.0 * i, -1e-17, 2.0 / 7.0};
    r.raw.pose.q = {std::sqrt(0.5), 0, std::sqrt(0.5), 0};
    r.raw.pose.jaw = 0.25;
    r.raw.buttons = 5u + i;
  }
  records[2].raw.pose.p[0] = std::nan("");
  write_device_stream(path("dev.csv"), records);
  ReplayDevice d = ReplayDevice::read_file(path("dev.csv"), 3.0);
  ASSERT_EQ(d.samples(), 2) << "fresh readings only";
  DeviceSample s;
  ASSERT_TRUE(d.read(0.001, s));
  EXPECT_EQ(s.pose.p, records[0].raw.pose.p) << "17 significant digits: bit for bit";
  EXPECT_EQ(s.pose.q, records[0].raw.pose.q);
  EXPECT_EQ(s.buttons, 5u);
  ASSERT_TRUE(d.read(0.003, s));
  EXPECT_TRUE(std::isnan(s.pose.p[0]));
  EXPECT_EQ(s.pose.p[2], 2.0 / 7.0);
  EXPECT_EQ(s.buttons, 7u);
}

}  // namespace
}  // namespace incise
