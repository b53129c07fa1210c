// Keyframe trajectories: slerp against the analytic rotation, linear
// position and jaw, clamping, the shorter arc, and each malformed file with
// the line its message names.
#include "engine/runtime/trajectory.h"

#include <gtest/gtest.h>

#include "tests/tools/temp_dir_test.h"

#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>

#include "engine/util/error.h"

namespace fs = std::filesystem;

namespace incise {
namespace {

const double kPi = 3.14159265358979323846;
const std::string kHeader = "t,x,y,z,qw,qx,qy,qz\n";

class TrajectoryTest : public test::TempDirTest {
 protected:
  std::string write(const std::string& text) const {
    TempDirTest::write("traj.csv", text);
    return path("traj.csv");
  }
  Trajectory read(const std::string& text) const { return Trajectory::read(write(text)); }
  // The message read throws for `text`; must be "PATH:LINE: " + rest.
  void expect_error(const std::string& text, int line, const std::string& rest) const {
    const std::string path = write(text);
    try {
      Trajectory::read(path);
      ADD_FAILURE() << "no error for:\n" << text;
    } catch (const Error& e) {
      EXPECT_EQ(std::string(e.what()), path + ":" + std::to_string(line) + ": " + rest);
    }
  }
};

// Rotation by `angle` about z as (w, x, y, z).
std::array<double, 4> about_z(double angle) { return {std::cos(angle / 2), 0.0, 0.0, std::sin(angle / 2)}; }

TEST_F(TrajectoryTest, SlerpHalfwayToA90DegreeTurnIsThe45DegreeTurn) {
  const Trajectory tr = read(kHeader + "0, 0,0,0, 1,0,0,0\n2, 0,0,0, 0.7071067811865476,0,0,0.7071067811865476\n");
  const std::array<double, 4> q = tr.sample(1.0).q, ref = about_z(kPi / 4);
  for (int k = 0; k < 4; ++k) EXPECT_NEAR(q[k], ref[k], 1e-12) << k;
  // A quarter of the way: 22.5 degrees (slerp is uniform in angle, lerp is not).
  const std::array<double, 4> q4 = tr.sample(0.5).q, ref4 = about_z(kPi / 8);
  for (int k = 0; k < 4; ++k) EXPECT_NEAR(q4[k], ref4[k], 1e-12) << k;
}

TEST_F(TrajectoryTest, PositionAndJawAreLinearBetweenKeyframes) {
  const Trajectory tr = read("t,x,y,z,qw,qx,qy,qz,jaw\n0, 1,2,3, 1,0,0,0, 0\n1, 3,2,-1, 1,0,0,0, 0.5\n3, 3,6,-1, 1,0,0,0, 1\n");
  EXPECT_TRUE(tr.has_jaw());
  EXPECT_EQ(tr.end_time(), 3.0);
  const ToolPose a = tr.sample(0.25);
  EXPECT_NEAR(a.p[0], 1.5, 1e-15);
  EXPECT_NEAR(a.p[1], 2.0, 1e-15);
  EXPECT_NEAR(a.p[2], 2.0, 1e-15);
  EXPECT_NEAR(a.jaw, 0.125, 1e-15);
  const ToolPose b = tr.sample(2.5);  // three quarters of the second span
  EXPECT_NEAR(b.p[1], 5.0, 1e-15);
  EXPECT_NEAR(b.jaw, 0.875, 1e-15);
  const ToolPose k = tr.sample(1.0);  // on a keyframe
  EXPECT_EQ(k.p, (std::array<double, 3>{3, 2, -1}));
  EXPECT_EQ(k.jaw, 0.5);
}

TEST_F(TrajectoryTest, ClampedToTheFirstAndLastKeyframe) {
  const Trajectory tr = read(kHeader + "# comment\n\n1, 1,0,0, 1,0,0,0\n2, 2,0,0, 0,0,0,1\n");
  EXPECT_FALSE(tr.has_jaw());
  EXPECT_EQ(tr.sample(-5.0).p[0], 1.0);
  EXPECT_EQ(tr.sample(-5.0).q, (std::array<double, 4>{1, 0, 0, 0}));
  EXPECT_EQ(tr.sample(9.0).p[0], 2.0);
  EXPECT_EQ(tr.sample(9.0).q, (std::array<double, 4>{0, 0, 0, 1}));
  EXPECT_EQ(tr.sample(9.0).jaw, 0.0);
}

TEST_F(TrajectoryTest, ASingleKeyframeIsAFixedPose) {
  const Trajectory tr = read(kHeader + "0.5, 1,2,3, 0,1,0,0\n");
  EXPECT_EQ(tr.sample(0.0).p, (std::array<double, 3>{1, 2, 3}));
  EXPECT_EQ(tr.sample(7.0).q, (std::array<double, 4>{0, 1, 0, 0}));
}

TEST_F(TrajectoryTest, SlerpTakesTheShorterArc) {
  // -q(90 deg) is the same rotation; halfway must still be the 45 degree turn
  // (the longer arc would give 45 - 180 degrees).
  const Trajectory tr = read(kHeader + "0, 0,0,0, 1,0,0,0\n1, 0,0,0, -0.7071067811865476,0,0,-0.7071067811865476\n");
  const std::array<double, 4> q = tr.sample(0.5).q, ref = about_z(kPi / 4);
  const double sign = q[0] < 0 ? -1.0 : 1.0;  // q and -q: either sign is the rotation
  for (int k = 0; k < 4; ++k) EXPECT_NEAR(sign * q[k], ref[k], 1e-12) << k;
  // Direct: 170 degrees to -170 degrees about z passes through 180, not 0.
  const std::array<double, 4> m = slerp(about_z(kPi * 170 / 180), about_z(-kPi * 170 / 180), 0.5);
  EXPECT_NEAR(std::abs(m[3]), 1.0, 1e-12);
  EXPECT_NEAR(m[0], 0.0, 1e-12);
}

TEST_F(TrajectoryTest, NearlyParallelQuaternionsInterpolateSmoothly) {
  const std::array<double, 4> a = about_z(0.0), b = about_z(1e-9);
  const std::array<double, 4> m = slerp(a, b, 0.5), ref = about_z(0.5e-9);
  for (int k = 0; k < 4; ++k) EXPECT_NEAR(m[k], ref[k], 1e-15) << k;
  const std::array<double, 4> same = slerp(a, a, 0.3);
  for (int k = 0; k < 4; ++k) EXPECT_EQ(same[k], a[k]);
}

TEST_F(TrajectoryTest, SpacesAroundFieldsAndCrLfAreTolerated) {
  const Trajectory tr = read(" t , x , y , z , qw , qx , qy , qz , jaw\r\n 0 , 1 , 2 , 3 , 1 , 0 , 0 , 0 , 0.25\r\n");
  EXPECT_EQ(tr.sample(0.0).p[2], 3.0);
  EXPECT_EQ(tr.sample(0.0).jaw, 0.25);
}

// --- malformed files --------------------------------------------------------------

TEST_F(TrajectoryTest, BadHeader) {
  expect_error("# header follows\nt,x,y,z,qx,qy,qz,qw\n0,0,0,0,1,0,0,0\n", 2,
               "the header must be t,x,y,z,qw,qx,qy,qz or t,x,y,z,qw,qx,qy,qz,jaw, got \"t,x,y,z,qx,qy,qz,qw\"");
  expect_error("0,0,0,0,1,0,0,0\n", 1,
               "the header must be t,x,y,z,qw,qx,qy,qz or t,x,y,z,qw,qx,qy,qz,jaw, got \"0,0,0,0,1,0,0,0\"");
}

TEST_F(TrajectoryTest, WrongFieldCount) {
  expect_error(kHeader + "0,0,0,0,1,0,0,0\n1,0,0,0,1,0,0\n", 3, "expected 8 values (as the header on line 1), got 7");
  expect_error(kHeader + "0,0,0,0,1,0,0,0,1\n", 2, "expected 8 values (as the header on line 1), got 9");
}

TEST_F(TrajectoryTest, NotANumberOrNaN) {
  expect_error(kHeader + "0,0,nan,0,1,0,0,0\n", 2, "y must be a finite number, got nan");
  expect_error(kHeader + "0,0,0,0,1,0,0,abc\n", 2, "qz must be a number, got \"abc\"");
  expect_error(kHeader + "0,0,,0,1,0,0,0\n", 2, "y must be a number, got \"\"");
  expect_error(kHeader + "0,0,0,0,1,0,0,inf\n", 2, "qz must be a finite number, got inf");
}

// Finite but huge: interpolating from x = 1.7e308 to -1.7e308 gave an
// infinite pose, and times that far apart froze it at the first keyframe.
TEST_F(TrajectoryTest, HugeTimesOrPositions) {
  expect_error(kHeader + "0,1.7e308,0,0,1,0,0,0\n1,-1.7e308,0,0,1,0,0,0\n", 2,
               "x must be within [-1e12, 1e12], got 1.7e308");
  expect_error(kHeader + "-1.7e308,0,0,0,1,0,0,0\n", 2, "t must be within [-1e12, 1e12], got -1.7e308");
}

TEST_F(TrajectoryTest, DecreasingOrRepeatedTime) {
  expect_error(kHeader + "0,0,0,0,1,0,0,0\n1,0,0,0,1,0,0,0\n# back in time\n0.5,0,0,0,1,0,0,0\n", 5,
               "time must increase strictly: t = 0.5 follows t = 1 (line 3)");
  expect_error(kHeader + "0,0,0,0,1,0,0,0\n0,0,0,0,1,0,0,0\n", 3, "time must increase strictly: t = 0 follows t = 0 (line 2)");
}

TEST_F(TrajectoryTest, NonUnitQuaternion) {
  expect_error(kHeader + "0,0,0,0,1,0,0,0\n1,0,0,0,1,0,0,0.1\n", 3,
               "the quaternion qw,qx,qy,qz must have unit norm (within 1e-3), got norm 1.004987562");
  expect_error(kHeader + "0,0,0,0,0,0,0,0\n", 2, "the quaternion qw,qx,qy,qz must have unit norm (within 1e-3), got norm 0");
  // A tracker's export rounded to 4 decimals (norm 0.99999) is accepted and normalised.
  const ToolPose r = read(kHeader + "0,0,0,0,0.7071,0,0,0.7071\n").sample(0.0);
  EXPECT_NEAR(r.q[0], std::sqrt(0.5), 1e-15);
  EXPECT_NEAR(r.q[3], std::sqrt(0.5), 1e-15);
  // Within the tolerance it is accepted (and normalised).
  const ToolPose p = read(kHeader + "0,0,0,0,1.0000005,0,0,0\n").sample(0.0);
  EXPECT_EQ(p.q[0], 1.0);
}

TEST_F(TrajectoryTest, JawOutOfRange) {
  expect_error("t,x,y,z,qw,qx,qy,qz,jaw\n0,0,0,0,1,0,0,0,0\n1,0,0,0,1,0,0,0,1.5\n", 3,
               "jaw must be in [0, 1] (0 open .. 1 closed), got 1.5");
  expect_error("t,x,y,z,qw,qx,qy,qz,jaw\n0,0,0,0,1,0,0,0,-0.1\n", 2, "jaw must be in [0, 1] (0 open .. 1 closed), got -0.1");
}

TEST_F(TrajectoryTest, EmptyFileOrNoKeyframe) {
  expect_error("", 1, "no header: expected t,x,y,z,qw,qx,qy,qz[,jaw] and at least one keyframe");
  expect_error("# only a comment\n\n", 2, "no header: expected t,x,y,z,qw,qx,qy,qz[,jaw] and at least one keyframe");
  expect_error(kHeader + "# nothing\n", 2, "no keyframe after the header on line 1; at least one is needed");
}

TEST_F(TrajectoryTest, MissingFile) {
  const std::string path = (dir_ / "nope.csv").string();
  try {
    Trajectory::read(path);
    ADD_FAILURE() << "no error";
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()), path + ": cannot open trajectory file: No such file or directory");
  }
}

}  // namespace
}  // namespace incise
