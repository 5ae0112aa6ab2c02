#include "hq/haptics/teleop_mapping.hpp"

#include "test_support.hpp"
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

namespace hq::haptics {
namespace {

constexpr std::int64_t kNowNs = 10'000 * test::kMsNs;

VehicleEstimate estimate_at(std::int64_t t_ns, const Eigen::Vector3d& v_H_mps,
                            double yaw_rate_radps = 0.0) {
  VehicleEstimate estimate;
  estimate.t_ns = t_ns;
  estimate.valid = true;
  estimate.v_H_mps = v_H_mps;
  estimate.yaw_rate_radps = yaw_rate_radps;
  return estimate;
}

class ForceFeedbackTest : public ::testing::Test {
 protected:
  ForceFeedbackTest()
      : mapping_(MappingConfig{}, test::core_paper_R_B_C()),
        feedback_(FeedbackConfig{}, mapping_) {}
  FeedbackConfig config_;
  TeleopMapping mapping_;
  ForceFeedback feedback_;
};

TEST_F(ForceFeedbackTest, VehicleLaggingTheCommandResistsThePush) {
  // GIVEN the handle pushed forward and a vehicle still at rest
  const Eigen::Vector3d p(0.03, 0.0, 0.0);
  const VelocityCommand command = mapping_.map(p).command;
  const FeedbackForce lagging = feedback_.compute(kNowNs, p, Eigen::Vector3d::Zero(), command,
                                                  estimate_at(kNowNs, Eigen::Vector3d::Zero()));
  const FeedbackForce tracking = feedback_.compute(kNowNs, p, Eigen::Vector3d::Zero(), command,
                                                   estimate_at(kNowNs, command.v_H_mps));
  // THEN the cue pushes back beyond the centring spring; with perfect tracking only the spring
  EXPECT_NEAR(tracking.F_D_n.x(), -config_.centring_stiffness_n_per_m * p.x(), 1e-12);
  EXPECT_LT(lagging.F_D_n.x(), tracking.F_D_n.x());
  const double cue_n = -config_.velocity_stiffness_n_per_m * mapping_.displacement_for(command).x();
  EXPECT_NEAR(lagging.F_D_n.x() - tracking.F_D_n.x(), cue_n, 1e-12);
  EXPECT_NEAR(lagging.F_D_n.y(), 0.0, 1e-12);
  EXPECT_NEAR(lagging.F_D_n.z(), 0.0, 1e-12);
}

TEST_F(ForceFeedbackTest, VehicleFasterThanCommandedPullsTheHandForward) {
  const Eigen::Vector3d p(0.02, 0.0, 0.0);
  const VelocityCommand command = mapping_.map(p).command;
  const FeedbackForce faster = feedback_.compute(kNowNs, p, Eigen::Vector3d::Zero(), command,
                                                 estimate_at(kNowNs, 3.0 * command.v_H_mps));
  EXPECT_GT(faster.F_D_n.x(), -config_.centring_stiffness_n_per_m * p.x());
}

TEST_F(ForceFeedbackTest, YawAndVerticalErrorsComeBackOnTheirAxes) {
  const VelocityCommand none;
  // The cue drags the handle towards the displacement that would command what the vehicle does.
  // Vehicle climbing (-z in H) without a command: under eq. 8 a climb is commanded by +p_z.
  const FeedbackForce climbing =
      feedback_.compute(kNowNs, Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero(), none,
                        estimate_at(kNowNs, Eigen::Vector3d(0.0, 0.0, -0.3)));
  EXPECT_GT(climbing.F_D_n.z(), 0.0);
  EXPECT_NEAR(climbing.F_D_n.head<2>().norm(), 0.0, 1e-12);
  // Vehicle yawing right (+) without a command: under eq. 10 that is commanded by -p_y.
  const FeedbackForce yawing =
      feedback_.compute(kNowNs, Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero(), none,
                        estimate_at(kNowNs, Eigen::Vector3d::Zero(), 0.5));
  EXPECT_LT(yawing.F_D_n.y(), 0.0);
  EXPECT_NEAR(yawing.F_D_n.x(), 0.0, 1e-12);
}

TEST_F(ForceFeedbackTest, DampingOpposesHandleVelocity) {
  const VelocityCommand none;
  const Eigen::Vector3d p_dot(0.1, -0.2, 0.05);
  const FeedbackForce out = feedback_.compute(kNowNs, Eigen::Vector3d::Zero(), p_dot, none,
                                              estimate_at(kNowNs, Eigen::Vector3d::Zero()));
  EXPECT_TRUE(out.F_D_n.isApprox(-config_.damping_ns_per_m * p_dot, 1e-12));
}

TEST_F(ForceFeedbackTest, ForceIsSaturatedInMagnitudeNotDirection) {
  const Eigen::Vector3d p(0.08, 0.0, 0.0);
  const VelocityCommand command = mapping_.map(p).command;
  const FeedbackForce out = feedback_.compute(kNowNs, p, Eigen::Vector3d(2.0, 0.0, 0.0), command,
                                              estimate_at(kNowNs, -command.v_H_mps));
  EXPECT_TRUE(out.saturated);
  EXPECT_NEAR(out.F_D_n.norm(), config_.max_force_n, 1e-12);
  EXPECT_LT(out.F_D_n.x(), 0.0);
}

TEST_F(ForceFeedbackTest, CueFadesSmoothlyToZeroWhenStateGoesStale) {
  const VehicleEstimate estimate = estimate_at(0, Eigen::Vector3d::Zero());
  const auto at_s = [](double t_s) { return static_cast<std::int64_t>(t_s * 1e9); };
  EXPECT_EQ(feedback_.cue_weight(at_s(config_.stale_after_s), estimate), 1.0);
  EXPECT_EQ(feedback_.cue_weight(at_s(config_.stale_after_s + config_.fade_s + 1e-3), estimate),
            0.0);
  double previous = 1.0;
  double max_step = 0.0;
  for (double t_s = config_.stale_after_s; t_s <= config_.stale_after_s + config_.fade_s;
       t_s += 1e-3) {
    const double weight = feedback_.cue_weight(at_s(t_s), estimate);
    EXPECT_LE(weight, previous + 1e-12);
    max_step = std::max(max_step, previous - weight);
    previous = weight;
  }
  // Smooth: no 1 ms step larger than the raised cosine's steepest slope allows.
  EXPECT_LT(max_step, 1.01 * M_PI / 2.0 * 1e-3 / config_.fade_s);
  EXPECT_NEAR(feedback_.cue_weight(at_s(config_.stale_after_s + 0.5 * config_.fade_s), estimate),
              0.5, 1e-6);
}

TEST_F(ForceFeedbackTest, StaleStateLeavesOnlySpringAndDamping) {
  const Eigen::Vector3d p(0.03, 0.0, 0.0);
  const VelocityCommand command = mapping_.map(p).command;
  const std::int64_t late_ns =
      kNowNs + static_cast<std::int64_t>((config_.stale_after_s + config_.fade_s + 0.01) * 1e9);
  const FeedbackForce stale = feedback_.compute(late_ns, p, Eigen::Vector3d::Zero(), command,
                                                estimate_at(kNowNs, Eigen::Vector3d::Zero()));
  EXPECT_EQ(stale.cue_weight, 0.0);
  EXPECT_NEAR(stale.F_D_n.x(), -config_.centring_stiffness_n_per_m * p.x(), 1e-12);
  const FeedbackForce never =
      feedback_.compute(kNowNs, p, Eigen::Vector3d::Zero(), command, VehicleEstimate{});
  EXPECT_EQ(never.cue_weight, 0.0);
  EXPECT_EQ(never.F_D_n, stale.F_D_n);
}

TEST_F(ForceFeedbackTest, NonFiniteInputsGiveZeroForce) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const VelocityCommand none;
  const FeedbackForce out = feedback_.compute(kNowNs, Eigen::Vector3d(nan, 0.0, 0.0),
                                              Eigen::Vector3d::Zero(), none, VehicleEstimate{});
  EXPECT_EQ(out.F_D_n, Eigen::Vector3d::Zero());
  // A NaN estimate drops the cue but keeps the spring.
  const Eigen::Vector3d p(0.01, 0.0, 0.0);
  const FeedbackForce bad_estimate = feedback_.compute(
      kNowNs, p, Eigen::Vector3d::Zero(), none, estimate_at(kNowNs, Eigen::Vector3d(nan, 0, 0)));
  EXPECT_TRUE(bad_estimate.F_D_n.allFinite());
  EXPECT_NEAR(bad_estimate.F_D_n.x(), -config_.centring_stiffness_n_per_m * p.x(), 1e-12);
}

}  // namespace
}  // namespace hq::haptics
