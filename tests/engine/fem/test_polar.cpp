// Inversion-safe rotation extraction.
#include <algorithm>
#include <cstring>
#include <limits>
#include <random>
#include <vector>

#include <Eigen/Geometry>
#include <Eigen/SVD>
#include <gtest/gtest.h>

#include "engine/fem/polar.h"

namespace incise {
namespace {

Eigen::Matrix3d random_rotation(std::mt19937& rng) {
  std::normal_distribution<double> N;
  Eigen::Quaterniond q(N(rng), N(rng), N(rng), N(rng));
  return q.normalized().toRotationMatrix();
}

// Reference: U diag(1, 1, det(U V^T)) V^T from an SVD.
Eigen::Matrix3d reference_rotation(const Eigen::Matrix3d& F) {
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(F, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d D = Eigen::Matrix3d::Identity();
  D(2, 2) = (svd.matrixU() * svd.matrixV().transpose()).determinant();
  return svd.matrixU() * D * svd.matrixV().transpose();
}

TEST(Polar, PureRotationIsRecoveredToRoundoffFromIdentity) {
  std::mt19937 rng(1);
  for (int k = 0; k < 200; ++k) {
    const Eigen::Matrix3d Q = random_rotation(rng);
    Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
    extract_rotation(Q, R);
    EXPECT_LT((R - Q).norm(), 1e-13) << Q;
  }
}

TEST(Polar, StretchedAndInvertedMatchTheSvdDefinition) {
  std::mt19937 rng(2);
  std::uniform_real_distribution<double> U(0.2, 3.0);
  for (int k = 0; k < 500; ++k) {
    const Eigen::Matrix3d Q1 = random_rotation(rng), Q2 = random_rotation(rng);
    Eigen::Vector3d s(U(rng), U(rng), U(rng));
    if (k % 2) s[k % 3] *= -1.0;  // inverted: det F < 0
    const Eigen::Matrix3d F = Q1 * s.asDiagonal() * Q2.transpose();
    Eigen::Matrix3d R = (k % 3 == 0) ? Eigen::Matrix3d::Identity() : Eigen::Matrix3d(reference_rotation(F + 0.05 * Q1));
    extract_rotation(F, R);
    EXPECT_NEAR(R.determinant(), 1.0, 1e-12);
    EXPECT_LT((R.transpose() * R - Eigen::Matrix3d::Identity()).norm(), 1e-12);
    EXPECT_LT((R - reference_rotation(F)).norm(), 1e-9) << "F=\n" << F;
  }
}

// Between frames the warm start is off by a few thousandths to hundredths of
// a radian: Newton (quadratic) must land in 2 steps from 0.003 rad and 3 from
// 0.03 rad, without the SVD fallback, at roundoff of the SVD definition.
TEST(Polar, WarmStartedExtractionConvergesInFewNewtonSteps) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> U(0.7, 1.4);
  std::normal_distribution<double> N;
  for (const auto& [angle, max_steps] : {std::pair{0.003, 2}, std::pair{0.03, 3}})
    for (int k = 0; k < 300; ++k) {
      const Eigen::Matrix3d Q1 = random_rotation(rng), Q2 = random_rotation(rng);
      const Eigen::Vector3d s(U(rng), U(rng), U(rng));
      const Eigen::Matrix3d F = Q1 * s.asDiagonal() * Q2.transpose();
      const Eigen::Matrix3d Rf = reference_rotation(F);
      const Eigen::Vector3d axis = Eigen::Vector3d(N(rng), N(rng), N(rng)).normalized();
      Eigen::Matrix3d R = Eigen::AngleAxisd(angle, axis).toRotationMatrix() * Rf;
      const int steps = extract_rotation(F, R);
      EXPECT_GE(steps, 1) << "no SVD fallback; F=\n" << F;
      EXPECT_LE(steps, max_steps) << "warm start " << angle << " rad; F=\n" << F;
      EXPECT_LT((R - Rf).norm(), 1e-12) << "F=\n" << F;
      EXPECT_LT((R.transpose() * R - Eigen::Matrix3d::Identity()).norm(), 1e-13);
    }
}

TEST(Polar, DegenerateFlatElementGivesAProperRotation) {
  Eigen::Matrix3d F = Eigen::Matrix3d::Identity();
  F(2, 2) = 0.0;  // squashed flat
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
  extract_rotation(F, R);
  EXPECT_NEAR(R.determinant(), 1.0, 1e-12);
  EXPECT_LT((R - Eigen::Matrix3d::Identity()).norm(), 1e-12);
}

// rotation_angle_to (the adaptive Newton check): the angle between R and
// F's rotation, to 1% below 0.1 rad (its one-step estimate) and exactly
// (to 1e-9) beyond 0.5 rad, never above pi, for stretched, nearly singular
// and inverted F: a one-step estimate there read thousands of radians.
TEST(Polar, RotationAngleToIsTheAngleForSmallLargeAndDegenerateF) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> U(0.3, 2.0);
  for (int k = 0; k < 300; ++k) {
    const Eigen::Matrix3d R = random_rotation(rng);
    const Eigen::Vector3d axis = Eigen::Vector3d::Random().normalized();
    const double angle = k < 100 ? 0.1 * k / 100.0 : 0.5 + 2.5 * (k - 100) / 200.0;
    const Eigen::Matrix3d Q = R * Eigen::AngleAxisd(angle, axis).toRotationMatrix();
    Eigen::Matrix3d S = Eigen::Matrix3d::Zero();
    S.diagonal() << U(rng), U(rng), U(rng);
    const Eigen::Matrix3d V = random_rotation(rng);
    const Eigen::Matrix3d F = Q * V * S * V.transpose();  // rotation Q, stretch V S V^T
    const double got = rotation_angle_to(F, R);
    if (angle < 0.1) {
      EXPECT_NEAR(got, angle, 0.01 * angle + 1e-12) << "k = " << k;
    } else if (angle > 0.5) {
      EXPECT_NEAR(got, angle, 1e-9) << "k = " << k;
    }
  }
  for (int k = 0; k < 300; ++k) {  // nearly singular and inverted: an angle in [0, pi]
    const Eigen::Matrix3d R = random_rotation(rng);
    Eigen::Matrix3d S = Eigen::Matrix3d::Zero();
    S.diagonal() << U(rng), U(rng), (k % 3 == 0 ? -1.0 : 1.0) * 1e-3 * U(rng) * (k % 2);
    const Eigen::Matrix3d V = random_rotation(rng);
    const Eigen::Matrix3d F = random_rotation(rng) * V * S * V.transpose();
    const double got = rotation_angle_to(F, R);
    EXPECT_GE(got, 0.0) << "k = " << k;
    EXPECT_LE(got, M_PI + 1e-12) << "k = " << k;
  }
}


// extract_rotations and rotation_angles_to run four gradients side by side
// (the assembly's lanes): each result must be the one-at-a-time function's
// to the bit, whatever its neighbours in the call are (a lane that stops
// early, takes the SVD, is inverted, zero or NaN, or needs the exact large
// step), and for counts that leave padding lanes. Otherwise a rotation
// would depend on how the slots are grouped.
TEST(Polar, FourAtATimeGivesEachRotationTheBitsOfOneAtATime) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> U(0.3, 2.0);
  std::normal_distribution<double> N;
  std::vector<Eigen::Matrix3d> F, R0;
  for (int k = 0; k < 40; ++k) {
    const Eigen::Matrix3d Q1 = random_rotation(rng), Q2 = random_rotation(rng);
    Eigen::Vector3d s(U(rng), U(rng), U(rng));
    if (k % 5 == 1) s[k % 3] *= -1.0;     // inverted
    if (k % 7 == 2) s[(k + 1) % 3] = 1e-9;  // nearly flat
    Eigen::Matrix3d Fk = Q1 * s.asDiagonal() * Q2.transpose();
    if (k == 13) Fk.setZero();
    if (k == 17) Fk(1, 2) = std::numeric_limits<double>::quiet_NaN();
    if (k == 23) Fk *= 1e-300;
    F.push_back(Fk);
    // Warm starts from 1e-4 to 2 rad off (the exact step past 0.1 rad).
    const double angle = std::pow(10.0, -4.0 + 4.3 * (k % 9) / 8.0);
    const Eigen::Vector3d axis = Eigen::Vector3d(N(rng), N(rng), N(rng)).normalized();
    R0.push_back(Eigen::AngleAxisd(angle, axis).toRotationMatrix() * reference_rotation(Fk.allFinite() ? Fk : Q1));
  }
  for (int count : {1, 3, 4, 7, 40}) {
    std::vector<double> Fs(9 * count), Rs(9 * count), angles(count);
    std::vector<int> its(count);
    for (int k = 0; k < count; ++k) {
      std::copy(F[k].data(), F[k].data() + 9, &Fs[9 * k]);
      std::copy(R0[k].data(), R0[k].data() + 9, &Rs[9 * k]);
    }
    rotation_angles_to(count, Fs.data(), Rs.data(), angles.data());
    const int fallbacks = extract_rotations(count, Fs.data(), Rs.data(), its.data());
    int expected_fallbacks = 0;
    for (int k = 0; k < count; ++k) {
      Eigen::Matrix3d R = R0[k];
      const int it = extract_rotation(F[k], R);
      expected_fallbacks += it < 0;
      EXPECT_EQ(its[k], it) << "count " << count << ", k " << k;
      EXPECT_EQ(std::memcmp(&Rs[9 * k], R.data(), sizeof(double) * 9), 0) << "count " << count << ", k " << k;
      const double a = rotation_angle_to(F[k], R0[k]);
      EXPECT_EQ(std::memcmp(&angles[k], &a, sizeof(double)), 0) << "count " << count << ", k " << k;
    }
    EXPECT_EQ(fallbacks, expected_fallbacks);
    if (count == 40) {
      EXPECT_GT(expected_fallbacks, 0) << "the set includes SVD fallbacks";
    }
  }
}

}  // namespace
}  // namespace incise
