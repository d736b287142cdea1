#include <algorithm>
#include <cmath>
#include <functional>
#include <numbers>
#include <random>

#include <Eigen/LU>
#include <gtest/gtest.h>

#include "mosaicloc/estimation/lock.hpp"
#include "mosaicloc/estimation/pose_filter.hpp"

namespace mosaicloc::estimation {
namespace {

using core::Pose2;
using core::Timestamp;
using namespace std::chrono_literals;

constexpr double kTrackMm = 500.0;

// An increment along a constant-curvature arc with an isotropic covariance, as the wheels of
// a vehicle with a 500 mm track measured it.
OdometryIncrement Arc(double forward_mm, double turn_rad, core::Duration dt, double sigma_mm = 0.05) {
  OdometryIncrement inc;
  inc.dt = dt;
  inc.travel.left_mm = forward_mm - 0.5 * turn_rad * kTrackMm;
  inc.travel.right_mm = forward_mm + 0.5 * turn_rad * kTrackMm;
  inc.travel.base_mm = kTrackMm;
  inc.previous_from_current = Pose2::Exp({forward_mm, 0.0, turn_rad});
  inc.covariance = Eigen::Vector3d(sigma_mm * sigma_mm, sigma_mm * sigma_mm, 1e-8).asDiagonal();
  return inc;
}

Timestamp At(int step) { return Timestamp::FromNanoseconds(10'000'000LL * step); }

TEST(PoseFilter, PredictionFollowsTheOdometryAndGrowsTheCovariance) {
  PoseFilter filter(PoseFilterOptions{}, At(0), Pose2(1000.0, 0.0, 0.0), Eigen::Matrix3d::Identity() * 1e-4);
  for (int i = 1; i <= 100; ++i) filter.Predict(At(i), Arc(10.0, 0.001, 10ms));
  const Pose2 expected = Pose2(1000.0, 0.0, 0.0) * Pose2::Exp({1000.0, 0.0, 0.1});
  EXPECT_LT(Distance(filter.world_from_vehicle(), expected), 1e-9);
  EXPECT_GT(filter.covariance()(1, 1), filter.covariance()(0, 0)) << "lateral grows faster through yaw";
}

TEST(PoseFilter, SystemModelInterpolatesAndExtrapolates) {
  PoseFilter filter(PoseFilterOptions{}, At(0), Pose2(), Eigen::Matrix3d::Identity() * 1e-4);
  for (int i = 1; i <= 10; ++i) filter.Predict(At(i), Arc(20.0, 0.0, 10ms));  // 2 m/s
  EXPECT_NEAR(filter.PoseAt(At(5) + 5ms).x_mm(), 110.0, 1e-9);
  EXPECT_NEAR(filter.PoseAt(At(10) + 25ms).x_mm(), 250.0, 1e-9) << "constant velocity past the last sample";
  EXPECT_GT(filter.CovarianceAt(At(10) + 500ms)(0, 0), filter.covariance()(0, 0));
}

TEST(PoseFilter, CoastingToAFrameDoesNotCountTheOdometryTwice) {
  // Odometry at 10 ms steps on an arc; a frame at 12.5 steps arrives before the sample at 13.
  PoseFilter coasted(PoseFilterOptions{}, At(0), Pose2(), Eigen::Matrix3d::Identity() * 1e-4);
  PoseFilter plain(PoseFilterOptions{}, At(0), Pose2(), Eigen::Matrix3d::Identity() * 1e-4);
  for (int i = 1; i <= 12; ++i) {
    coasted.Predict(At(i), Arc(20.0, 0.002, 10ms));
    plain.Predict(At(i), Arc(20.0, 0.002, 10ms));
  }
  coasted.Coast(At(12) + 5ms);
  EXPECT_LT(Distance(coasted.world_from_vehicle(), plain.PoseAt(At(12) + 5ms)), 1e-9);
  EXPECT_GT(coasted.covariance()(0, 0), plain.covariance()(0, 0));
  const MotionState latest = coasted.Latest();
  EXPECT_NEAR(latest.forward_speed_mm_per_s, 2000.0, 1e-6);
  EXPECT_LT(Distance(latest.PoseAt(At(14)), plain.PoseAt(At(14))), 1e-9);
  for (int i = 13; i <= 20; ++i) {
    coasted.Predict(At(i), Arc(20.0, 0.002, 10ms));
    plain.Predict(At(i), Arc(20.0, 0.002, 10ms));
  }
  EXPECT_LT(Distance(coasted.world_from_vehicle(), plain.world_from_vehicle()), 1e-9);
  EXPECT_LT(std::abs(YawDifference(coasted.world_from_vehicle(), plain.world_from_vehicle())), 1e-12);
}

TEST(PoseFilter, LateFixGivesTheSameStateAsAnOnTimeFix) {
  const Pose2 fix(246.5, 0.8, 0.002);  // the prediction there is about (246, 0.3, 0.0025)
  const Eigen::Matrix3d fix_covariance = Eigen::Vector3d(0.01, 0.01, 1e-6).asDiagonal();
  const auto run = [&](bool late) {
    PoseFilter filter(PoseFilterOptions{}, At(0), Pose2(), Eigen::Matrix3d::Identity() * 4.0);
    for (int i = 1; i <= 50; ++i) {
      filter.Predict(At(i), Arc(10.0, 0.0001, 10ms, 0.5));
      if (!late && i == 25) {
        EXPECT_TRUE(filter.Correct(At(25) - 4ms, fix, fix_covariance).accepted);
      }
    }
    if (late) {
      const FixOutcome outcome = filter.Correct(At(25) - 4ms, fix, fix_covariance);
      EXPECT_TRUE(outcome.accepted) << outcome.reason;
    }
    return filter;
  };
  // On time means: applied when odometry reached the sample after the fix's time.
  const PoseFilter on_time = run(false);
  const PoseFilter late = run(true);
  EXPECT_LT(Distance(on_time.world_from_vehicle(), late.world_from_vehicle()), 1e-9);
  EXPECT_LT((on_time.covariance() - late.covariance()).norm(), 1e-12);
}

// A restart at a frame's time inside the history keeps the odometry after it: the pose
// later is the new pose moved on by that odometry, and the next frame's fix still finds its
// time in the history.
TEST(PoseFilter, RestartInsideTheHistoryReplaysTheLaterOdometry) {
  PoseFilter filter(PoseFilterOptions{}, At(0), Pose2(), Eigen::Matrix3d::Identity() * 1e-4);
  for (int i = 1; i <= 20; ++i) filter.Predict(At(i), Arc(10.0, 0.001, 10ms));
  const Pose2 restart(500.0, 30.0, 0.2);
  const Timestamp frame = At(12) + 5ms;
  filter.RestartAt(frame, restart, Eigen::Matrix3d::Identity() * 1e-6);
  const Pose2 odometry_after = Pose2::Exp({75.0, 0.0, 0.0075});  // 7.5 steps of the arc
  EXPECT_LT(Distance(filter.world_from_vehicle(), restart * odometry_after), 1e-9);
  EXPECT_LT(Distance(filter.PoseAt(frame), restart), 1e-9);
  EXPECT_LT(filter.CovarianceAt(frame)(0, 0), 1e-5);
  const FixOutcome next = filter.Correct(At(15) + 5ms, filter.PoseAt(At(15) + 5ms), Eigen::Matrix3d::Identity() * 1e-6);
  EXPECT_TRUE(next.accepted) << next.reason;
  EXPECT_FALSE(filter.Correct(At(11), restart, Eigen::Matrix3d::Identity() * 1e-6).accepted)
      << "the states before the restart are gone";
  // After the history: a plain restart there.
  filter.RestartAt(At(30), restart, Eigen::Matrix3d::Identity() * 1e-6);
  EXPECT_LT(Distance(filter.world_from_vehicle(), restart), 1e-12);
}

TEST(PoseFilter, GatesAFixFarFromThePrediction) {
  PoseFilter filter(PoseFilterOptions{}, At(0), Pose2(), Eigen::Matrix3d::Identity() * 1.0);
  filter.Predict(At(1), Arc(10.0, 0.0, 10ms));
  const FixOutcome outcome = filter.Correct(At(1), Pose2(1000.0, 0.0, 0.0), Eigen::Matrix3d::Identity() * 0.01);
  EXPECT_FALSE(outcome.accepted);
  EXPECT_NE(outcome.reason.find("sigma"), std::string::npos);
  EXPECT_NEAR(filter.world_from_vehicle().x_mm(), 10.0, 1e-9) << "a rejected fix changes nothing";
  EXPECT_FALSE(filter.Correct(At(2), Pose2(), Eigen::Matrix3d::Identity()).accepted) << "newer than odometry";
}

TEST(PoseFilter, SaysTheCovarianceAFixWouldLeave) {
  // A prediction uncertain along x, a fix uncertain along y, with a spread added on top.
  PoseFilter filter(PoseFilterOptions{}, At(0), Pose2(), Eigen::Vector3d(4.0, 0.01, 1e-6).asDiagonal());
  filter.Predict(At(1), Arc(10.0, 0.0, 10ms));
  const Eigen::Matrix3d fix = Eigen::Vector3d(0.01, 4.0, 1e-6).asDiagonal();
  const Eigen::Matrix3d spread = Eigen::Matrix3d::Identity() * 0.5;
  const Eigen::Matrix3d expected = filter.CorrectedCovariance(At(1), fix, spread);
  EXPECT_LT(expected(0, 0), 0.011) << "x: the fix's";
  EXPECT_LT(expected(1, 1), 0.53) << "y: the prediction's";
  ASSERT_TRUE(filter.Correct(At(1), Pose2(10.0, 0.0, 0.0), fix, spread).accepted);
  EXPECT_LT((filter.covariance() - expected).cwiseAbs().maxCoeff(), 1e-9 * expected.norm());
}

// A drive with known truth: odometry with a 2 % scale error and noise, fixes with known
// noise at 30 Hz. The filter must stay within its own covariance (normalised estimation
// error squared near 3) and far better than dead reckoning.
TEST(PoseFilter, FusesBiasedOdometryWithFixesConsistently) {
  std::mt19937 rng(3);
  std::normal_distribution<double> unit(0.0, 1.0);
  const double fix_sigma_mm = 0.01, fix_sigma_rad = 2e-5;
  Pose2 truth;
  PoseFilter filter(PoseFilterOptions{}, At(0), truth, Eigen::Vector3d(1e-4, 1e-4, 1e-8).asDiagonal());
  Pose2 dead_reckoning;
  double nees_sum = 0.0;
  int nees_count = 0;
  for (int i = 1; i <= 3000; ++i) {
    const double forward = 15.0, turn = 0.002 * std::sin(i * 0.003);
    truth = truth * Pose2::Exp({forward, 0.0, turn});
    OdometryIncrement inc = Arc(forward * 1.02 + 0.05 * unit(rng), turn + 1e-5 * unit(rng), 10ms, 0.35);
    inc.covariance(2, 2) = 1e-9;
    filter.Predict(At(i), inc);
    dead_reckoning = dead_reckoning * inc.previous_from_current;
    if (i % 3 == 0) {
      const Pose2 fix(truth.x_mm() + fix_sigma_mm * unit(rng), truth.y_mm() + fix_sigma_mm * unit(rng),
                      truth.yaw_rad() + fix_sigma_rad * unit(rng));
      const Eigen::Matrix3d r = Eigen::Vector3d(fix_sigma_mm * fix_sigma_mm, fix_sigma_mm * fix_sigma_mm,
                                                fix_sigma_rad * fix_sigma_rad).asDiagonal();
      ASSERT_TRUE(filter.Correct(At(i), fix, r).accepted) << "step " << i;
      const Eigen::Vector3d e(filter.world_from_vehicle().x_mm() - truth.x_mm(),
                              filter.world_from_vehicle().y_mm() - truth.y_mm(),
                              core::WrapAngle(filter.world_from_vehicle().yaw_rad() - truth.yaw_rad()));
      nees_sum += e.dot(filter.covariance().inverse() * e);
      ++nees_count;
    }
  }
  EXPECT_LT(Distance(filter.world_from_vehicle(), truth), 0.05);
  EXPECT_GT(Distance(dead_reckoning, truth), 100.0);
  const double nees = nees_sum / nees_count;
  EXPECT_GT(nees, 1.0);
  EXPECT_LT(nees, 8.0) << "the covariance must describe the error";
}

// Wheels 2 % and 2.5 % larger than calibrated, the vehicle at 7.2 m/s with odometry at
// 100 Hz and fixes at 30 Hz: the filter learns both scales, and its prediction one frame
// ahead is then as good as the wheels' random error, not 2 % of the travel off.
// 900 steps of 10 ms with a fix (5 um, 20 urad) every third: a filter that learns its two
// calibration states beside one that takes the calibration as exact. `step` gives step i's
// odometry increment and the true motion over it.
struct LearningDrive {
  Eigen::Vector2d learnt;
  Eigen::Matrix2d learnt_covariance;
  Eigen::Vector2d exact_states;
  double worst_late = 0.0;   ///< late in the drive, the learning filter's worst prediction one frame after a fix
  double worst_exact = 0.0;  ///< and the exact one's
};
LearningDrive DriveWithFixes(const PoseFilterOptions& learning, std::mt19937& rng,
                             const std::function<OdometryIncrement(int step, Pose2* true_motion)>& step) {
  std::normal_distribution<double> unit(0.0, 1.0);
  const double fix_sigma_mm = 0.005, fix_sigma_rad = 2e-5;
  const Eigen::Matrix3d r = Eigen::Vector3d(fix_sigma_mm * fix_sigma_mm, fix_sigma_mm * fix_sigma_mm,
                                            fix_sigma_rad * fix_sigma_rad).asDiagonal();
  PoseFilterOptions exact = learning;
  exact.wheel_scale_sigma = exact.steering_offset_sigma_deg = exact.lateral_scale_sigma = 0.0;
  exact.wheel_scale_walk_per_sqrt_m = exact.steering_offset_walk_deg_per_sqrt_m = 0.0;
  Pose2 truth;
  const Eigen::Matrix3d start = Eigen::Vector3d(1e-4, 1e-4, 1e-8).asDiagonal();
  PoseFilter filter(learning, At(0), truth, start), calibrated(exact, At(0), truth, start);
  LearningDrive drive;
  for (int i = 1; i <= 900; ++i) {
    Pose2 motion;
    const OdometryIncrement inc = step(i, &motion);
    truth = truth * motion;
    filter.Predict(At(i), inc);
    calibrated.Predict(At(i), inc);
    if (i % 3 != 0) continue;
    // The prediction one frame after the last fix, before this fix corrects it.
    if (i > 600) {
      drive.worst_late = std::max(drive.worst_late, Distance(filter.world_from_vehicle(), truth));
      drive.worst_exact = std::max(drive.worst_exact, Distance(calibrated.world_from_vehicle(), truth));
    }
    const Pose2 fix(truth.x_mm() + fix_sigma_mm * unit(rng), truth.y_mm() + fix_sigma_mm * unit(rng),
                    truth.yaw_rad() + fix_sigma_rad * unit(rng));
    EXPECT_TRUE(filter.Correct(At(i), fix, r).accepted) << "step " << i;
    calibrated.Correct(At(i), fix, r);
  }
  drive.learnt = filter.wheel_scale_error();
  drive.learnt_covariance = filter.wheel_scale_covariance();
  drive.exact_states = calibrated.wheel_scale_error();
  return drive;
}

TEST(PoseFilter, LearnsTheWheelsScaleErrorsFromFixes) {
  std::mt19937 rng(5);
  std::normal_distribution<double> unit(0.0, 1.0);
  const double k_left = 0.02, k_right = 0.025, slip = 0.002;
  const LearningDrive drive = DriveWithFixes(PoseFilterOptions{}, rng, [&](int i, Pose2* motion) {
    const double true_left = 72.0 * (1.0 + slip * unit(rng)), true_right = 72.0 * (1.0 + slip * unit(rng)) +
                                                                          0.02 * std::sin(0.01 * i);
    *motion = Pose2::Exp({0.5 * (true_left + true_right), 0.0, (true_right - true_left) / kTrackMm});
    OdometryIncrement inc;
    inc.dt = 10ms;
    inc.travel.left_mm = true_left / (1.0 + k_left);
    inc.travel.right_mm = true_right / (1.0 + k_right);
    inc.travel.base_mm = kTrackMm;
    const double ds = 0.5 * (inc.travel.left_mm + inc.travel.right_mm), dtheta = (inc.travel.right_mm - inc.travel.left_mm) / kTrackMm;
    inc.previous_from_current = Pose2::Exp({ds, 0.0, dtheta});
    const double wheel_variance = 0.01 * 72.0;
    inc.covariance = Eigen::Vector3d(wheel_variance / 2.0, 1e-6, 2.0 * wheel_variance / (kTrackMm * kTrackMm))
                         .asDiagonal();
    return inc;
  });
  EXPECT_NEAR(drive.learnt.x(), k_left, 1e-3);
  EXPECT_NEAR(drive.learnt.y(), k_right, 1e-3);
  EXPECT_LT(std::sqrt(drive.learnt_covariance(0, 0)), 2e-3) << "and it knows it";
  EXPECT_EQ(drive.exact_states, Eigen::Vector2d::Zero()) << "sigma 0: the calibration is exact";
  // 216 mm between fixes: 2 % of it is 4.3 mm; the wheels' slip alone about 0.4 mm.
  EXPECT_GT(drive.worst_exact, 3.0);
  EXPECT_LT(drive.worst_late, 1.5);
}

// A mecanum vehicle whose wheels are 2 % larger than calibrated and whose rollers slip 5 %
// sideways, crabbing and turning: both scales are learnt from fixes, and the prediction between
// fixes is then as good as the wheels' random error allows.
TEST(PoseFilter, LearnsAMecanumVehiclesWheelAndSidewaysScalesFromFixes) {
  std::mt19937 rng(9);
  std::normal_distribution<double> unit(0.0, 1.0);
  const double k = 0.02, k_y = -0.05, l = 520.0;
  PoseFilterOptions options;
  options.kind = core::DriveKind::kMecanum;
  const LearningDrive drive = DriveWithFixes(options, rng, [&](int i, Pose2* motion) {
    const double crab = 1.2 * std::sin(0.004 * i), speed = 72.0 * (1.0 + 0.002 * unit(rng));
    const Eigen::Vector3d twist(speed * std::cos(crab), speed * std::sin(crab), 0.002 * std::sin(0.003 * i));
    *motion = Pose2::Exp(twist);
    // The wheels' travels that the true motion gives on wheels (1 + k) larger, with rollers
    // that carry the vehicle only (1 + k_y) of the way sideways.
    const double forward = twist.x() / (1.0 + k), sideways = twist.y() / ((1.0 + k) * (1.0 + k_y));
    const double turn = l * twist.z() / (1.0 + k);
    OdometryIncrement inc;
    inc.dt = 10ms;
    inc.travel.kind = core::DriveKind::kMecanum;
    inc.travel.left_mm = forward - sideways - turn;
    inc.travel.right_mm = forward + sideways + turn;
    inc.travel.rear_left_mm = forward + sideways - turn;
    inc.travel.rear_right_mm = forward - sideways + turn;
    inc.travel.base_mm = l;
    inc.previous_from_current = Pose2::Exp(inc.travel.Motion(Eigen::Vector2d::Zero()));
    inc.covariance = Eigen::Vector3d(0.01 * 72.0 / 4.0, 0.01 * 72.0 / 4.0, 0.01 * 72.0 / (4.0 * l * l)).asDiagonal();
    return inc;
  });
  EXPECT_NEAR(drive.learnt.x(), k, 1e-3);
  EXPECT_NEAR(drive.learnt.y(), k_y, 2e-3);
  EXPECT_LT(std::sqrt(drive.learnt_covariance(1, 1)), 2e-3) << "and it knows it";
  EXPECT_EQ(drive.exact_states, Eigen::Vector2d::Zero());
  EXPECT_GT(drive.worst_exact, 3.0);
  EXPECT_LT(drive.worst_late, 1.5);
}

// A tricycle's drive wheel 2 % off its calibrated radius and its steering 0.5 degrees off its
// calibrated zero, on a winding drive: both are learnt from fixes, and the prediction between
// fixes is then as good as the wheel's random error allows.
TEST(PoseFilter, LearnsATricyclesDriveScaleAndSteeringOffsetFromFixes) {
  std::mt19937 rng(7);
  std::normal_distribution<double> unit(0.0, 1.0);
  const double k_drive = 0.02, offset_rad = 0.5 * std::numbers::pi / 180.0, wheelbase_mm = 1200.0;
  PoseFilterOptions options;
  options.kind = core::DriveKind::kTricycle;
  const LearningDrive drive = DriveWithFixes(options, rng, [&](int i, Pose2* motion) {
    const double true_phi = 0.3 * std::sin(0.005 * i);
    const double true_s = 72.0 * (1.0 + 0.002 * unit(rng));
    *motion = Pose2::Exp({true_s * std::cos(true_phi), 0.0, true_s * std::sin(true_phi) / wheelbase_mm});
    OdometryIncrement inc;
    inc.dt = 10ms;
    inc.travel.kind = core::DriveKind::kTricycle;
    inc.travel.drive_mm = true_s / (1.0 + k_drive);
    inc.travel.steering_rad = true_phi - offset_rad;
    inc.travel.base_mm = wheelbase_mm;
    inc.previous_from_current = Pose2::Exp(inc.travel.Motion(Eigen::Vector2d::Zero()));
    inc.covariance = Eigen::Vector3d(0.01 * 72.0, 1e-6, 1e-9).asDiagonal();
    return inc;
  });
  EXPECT_NEAR(drive.learnt.x(), k_drive, 1e-3);
  EXPECT_NEAR(drive.learnt.y(), offset_rad, 0.02 * std::numbers::pi / 180.0);
  EXPECT_LT(std::sqrt(drive.learnt_covariance(1, 1)), 0.02 * std::numbers::pi / 180.0) << "and it knows it";
  EXPECT_EQ(drive.exact_states, Eigen::Vector2d::Zero());
  EXPECT_GT(drive.worst_exact, 3.0);  // 2 % of 216 mm between fixes
  EXPECT_LT(drive.worst_late, 1.5);
}

// A late fix moves the scales too, and the odometry after it is replayed with them.
TEST(PoseFilter, LateFixCorrectsTheScalesAsAnOnTimeFix) {
  // The fix at 29.7 steps of the arc puts the vehicle where wheels 1 % shorter would have.
  const Pose2 fix = Pose2::Exp(0.99 * 29.7 * Eigen::Vector3d(20.0, 0.0, 0.0005));
  const Eigen::Matrix3d fix_covariance = Eigen::Vector3d(1e-2, 1e-2, 1e-6).asDiagonal();
  const auto run = [&](bool late) {
    PoseFilter filter(PoseFilterOptions{}, At(0), Pose2(), Eigen::Matrix3d::Identity() * 1e-6);
    for (int i = 1; i <= 40; ++i) {
      filter.Predict(At(i), Arc(20.0, 0.0005, 10ms, 0.05));
      if (!late && i == 30) {
        EXPECT_TRUE(filter.Correct(At(30) - 3ms, fix, fix_covariance).accepted);
      }
    }
    if (late) {
      EXPECT_TRUE(filter.Correct(At(30) - 3ms, fix, fix_covariance).accepted);
    }
    return filter;
  };
  const PoseFilter on_time = run(false), late = run(true);
  EXPECT_NEAR(late.wheel_scale_error().x(), -0.01, 2e-3);
  EXPECT_NEAR(late.wheel_scale_error().y(), -0.01, 2e-3);
  EXPECT_LT((on_time.wheel_scale_error() - late.wheel_scale_error()).norm(), 1e-12);
  EXPECT_LT(Distance(on_time.world_from_vehicle(), late.world_from_vehicle()), 1e-9);
  EXPECT_LT((on_time.covariance() - late.covariance()).norm(), 1e-12);
}

// Degraded after 2 misses, lost after 4, tracking again after 3 fixes.
LockOptions ShortLockOptions() {
  LockOptions options;
  options.degraded_after_misses = 2;
  options.lost_after_misses = 4;
  options.regain_after_fixes = 3;
  return options;
}

TEST(LockMonitor, DegradesLosesAndRegainsWithHysteresis) {
  LockMonitor lock(ShortLockOptions());
  constexpr FrameVerdict kFixed = FrameVerdict::kFixed, kMissed = FrameVerdict::kMissed;
  EXPECT_EQ(lock.Update(kMissed, 0.1, "no texture"), LockState::kTracking);
  EXPECT_EQ(lock.Update(kMissed, 0.1), LockState::kDegraded);
  EXPECT_EQ(lock.Update(kFixed, 0.1), LockState::kDegraded) << "one fix is not enough";
  EXPECT_EQ(lock.Update(kFixed, 0.1), LockState::kDegraded);
  EXPECT_EQ(lock.Update(kFixed, 0.1), LockState::kTracking);
  for (int i = 0; i < 4; ++i) lock.Update(kMissed, 0.1, "no match");
  EXPECT_EQ(lock.state(), LockState::kLost);
  EXPECT_EQ(lock.losses(), 1);
  EXPECT_EQ(lock.last_reason(), "no match");
  lock.Update(kMissed, 0.1);
  EXPECT_EQ(lock.losses(), 1) << "staying lost is one loss";
  for (int i = 0; i < 3; ++i) lock.Update(kFixed, 0.1);
  EXPECT_EQ(lock.state(), LockState::kTracking);
  EXPECT_EQ(lock.Update(kMissed, 50.0), LockState::kLost) << "too uncertain is lost at once";
  EXPECT_EQ(lock.losses(), 2);
}

// A view predicted off the map is no miss: however long the excursion and however uncertain
// the dead reckoning, the state says off-map and no loss is counted. Back on the map, the
// lock counts misses and fixes again from degraded.
TEST(LockMonitor, OffTheMapIsAStateOfItsOwnAndNoLoss) {
  LockMonitor lock(ShortLockOptions());
  for (int i = 0; i < 100; ++i) EXPECT_EQ(lock.Update(FrameVerdict::kOffMap, 0.1 * i, "off-map"), LockState::kOffMap);
  EXPECT_EQ(lock.losses(), 0);
  EXPECT_EQ(lock.last_reason(), "off-map");
  EXPECT_EQ(lock.Update(FrameVerdict::kMissed, 1.0), LockState::kDegraded) << "back on the map, not fixed yet";
  EXPECT_EQ(lock.Update(FrameVerdict::kOffMap, 1.0), LockState::kOffMap);
  EXPECT_EQ(lock.Update(FrameVerdict::kFixed, 1.0), LockState::kDegraded) << "a fix is on the map";
  EXPECT_EQ(lock.Update(FrameVerdict::kFixed, 0.1), LockState::kDegraded);
  EXPECT_EQ(lock.Update(FrameVerdict::kFixed, 0.1), LockState::kTracking);
  EXPECT_EQ(lock.losses(), 0);
  // Back on the map with dead reckoning too uncertain to be tracking: lost, but the lock was
  // not lost here: it ended when the view left the map.
  lock.Update(FrameVerdict::kOffMap, 30.0);
  EXPECT_EQ(lock.Update(FrameVerdict::kMissed, 30.0), LockState::kLost);
  EXPECT_EQ(lock.losses(), 0);
  EXPECT_STREQ(ToString(LockState::kOffMap), "off-map");
}

}  // namespace
}  // namespace mosaicloc::estimation
