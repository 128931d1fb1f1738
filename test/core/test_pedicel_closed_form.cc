// The closed form of an idle kernel on its pedicel (src/core/async/pedicel_propagator.h): its
// linearisation, its accuracy against the integrated nonlinear pedicel, its validity bound, the
// pedicel break, and its use by the island scheme.
#include <gtest/gtest.h>

#include <cmath>

#include "../../src/core/async/async.h"
#include "sim_test_util.h"
#include "threshing_sim/core/simulator.h"

namespace threshing_sim {
namespace {

using internal::PedicelAmplitude;
using internal::PedicelPropagator;
using internal::PedicelVec;

constexpr double kAnchorAngle = 0.7;  // direction of the anchor from the kernel's start [rad]

// A kernel of the bench stream's kind (28 mg, 5 x 1.3 mm) on a 3 mm stem (1600 N/m), compiled.
KernelModel benchKernel(double detachment_force_N = 1.6) {
  KernelModel k = testutil::makeKernel(5e-3, 1.3e-3, Vec2(0.0, 0.0), Vec2::Zero(), kAnchorAngle);
  k.pedicel.present = true;
  k.pedicel.p_WA_W = 8e-3 * Vec2(std::cos(kAnchorAngle), std::sin(kAnchorAngle));
  k.pedicel.p_KP_K = Vec2(5e-3, 0.0);
  k.pedicel.stiffness_Npm = 1600.0;
  k.pedicel.damping_Nspm = 0.002;
  k.pedicel.rest_length_m = 3e-3;
  k.pedicel.detachment_force_N = detachment_force_N;
  k.inertia_kgm2 = k.mass_kg * (5e-3 * 5e-3 + 1.3e-3 * 1.3e-3) / 4.0;
  return k;
}

const Vec2 kGravity(0.0, -testutil::kG);

// The class's equilibrium state for kernel k.
PedicelVec equilibriumOf(const PedicelPropagator& p, const KernelModel& k) {
  PedicelVec y = PedicelVec::Zero();
  y.head<2>() = k.pedicel.p_WA_W + p.p_AC_W;
  y[2] = p.psi_eq_rad;
  return y;
}

// Classical RK4 of the nonlinear pedicel dynamics (pedicelRates) with n steps over h_s.
PedicelVec integrate(const KernelModel& k, PedicelVec y, double h_s, long n) {
  const double dt = h_s / static_cast<double>(n);
  for (long s = 0; s < n; ++s) {
    const PedicelVec k1 = internal::pedicelRates(k, kGravity, y);
    const PedicelVec k2 = internal::pedicelRates(k, kGravity, y + 0.5 * dt * k1);
    const PedicelVec k3 = internal::pedicelRates(k, kGravity, y + 0.5 * dt * k2);
    const PedicelVec k4 = internal::pedicelRates(k, kGravity, y + dt * k3);
    y += dt / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4);
  }
  return y;
}

TEST(PedicelClosedForm, JacobianMatchesFiniteDifferences) {
  const KernelModel k = benchKernel();
  PedicelVec y;
  y << 1e-3, -2e-3, 0.4, 0.03, -0.02, 5.0;
  const internal::PedicelMat J = internal::pedicelJacobian(k, y);
  for (int j = 0; j < 6; ++j) {
    const double h = j < 2 ? 1e-9 : j == 2 ? 1e-7 : j < 5 ? 1e-5 : 1e-3;  // [m, rad, m/s, rad/s]
    PedicelVec yp = y, ym = y;
    yp[j] += h;
    ym[j] -= h;
    const PedicelVec col =
        (internal::pedicelRates(k, kGravity, yp) - internal::pedicelRates(k, kGravity, ym)) /
        (2.0 * h);
    EXPECT_LT((col - J.col(j)).norm(), 1e-5 * std::max(1.0, col.norm())) << "column " << j;
  }
}

TEST(PedicelClosedForm, EquilibriumIsAStaticBalanceAndStable) {
  const KernelModel k = benchKernel();
  const PedicelPropagator p = internal::buildPedicelPropagator(k, kGravity);
  ASSERT_TRUE(p.valid);
  const PedicelVec f = internal::pedicelRates(k, kGravity, equilibriumOf(p, k));
  EXPECT_LT(f.norm(), 1e-9);
  // Hanging: the centre straight below the anchor, by the stretched stem and the attachment arm.
  EXPECT_NEAR(p.p_AC_W.x(), 0.0, 1e-15);
  EXPECT_NEAR(-p.p_AC_W.y(), 3e-3 + k.mass_kg * testutil::kG / 1600.0 + 5e-3, 1e-12);
  for (int i = 0; i < 6; ++i) EXPECT_LE(p.lambda[i].real(), 0.0);
  // The stiffest mode is the stem's stretch: sqrt(k / m) (the attachment point on the line).
  double w_max = 0.0;
  for (int i = 0; i < 6; ++i) w_max = std::max(w_max, std::abs(p.lambda[i].imag()));
  EXPECT_NEAR(w_max, std::sqrt(1600.0 / k.mass_kg), 1e-3 * w_max);
}

// The closed form against the integrated nonlinear pedicel over 100 periods of its fastest
// mode, from a small amplitude in every state: within the validity bound's error, which is
// within the tolerance's scale.
TEST(PedicelClosedForm, AgreesWithTheIntegratedPedicelOverAHundredPeriods) {
  const KernelModel k = benchKernel();
  const PedicelPropagator p = internal::buildPedicelPropagator(k, kGravity);
  ASSERT_TRUE(p.valid);
  PedicelVec y0 = equilibriumOf(p, k);
  PedicelVec dy;
  dy << 1e-10, -1e-7, 1e-8, 1e-7, 1e-4, 1e-5;
  y0 += dy;
  const double tol = 1e-6;
  const PedicelAmplitude a = internal::pedicelAmplitude(p, k, y0);
  const double span = internal::pedicelClosedFormSpan(p, a, tol);
  const double H = 100.0 * p.min_period_s;
  ASSERT_GE(span, H) << "rho " << a.rho;
  const PedicelVec closed = internal::propagatePedicel(p, a, H);
  const PedicelVec exact = integrate(k, y0, H, 200000);
  // Error within tol x the error scale's absolute floor (1e-2 m or rad, 1 m/s or rad/s).
  for (int j = 0; j < 6; ++j)
    EXPECT_LE(std::abs(closed[j] - exact[j]), tol * (j < 3 ? 1e-2 : 1.0)) << "state " << j;
  // And it is not trivially so: the motion (the stem's stretch, damped over the span) is far
  // larger than the error.
  EXPECT_GT(std::abs(exact[4] - y0[4]), 1e-5);
}

// The bound is not loose by orders of magnitude either: at an amplitude where it forbids the
// span, the linearisation error over it is a sizeable share of the tolerance's scale.
TEST(PedicelClosedForm, ValidityBoundSwitchesToIntegrationAtLargeAmplitude) {
  const KernelModel k = benchKernel();
  const PedicelPropagator p = internal::buildPedicelPropagator(k, kGravity);
  ASSERT_TRUE(p.valid);
  const double tol = 1e-6;
  PedicelVec y = equilibriumOf(p, k);
  y[0] += 2e-3;  // a 2 mm swing on an 8 mm pendulum
  const PedicelAmplitude large = internal::pedicelAmplitude(p, k, y);
  const double span = internal::pedicelClosedFormSpan(p, large, tol);
  EXPECT_LT(span, 0.25 * p.min_period_s);
  // Its error over a tenth of the pendulum's period is indeed beyond the tolerance.
  const double H = 0.018;
  const PedicelVec err = internal::propagatePedicel(p, large, H) - integrate(k, y, H, 40000);
  EXPECT_GT(err.head<3>().cwiseAbs().maxCoeff(), tol * 1e-2);
  // Small amplitudes: a span of many periods.
  PedicelVec y_small = equilibriumOf(p, k);
  y_small[0] += 1e-7;
  EXPECT_GT(internal::pedicelClosedFormSpan(p, internal::pedicelAmplitude(p, k, y_small), tol),
            100.0 * p.min_period_s);
}

TEST(PedicelClosedForm, ForceBoundRefusesASpanThatCouldBreakTheStem) {
  // Detachment at 1.5 m g: hanging at rest holds, a 2 um stretch (3.2 mN) could break it.
  const double mg = 2.8e-5 * testutil::kG;
  const KernelModel k = benchKernel(1.5 * mg);
  const PedicelPropagator p = internal::buildPedicelPropagator(k, kGravity);
  ASSERT_TRUE(p.valid);
  PedicelVec y = equilibriumOf(p, k);
  EXPECT_GT(internal::pedicelClosedFormSpan(p, internal::pedicelAmplitude(p, k, y), 1e-6), 1.0);
  y[1] -= 2e-6;
  EXPECT_EQ(internal::pedicelClosedFormSpan(p, internal::pedicelAmplitude(p, k, y), 1e-6), 0.0);
}

// A lone pedicel kernel in a model: displaced from its hanging equilibrium by dy.
Model swingModel(IntegratorType type, bool islands, const PedicelVec& dy,
                 double detachment_force_N = 1.6) {
  Model m = testutil::bareModel(type);
  KernelModel k = benchKernel(detachment_force_N);
  const PedicelPropagator p = internal::buildPedicelPropagator(k, m.gravity_mps2);
  const PedicelVec y = equilibriumOf(p, k) + dy;
  k.initial_position_m = y.head<2>();
  k.initial_angle_rad = y[2];
  k.initial_velocity_mps = y.segment<2>(3);
  k.initial_angular_velocity_radps = y[5];
  m.kernels.push_back(k);
  m.integrator.islands = islands;
  m.integrator.tolerance = 1e-6;
  compileModel(&m);
  return m;
}

long closedForms(const Data& d) { return d.ws->async ? d.ws->async->pedicel_closed_forms : 0; }

TEST(PedicelClosedForm, IslandSchemeUsesItAndAgreesWithTheGlobalIntegrator) {
  PedicelVec dy;
  dy << 1e-10, -1e-7, 1e-8, 1e-7, 1e-4, 1e-5;
  for (IntegratorType type : {IntegratorType::kEventDriven, IntegratorType::kTimeStepping}) {
    Model mg = swingModel(IntegratorType::kEventDriven, false, dy);
    mg.integrator.tolerance = 1e-10;
    const Model ma = swingModel(type, true, dy);
    Data g, a;
    resetData(mg, &g);
    resetData(ma, &a);
    const double t_end = 0.05;  // ~60 periods of the stem's stretch
    ASSERT_EQ(advanceTo(mg, &g, t_end), StepStatus::kOk);
    ASSERT_EQ(advanceTo(ma, &a, t_end), StepStatus::kOk);
    EXPECT_LT((g.z - a.z).cwiseAbs().maxCoeff(), 1e-6 * 1e-2);
    EXPECT_LT((g.u - a.u).cwiseAbs().maxCoeff(), 1e-6);
    EXPECT_EQ(a.stats.scheduler.pedicel_steps, 0);  // no numerical step: the closed form
    EXPECT_GT(closedForms(a), 0);
  }
}

TEST(PedicelClosedForm, LargeSwingIsIntegratedNumerically) {
  PedicelVec dy = PedicelVec::Zero();
  dy[0] = 3e-3;
  const Model m = swingModel(IntegratorType::kEventDriven, true, dy);
  Data d;
  resetData(m, &d);
  ASSERT_EQ(advanceTo(m, &d, 0.01), StepStatus::kOk);
  EXPECT_GT(d.stats.scheduler.pedicel_steps, 0);
  EXPECT_EQ(closedForms(d), 0);
}

TEST(PedicelClosedForm, BreakIsDetectedNearEquilibrium) {
  // Detachment at 1.5 m g, released 2 um below equilibrium: the first rebound breaks the stem.
  const double mg = 2.8e-5 * testutil::kG;
  PedicelVec dy = PedicelVec::Zero();
  dy[1] = -2e-6;
  const Model ma = swingModel(IntegratorType::kEventDriven, true, dy, 1.5 * mg);
  const Model mg_model = swingModel(IntegratorType::kEventDriven, false, dy, 1.5 * mg);
  Data a, g;
  resetData(ma, &a);
  resetData(mg_model, &g);
  ASSERT_EQ(advanceTo(ma, &a, 0.005), StepStatus::kOk);
  ASSERT_EQ(advanceTo(mg_model, &g, 0.005), StepStatus::kOk);
  EXPECT_EQ(a.kernel_attached[0], 0);
  EXPECT_EQ(g.kernel_attached[0], 0);
  EXPECT_NEAR(a.stats.kernel_detach_time_s[0], g.stats.kernel_detach_time_s[0], 2e-5);
}

TEST(PedicelClosedForm, Deterministic) {
  PedicelVec dy;
  dy << 1e-10, -1e-7, 1e-8, 1e-7, 1e-4, 1e-5;
  const Model m = swingModel(IntegratorType::kEventDriven, true, dy);
  Data a, b;
  resetData(m, &a);
  resetData(m, &b);
  for (int s = 1; s <= 20; ++s) {
    ASSERT_EQ(advanceTo(m, &a, 1e-3 * s), StepStatus::kOk);
    ASSERT_EQ(advanceTo(m, &b, 1e-3 * s), StepStatus::kOk);
  }
  for (int j = 0; j < 3; ++j) {
    EXPECT_EQ(a.z[j], b.z[j]);
    EXPECT_EQ(a.u[j], b.u[j]);
  }
  // A reset run repeats it bit for bit (the class is kept by the scheduler).
  resetData(m, &a);
  for (int s = 1; s <= 20; ++s) ASSERT_EQ(advanceTo(m, &a, 1e-3 * s), StepStatus::kOk);
  for (int j = 0; j < 3; ++j) EXPECT_EQ(a.z[j], b.z[j]);
}

// The calendar gives a kernel swinging within its closed form's validity the envelope of its
// oscillation: its wake is the longest horizon, and its trajectory stays in its circle.
TEST(PedicelClosedForm, EnvelopeBoundsTheTrajectory) {
  PedicelVec dy;
  dy << 1e-10, -1e-7, 1e-8, 1e-7, 1e-4, 1e-5;
  const Model m = swingModel(IntegratorType::kEventDriven, true, dy);
  Data d;
  resetData(m, &d);
  ASSERT_EQ(advanceTo(m, &d, 1e-4), StepStatus::kOk);
  const internal::KernelClock kc = d.ws->async->kernels[0];
  ASSERT_NE(kc.motion, internal::KernelMotion::kIsland);
  EXPECT_GE(kc.wake_s, 0.5);
  for (int s = 1; s <= 100; ++s) {
    ASSERT_EQ(advanceTo(m, &d, 1e-4 + 1e-4 * s), StepStatus::kOk);
    const Vec2 c = d.z.segment<2>(0);
    EXPECT_LE((c - kc.bound_c_W).norm() + m.kernels[0].semi_axis_b_m, kc.bound_r_m + 1e-12);
  }
}

}  // namespace
}  // namespace threshing_sim

namespace threshing_sim {
namespace {

// A kernel of the bench's idle swinging layout: radial, its stem unstretched along its axis
// (rest length 3 mm), released at rest at angle phi about its anchor, so that it swings and
// falls under gravity (release angles all around: the large-angle regime beyond any closed
// form). State [c_x, c_y, psi, v_x, v_y, omega].
Model releasedModel(IntegratorType type, double phi_rad, PedicelVec* y0) {
  Model m = testutil::bareModel(type);
  const Vec2 e(std::cos(phi_rad), std::sin(phi_rad));
  KernelModel k = benchKernel();
  k.initial_position_m = Vec2::Zero();
  k.initial_angle_rad = phi_rad;
  k.initial_velocity_mps = Vec2::Zero();
  k.initial_angular_velocity_radps = 0.0;
  k.pedicel.p_WA_W = 8e-3 * e;
  m.kernels.push_back(k);
  m.integrator.islands = true;
  m.integrator.tolerance = 1e-6;
  if (type == IntegratorType::kTimeStepping) m.integrator.dt_s = 1e-6;
  compileModel(&m);
  *y0 = PedicelVec::Zero();
  (*y0)[2] = phi_rad;
  return m;
}

// The pedicel clock of a lone swinging kernel against the nonlinear pedicel integrated by RK4
// at 50 ns steps (its error far below the tolerance), at release angles all around the anchor
// (the bench's idle swinging range), under both integrators: 2 ms (the bench's run) and 20 ms
// (the swing developed: ~20 periods of the stem's stretch). PEDICEL_CLOCK_DETAIL=1 prints each
// release's error.
TEST(PedicelClock, SwingingKernelAgreesWithATightIntegrationAtEveryReleaseAngle) {
  const double tol = 1e-6;
  for (IntegratorType type : {IntegratorType::kEventDriven, IntegratorType::kTimeStepping}) {
    for (double t_end : {2e-3, 2e-2}) {
      double worst_q = 0.0, worst_v = 0.0;
      for (int i = 0; i < 16; ++i) {
        const double phi = -M_PI + (2.0 * M_PI / 16.0) * (i + 0.5);
        PedicelVec y0;
        const Model m = releasedModel(type, phi, &y0);
        Data d;
        resetData(m, &d);
        ASSERT_EQ(advanceTo(m, &d, t_end), StepStatus::kOk);
        EXPECT_GT(d.stats.scheduler.pedicel_steps, 0) << "phi " << phi;  // numerically
        EXPECT_EQ(d.kernel_attached[0], 1);
        const PedicelVec ref = integrate(m.kernels[0], y0, t_end, std::lround(t_end / 5e-8));
        // The motion is far larger than the error: the kernel falls g t^2 / 2 at most.
        EXPECT_GT((ref.head<2>() - y0.head<2>()).norm(), 1e-7) << "phi " << phi;
        if (std::getenv("PEDICEL_CLOCK_DETAIL"))
          std::printf("phi %.3f closed %ld steps %ld dq %.3g %.3g %.3g dv %.3g %.3g %.3g\n", phi,
                      closedForms(d), d.stats.scheduler.pedicel_steps, d.z[0] - ref[0],
                      d.z[1] - ref[1], d.z[2] - ref[2], d.u[0] - ref[3], d.u[1] - ref[4],
                      d.u[2] - ref[5]);
        for (int j = 0; j < 3; ++j) {
          worst_q = std::max(worst_q, std::abs(d.z[j] - ref[j]) / (tol * 1e-2));
          worst_v = std::max(worst_v, std::abs(d.u[j] - ref[3 + j]) / tol);
        }
      }
      // In units of the error scale's absolute floors (tol x 1e-2 m or rad; tol x 1 m/s). Over
      // the bench's 2 ms: 0.004 (positions) and 3.2 (rates, the spin). Over 20 ms the local
      // error control lets the spin's error grow (~220 steps of at most tol x (1 + |omega|)
      // each): 10.6 and 1.1e3.
      const bool bench_run = t_end < 5e-3;
      EXPECT_LE(worst_q, bench_run ? 5.0 : 20.0) << "t_end " << t_end;
      EXPECT_LE(worst_v, bench_run ? 5.0 : 2e3) << "t_end " << t_end;
      std::printf("pedicel clock, %s, %g s: worst error %.3g (positions), %.3g (rates)\n",
                  type == IntegratorType::kEventDriven ? "event-driven" : "time stepping", t_end,
                  worst_q, worst_v);
    }
  }
}

}  // namespace
}  // namespace threshing_sim
