// The physical State as a value: copied, saved, restored and hashed.
#include <cmath>
#include <cstring>
#include <sstream>
#include <string>

#include <gtest/gtest.h>

#include "engine/dynamics/state.h"
#include "engine/dynamics/step.h"
#include "engine/util/error.h"
#include "tests/engine/test_util.h"

namespace incise {
namespace {

// A soft corotated beam fixed at x = 0, sagging and swinging under gravity:
// large rotations, adaptive Newton iterations.
Scene sagging_beam() {
  Scene s = test::basic_scene(2);
  s.material.young = 2e3;
  s.material.poisson = 0.4;
  s.material.rayleigh_mass = 0.1;
  s.gravity = {0.0, 0.0, -9.81};
  s.fixed.push_back(test::box_region({-1, -1, -1}, {1e-9, 2, 2}));
  return s;
}

void run(const Model& m, State& s, Workspace& ws, int frames) {
  for (int k = 0; k < frames; ++k) step(m, s, ws);
}

TEST(State, ACopySteppedOnAFreshWorkspaceMatchesBitForBit) {
  const Model m = build_model(make_beam(4, 1, 1, 6, 2, 2, 1), sagging_beam());
  State a;
  Workspace wa;
  init_state(m, a, wa);
  run(m, a, wa, 20);
  const State copy = a;  // mid-run, after the beam has started to swing
  State b = copy;
  Workspace wb;
  attach_state(m, b, wb);
  for (int k = 0; k < 100; ++k) {
    step(m, a, wa);
    step(m, b, wb);
    ASSERT_EQ(state_hash(a), state_hash(b)) << "frame " << a.frame;
  }
  EXPECT_TRUE(a == b);
  EXPECT_EQ(a.frame, 120);
  EXPECT_GT(wa.newton_iterations_done, 0);
  double umax = 0;
  for (double x : a.u) umax = std::max(umax, std::abs(x));
  EXPECT_GT(umax, 0.1) << "the beam moved: the test compares a real trajectory";
}

TEST(State, HashSeesEveryFieldAndOneBit) {
  const Model m = build_model(make_beam(2, 1, 1, 2, 1, 1, 1), sagging_beam());
  State s;
  Workspace ws;
  init_state(m, s, ws);
  run(m, s, ws, 3);
  s.cut_progress = {-1.0};
  const auto h0 = state_field_hashes(s);
  const std::uint64_t all = state_hash(s);
  ASSERT_EQ(s.du.size(), s.u.size()) << "a stepped state keeps its last increment";
  // (field, which vector): du is hashed with v (kStateFieldNames: "v/du")
  for (int field_du : {kFieldU, kFieldV, kFieldA, kFieldR, kFieldTopology, kNumStateFields}) {
    const int field = field_du == kNumStateFields ? kFieldV : field_du;
    State t = s;
    std::vector<double>* f[] = {nullptr, &t.u, &t.v, &t.a, &t.R, &t.cut_progress, &t.du};
    std::uint64_t bits;
    std::memcpy(&bits, f[field_du]->data(), sizeof bits);
    bits ^= 1;  // the last bit of the mantissa of the first value
    std::memcpy(f[field_du]->data(), &bits, sizeof bits);
    const auto h = state_field_hashes(t);
    for (int k = 0; k < kNumStateFields; ++k)
      EXPECT_EQ(h[k] != h0[k], k == field) << kStateFieldNames[k] << " when " << kStateFieldNames[field] << " changed";
    EXPECT_NE(state_hash(t), all);
  }
  State t = s;
  t.frame += 1;
  EXPECT_NE(state_field_hashes(t)[kFieldClock], h0[kFieldClock]);
}

TEST(State, SaveAndRestoreKeepTheHashAndTheTrajectory) {
  const Model m = build_model(make_beam(4, 1, 1, 4, 2, 2, 1), sagging_beam());
  State a;
  Workspace wa;
  init_state(m, a, wa);
  run(m, a, wa, 10);
  std::stringstream file;
  write_state(file, a);
  State b = read_state(file, "saved.state");
  EXPECT_EQ(state_hash(b), state_hash(a));
  EXPECT_TRUE(b == a);
  Workspace wb;
  attach_state(m, b, wb);
  run(m, a, wa, 30);
  run(m, b, wb, 30);
  EXPECT_EQ(state_hash(b), state_hash(a));
}

std::string saved(const State& s) {
  std::stringstream os;
  write_state(os, s);
  return os.str();
}

std::string read_error(const std::string& bytes) {
  std::stringstream is(bytes);
  try {
    read_state(is, "run.state");
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

TEST(State, DamagedFilesAreRefusedWithTheField) {
  State s;
  s.time = 0.5;
  s.frame = 15;
  s.u = {1, 2, 3};
  s.v = {0, 0, 0};
  s.a = {0, 0, 1};
  s.R = {1, 0, 0, 0, 1, 0, 0, 0, 1};
  s.cut_progress = {0.25};
  s.swept = {0, 0, 0, 1, 0, 0, 0, 1, 0};
  s.swept_tool = {0};
  s.swept_frame = {3};
  const std::string good = saved(s);
  EXPECT_EQ(read_error(good), "");
  EXPECT_NE(read_error("INCSTAT2" + good.substr(8)).find("not an incise state file of version 3 to 6"), std::string::npos);
  {
    // A version 5 file (no blade_done: the 8 bytes of its empty length
    // before the recovery flag dropped) is read with blade_done empty; a
    // version 4 file (no recovery flag either) with the flag off; a version
    // 3 file (no du either: the 8 bytes of its empty length dropped too)
    // with du empty. Their hash is the same.
    const std::string body = good.substr(8, good.size() - 25);  // header, blade_done's length, flag and hash off
    const std::string v5 = "INCSTAT5" + body + good.substr(good.size() - 9);
    std::stringstream is5(v5);
    EXPECT_TRUE(read_state(is5, "old.state") == s);
    const std::string v4 = "INCSTAT4" + body + good.substr(good.size() - 8);
    std::stringstream is4(v4);
    const State r4 = read_state(is4, "old.state");
    EXPECT_TRUE(r4 == s);
    EXPECT_FALSE(r4.recovery);
    const std::string v3 = "INCSTAT3" + body.substr(0, body.size() - 8) + good.substr(good.size() - 8);
    std::stringstream is(v3);
    const State r = read_state(is, "old.state");
    EXPECT_TRUE(r == s);
    EXPECT_TRUE(r.du.empty());
  }
  {
    // The recovery flag (the next step is a recovery step) is kept, enters
    // the hash only when set, and a byte other than 0 or 1 is refused.
    State rec = s;
    rec.recovery = true;
    EXPECT_NE(state_hash(rec), state_hash(s));
    const std::string bytes = saved(rec);
    std::stringstream is(bytes);
    EXPECT_TRUE(read_state(is, "rec.state") == rec);
    std::string two = bytes;
    two[two.size() - 9] = 2;
    EXPECT_NE(read_error(two).find("state field recovery is 2, not 0 or 1"), std::string::npos) << read_error(two);
  }
  {
    // A scalpel's blade_done (cut_front "enriched") is kept and enters the
    // hash only when there is one.
    State out = s;
    out.blade_done = {0, 24, 1, 10};
    EXPECT_NE(state_hash(out), state_hash(s));
    const std::string bytes = saved(out);
    std::stringstream is(bytes);
    EXPECT_TRUE(read_state(is, "out.state") == out);
  }
  // Cut inside u's values (u's length at byte 24, its values from byte 32).
  EXPECT_NE(read_error(good.substr(0, 40)).find("run.state: state truncated in u"), std::string::npos) << read_error(good.substr(0, 40));
  EXPECT_NE(read_error(good.substr(0, 28)).find("run.state: state truncated in u (at byte 24)"), std::string::npos)
      << read_error(good.substr(0, 28));
  // u's length claims 2^60 values: refused before any allocation.
  std::string huge = good;
  const std::uint64_t n = 1ULL << 60;
  std::memcpy(&huge[8 + 8 + 8], &n, sizeof n);
  EXPECT_NE(read_error(huge).find("state field u claims"), std::string::npos) << read_error(huge);
  // One flipped byte in v: the stored hash catches it.
  std::string flipped = good;
  flipped[8 + 8 + 8 + 8 + 3 * 8 + 8 + 2] ^= 0x10;
  EXPECT_NE(read_error(flipped).find("hash mismatch"), std::string::npos) << read_error(flipped);
  // A NaN written into a: named.
  State bad = s;
  bad.a[1] = std::nan("");
  EXPECT_NE(read_error(saved(bad)).find("state field a[1] is not finite"), std::string::npos) << read_error(saved(bad));
}

TEST(State, AttachRefusesAStateOfAnotherModel) {
  const Model m = build_model(make_beam(2, 1, 1, 2, 1, 1, 1), sagging_beam());
  State s;
  Workspace ws;
  init_state(m, s, ws);
  s.v.pop_back();
  try {
    attach_state(m, s, ws);
    FAIL() << "accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("state: v has " + std::to_string(m.ndof() - 1) + " values, the model needs " +
                                         std::to_string(m.ndof())),
              std::string::npos)
        << e.what();
  }
}

}  // namespace
}  // namespace incise
