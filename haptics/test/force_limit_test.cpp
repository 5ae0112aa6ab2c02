#include "hq/haptics/force_limit.hpp"

#include <gtest/gtest.h>

#include <limits>

namespace hq::haptics {
namespace {

TEST(LimitForce, BelowTheCapPassesUntouched) {
  const LimitedForce out = limit_force({1.0, -2.0, 3.0}, 8.0);
  EXPECT_EQ(out.F_D_n, Eigen::Vector3d(1.0, -2.0, 3.0));
  EXPECT_FALSE(out.saturated);
  EXPECT_TRUE(out.finite);
}

TEST(LimitForce, AboveTheCapScalesTheMagnitudeAndKeepsTheDirection) {
  const Eigen::Vector3d F_D_n(6.0, -8.0, 2.5);  // the law's 8 N plus a damper's term
  const LimitedForce out = limit_force(F_D_n, 8.0);
  EXPECT_TRUE(out.saturated);
  EXPECT_NEAR(out.F_D_n.norm(), 8.0, 1e-12);
  EXPECT_NEAR(out.F_D_n.normalized().dot(F_D_n.normalized()), 1.0, 1e-12);
}

TEST(LimitForce, HugeFiniteSumKeepsItsDirection) {
  const LimitedForce out = limit_force({3e200, 0.0, -4e200}, 8.0);
  EXPECT_TRUE(out.finite);
  EXPECT_TRUE(out.saturated);
  EXPECT_NEAR(out.F_D_n.x(), 4.8, 1e-9);
  EXPECT_NEAR(out.F_D_n.z(), -6.4, 1e-9);
}

TEST(LimitForce, NonFiniteTermGivesZeroForceAndSaysSo) {
  constexpr double kNan = std::numeric_limits<double>::quiet_NaN();
  constexpr double kInf = std::numeric_limits<double>::infinity();
  for (const Eigen::Vector3d& F_D_n :
       {Eigen::Vector3d(kNan, 0.0, 0.0), Eigen::Vector3d(1.0, -kInf, 0.0),
        Eigen::Vector3d(kInf, kInf, kInf)}) {
    const LimitedForce out = limit_force(F_D_n, 8.0);
    EXPECT_FALSE(out.finite);
    EXPECT_EQ(out.F_D_n, Eigen::Vector3d::Zero());
  }
  EXPECT_FALSE(limit_force({1.0, 0.0, 0.0}, kNan).finite);
}

}  // namespace
}  // namespace hq::haptics
