// Tests of what only the Moreau-Jean time stepper (src/core/time_stepping.cc) has, on closed
// forms and invariants: free flight (exact for theta = 1/2, first order otherwise), Zeno
// bouncing without drift, and a rocking kernel that does not sink. What both integrators must
// satisfy (restitution, friction limit, energy, no energy from friction, bit-identical reruns)
// is in test_integrators.cc.
//
// Tolerances follow the scheme: the kernels' velocities take the force impulse h f per step,
// positions the theta-average of old and new velocities, contacts are detected at the
// midpoint q + h/2 u and impacts resolved with the velocity at the start of the step. Each
// test says which of these limits its agreement.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>

#include "sim_test_util.h"
#include "threshing_sim/core/simulator.h"

namespace threshing_sim {
namespace {

using testutil::fmt;
using testutil::kG;
using testutil::kPi;

constexpr IntegratorType kTS = IntegratorType::kTimeStepping;

// ---------------------------------------------------------------------------------------------
// Free flight.

Model freeKernelModel(double theta, double dt) {
  Model m = testutil::bareModel(kTS);
  KernelModel k = testutil::makeKernel(5e-3, 1.3e-3, Vec2(0.01, 0.3), Vec2(1.2, 2.5), 0.4);
  k.initial_angular_velocity_radps = 40.0;
  m.kernels = {k};
  m.integrator.theta = theta;
  m.integrator.dt_s = dt;
  compileModel(&m);
  return m;
}

// theta = 1/2: u_{n+1} = u_n + h g and z_{n+1} = z_n + h (u_n + u_{n+1}) / 2 is the
// trapezoidal rule, exact for a constant acceleration. Only rounding remains: 5000 additions
// of h g, each rounded to ~2e-16 of |v| ~ 2.5 m/s, drift by up to ~1e-12; 1e-10 m and m/s
// are still 4 orders below the first-order error g h t / 2 = 2.5e-6 m of any theta != 1/2.
TEST(TimeStepping, FreeKernelFollowsTheParabolaExactlyAtThetaHalf) {
  const Model m = freeKernelModel(0.5, 1e-5);
  Data d;
  resetData(m, &d);
  const Vec2 c0(0.01, 0.3), v0(1.2, 2.5);
  for (double t : {0.01, 0.05}) {
    ASSERT_EQ(advanceTo(m, &d, t), StepStatus::kOk);
    ASSERT_NEAR(d.t_s, t, 1e-15);
    const Vec2 c = c0 + v0 * t + 0.5 * m.gravity_mps2 * t * t;
    const Vec2 v = v0 + m.gravity_mps2 * t;
    EXPECT_NEAR(d.z[0], c.x(), 1e-10);
    EXPECT_NEAR(d.z[1], c.y(), 1e-10);
    EXPECT_NEAR(d.z[2], 0.4 + 40.0 * t, 1e-10);
    EXPECT_NEAR(d.u[0], v.x(), 1e-10);
    EXPECT_NEAR(d.u[1], v.y(), 1e-10);
  }
}

// theta = 1 (backward Euler positions): z_N = z0 + u0 t + g t^2/2 + g h t/2 exactly (the sum
// of h u_{n+1} over the steps), a first-order error the test predicts to rounding: 1e-12 m.
// The same error must halve with h (first order).
TEST(TimeStepping, FreeKernelAtThetaOneHasTheFirstOrderErrorOfTheScheme) {
  const double t = 0.05;
  double err_prev = 0;
  for (double h : {2e-5, 1e-5}) {
    const Model m = freeKernelModel(1.0, h);
    Data d;
    resetData(m, &d);
    ASSERT_EQ(advanceTo(m, &d, t), StepStatus::kOk);
    const double y_exact = 0.3 + 2.5 * t - 0.5 * kG * t * t;
    const double y_scheme = y_exact - 0.5 * kG * h * t;
    EXPECT_NEAR(d.z[1], y_scheme, 1e-12) << "h = " << h;
    const double err = std::abs(d.z[1] - y_exact);
    if (err_prev > 0) {
      EXPECT_NEAR(err_prev / err, 2.0, 1e-6);
    }
    err_prev = err;
  }
}

// ---------------------------------------------------------------------------------------------
// Zeno: a kernel dropped from 10 mm with e = 0.5 on the plate, for 1 s with h = 1e-5 s. The
// velocity-level LCP has no accumulation problem: bounces below zeno_velocity (1 mm/s) are
// plastic, after which the kernel rests. Checked: every step taken (1e5, finite by
// construction), penetration bounded by the distance one step can cover at the impact speed
// (|v_imp| h = 4.4 um, midpoint detection), and no drift through the plate once at rest.

TEST(TimeStepping, ZenoBouncingComesToRestWithoutDrift) {
  const double r = 1.5e-3, h0 = 0.01, h = 1e-5;
  Model m = testutil::dropModel(kTS, ContactLaw::kRigid, 0.5, 0.5, r, r, h0, Vec2::Zero());
  m.integrator.dt_s = h;
  compileModel(&m);
  Data d;
  testutil::runTo(m, &d, 0.5);
  const double y_half = d.z[1];
  ASSERT_EQ(advanceTo(m, &d, 1.0), StepStatus::kOk);
  EXPECT_EQ(d.steps, 100000);
  const double v_imp = std::sqrt(2 * kG * h0);
  EXPECT_LE(d.stats.max_penetration_m, v_imp * h);
  EXPECT_GE(d.z[1], r - v_imp * h);
  // At rest: no motion in the second half second beyond rounding (1e-12 m).
  EXPECT_NEAR(d.z[1], y_half, 1e-12);
  EXPECT_NEAR(d.u[1], 0.0, 1e-12);
  // The bounces: 9-11 impacts before they go plastic (e^k 0.443 m/s < 1 mm/s at k = 9).
  EXPECT_GE(d.stats.impacts, 8);
  EXPECT_LE(d.stats.impacts, 12);
  RecordProperty("max_penetration_m", fmt(d.stats.max_penetration_m));
}

// A paddy kernel dropped tilted (0.4 rad) from 0.7 mm onto a steel floor settles into rocking
// on its flank: rolling without slip dissipates nothing, so it rocks for as long as it runs,
// the floor contact closed and its point sweeping the curved flank. The velocity-level
// constraint drops a second-order term of that rolling every step: without the depth kept
// after each step the kernel sank 2.5e-5 m in this one second (h = 1e-5; 8e-4 m over the
// 750 s long run of hard case 10 at h = 1e-6), and without the correction of rises the
// contact would open and close again (chatter). Checked: after the bounces the exact gap of
// the ellipse above the floor, sampled every millisecond, is never deeper than the impact
// penetration (|v_imp| h = 1.2 um) plus two slops (2 h zeno_velocity), while the kernel keeps
// rocking (its angle still sweeps 0.1 rad in the last half second) with no energy gained and
// no new impacts from the corrections (the bounces give 5-9).
TEST(TimeStepping, RockingKernelOnTheFloorDoesNotSink) {
  const double a = 5e-3, b = 1.3e-3, psi = 0.4, drop = 7e-4, h = 1e-5;
  Model m = testutil::dropModel(kTS, ContactLaw::kRigid, 0.47, 0.5, a, b, drop, Vec2::Zero(), psi);
  m.integrator.dt_s = h;
  compileModel(&m);
  Data d;
  resetData(m, &d);
  const double e0 = mechanicalEnergy(m, d);
  const double bound = std::sqrt(2 * kG * drop) * h + 2 * h * m.integrator.zeno_velocity_mps;
  double worst = 0, psi_min = 1e9, psi_max = -1e9;
  long impacts_settled = -1;
  for (int i = 1; i <= 1000; ++i) {
    ASSERT_EQ(advanceTo(m, &d, 1e-3 * i), StepStatus::kOk);
    const double s = std::sin(d.z[2]), c = std::cos(d.z[2]);
    const double gap = d.z[1] - std::sqrt(a * a * s * s + b * b * c * c);
    if (i >= 100) worst = std::min(worst, gap);
    if (i == 100) impacts_settled = d.stats.impacts;
    if (i >= 500) psi_min = std::min(psi_min, d.z[2]), psi_max = std::max(psi_max, d.z[2]);
  }
  EXPECT_GE(worst, -bound);
  EXPECT_GE(psi_max - psi_min, 0.1);
  EXPECT_LE(mechanicalEnergy(m, d), e0);
  EXPECT_EQ(d.stats.impacts, impacts_settled);
  EXPECT_GE(d.stats.impacts, 5);
  EXPECT_LE(d.stats.impacts, 9);
  RecordProperty("worst_gap_m", fmt(worst));
  RecordProperty("depth_corrections", fmt(d.stats.depth_corrections));
}

}  // namespace
}  // namespace threshing_sim
