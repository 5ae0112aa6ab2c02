#include "hq/geometry/lie.hpp"

#include "hq/geometry/pinhole_camera.hpp"

#include <gtest/gtest.h>

#include <random>

namespace hq::geometry {
namespace {

std::vector<Vector6d> sample_twists() {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<Vector6d> twists;
  twists.push_back(Vector6d::Zero());
  Vector6d tiny;
  tiny << 1e-9, -2e-9, 3e-9, 1e-8, -1e-9, 2e-9;
  twists.push_back(tiny);
  for (int i = 0; i < 50; ++i) {
    Vector6d xi;
    for (int k = 0; k < 6; ++k) xi(k) = u(rng);
    twists.push_back(xi);
  }
  Vector6d near_pi = Vector6d::Zero();
  near_pi.tail<3>() = Eigen::Vector3d(0.0, 0.0, 3.1);
  twists.push_back(near_pi);
  return twists;
}

TEST(Lie, ExpLogRoundTripOverSampledTwists) {
  for (const Vector6d& xi : sample_twists()) {
    const Vector6d back = log_se3(exp_se3(xi));
    EXPECT_LT((back - xi).norm(), 1e-9) << xi.transpose();
  }
}

TEST(Lie, ExpSo3IsOrthonormalAndMatchesAngleAxis) {
  const Eigen::Vector3d w(0.3, -0.2, 0.9);
  const Eigen::Matrix3d R = exp_so3(w);
  EXPECT_LT((R * R.transpose() - Eigen::Matrix3d::Identity()).norm(), 1e-12);
  const Eigen::Matrix3d expected = Eigen::AngleAxisd(w.norm(), w.normalized()).toRotationMatrix();
  EXPECT_LT((R - expected).norm(), 1e-12);
}

TEST(Lie, HatIsCrossProduct) {
  const Eigen::Vector3d a(1.0, 2.0, 3.0);
  const Eigen::Vector3d b(-0.5, 0.25, 4.0);
  EXPECT_LT((hat(a) * b - a.cross(b)).norm(), 1e-15);
}

TEST(Lie, ExpDerivativeAtIdentityMatchesGenerator) {
  // d(exp(xi) p)/d xi at xi = 0 is [I, -[p]x]: checks the (v, omega) convention numerically.
  const Eigen::Vector3d p(0.4, -1.2, 2.5);
  const double h = 1e-6;
  for (int k = 0; k < 6; ++k) {
    Vector6d xi = Vector6d::Zero();
    xi(k) = h;
    const Eigen::Vector3d numeric = (exp_se3(xi) * p - exp_se3(-xi) * p) / (2 * h);
    Eigen::Matrix<double, 3, 6> analytic;
    analytic << Eigen::Matrix3d::Identity(), -hat(p);
    EXPECT_LT((numeric - analytic.col(k)).norm(), 1e-8) << "column " << k;
  }
}

TEST(Lie, AdjointConjugatesTwists) {
  Vector6d a;
  a << 0.1, 0.2, -0.3, 0.2, -0.1, 0.4;
  Vector6d xi;
  xi << -0.2, 0.05, 0.1, 0.03, 0.02, -0.05;
  const Eigen::Isometry3d T = exp_se3(a);
  const Vector6d lhs = log_se3(T * exp_se3(xi) * T.inverse());
  EXPECT_LT((lhs - adjoint(T) * xi).norm(), 1e-9);
}

TEST(PinholeCamera, LevelHalvesFocalAndKeepsPixelCentres) {
  const PinholeCamera cam{517.3, 516.5, 318.6, 255.3, 640, 480};
  const PinholeCamera l1 = cam.at_level(1);
  EXPECT_DOUBLE_EQ(l1.fx, 517.3 / 2);
  EXPECT_DOUBLE_EQ(l1.cx, (318.6 + 0.5) / 2 - 0.5);
  EXPECT_EQ(l1.width, 320);
  EXPECT_EQ(l1.height, 240);
}

}  // namespace
}  // namespace hq::geometry
