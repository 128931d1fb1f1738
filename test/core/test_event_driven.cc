// Tests of what only the event-driven integrator (src/core/event_driven.cc) has, on closed
// forms and invariants: free flight, a contact closed at the start, Zeno accumulation in finite
// steps, the pile's energy step by step, and the exact propagation of free teeth (closed form,
// matrix exponential, against Dormand-Prince). What both integrators must satisfy is in
// test_integrators.cc.
//
// Tolerances: the smooth phases are integrated by Dormand-Prince 5(4) to a local tolerance of
// 1e-9 (model.integrator.tolerance, scaled by 1e-2 m for positions and 1 m/s for velocities)
// and events are located by bisection to ~1e-15 s, so whatever a closed form predicts is
// matched to ~1e-9 relative unless the model itself departs from the closed form.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>

#include "../../src/core/internal.h"
#include "free_motion_reference.h"
#include "sim_test_util.h"
#include "threshing_sim/core/beam.h"
#include "threshing_sim/core/simulator.h"

namespace threshing_sim {
namespace {

using testutil::fmt;
using testutil::kG;
using testutil::kPi;

constexpr IntegratorType kED = IntegratorType::kEventDriven;

// ---------------------------------------------------------------------------------------------
// Free flight.

// A free kernel: c(t) = c0 + v0 t + g t^2 / 2, psi(t) = psi0 + w0 t. DOPRI5 integrates a
// quadratic exactly, so only rounding remains: ~500 steps of ~1e-17 relative each; 1e-12 m
// and 1e-12 m/s leave room for that and nothing else.
TEST(EventDriven, FreeKernelFollowsTheParabola) {
  Model m = testutil::bareModel(kED);
  const Vec2 c0(0.01, 0.3), v0(1.2, 2.5);
  const double psi0 = 0.4, w0 = 40.0;
  KernelModel k = testutil::makeKernel(5e-3, 1.3e-3, c0, v0, psi0);
  k.initial_angular_velocity_radps = w0;
  m.kernels = {k};
  compileModel(&m);
  Data d;
  resetData(m, &d);
  for (double t : {0.01, 0.023, 0.05}) {
    ASSERT_EQ(advanceTo(m, &d, t), StepStatus::kOk);
    ASSERT_EQ(d.t_s, t);  // lands exactly
    const Vec2 c = c0 + v0 * t + 0.5 * m.gravity_mps2 * t * t;
    const Vec2 v = v0 + m.gravity_mps2 * t;
    EXPECT_NEAR(d.z[0], c.x(), 1e-12) << "t = " << t;
    EXPECT_NEAR(d.z[1], c.y(), 1e-12) << "t = " << t;
    EXPECT_NEAR(d.z[2], psi0 + w0 * t, 1e-12) << "t = " << t;
    EXPECT_NEAR(d.u[0], v.x(), 1e-12) << "t = " << t;
    EXPECT_NEAR(d.u[1], v.y(), 1e-12) << "t = " << t;
    EXPECT_NEAR(d.u[2], w0, 1e-12) << "t = " << t;
  }
  EXPECT_TRUE(d.events.empty());
}

// ---------------------------------------------------------------------------------------------
// Contacts at the start of a run (restitution and the friction limit on an incline are checked
// for both integrators in test_integrators.cc).

// A kernel resting on the plate at t = 0 (gap exactly 0) stays on it. Regression guard: an
// event used to fire only when a function went from > 0 to <= 0 over a step, so a pair closed
// at the start never fired and the kernel fell through the plate (12 mm below it after
// 0.05 s). The step start now treats a separated pair with g_N <= 0 and dg_N/dt <= 0 as an
// initial contact.
TEST(EventDriven, RestingContactAtStartIsHeld) {
  const double r = 1.5e-3;
  Model m = testutil::dropModel(kED, ContactLaw::kRigid, 0.5, 0.5, r, r, 0.0, Vec2::Zero());
  compileModel(&m);
  Data d;
  testutil::runTo(m, &d, 0.05);
  // Resting: it must stay on the plate; 1e-9 m is the constraint projection's accuracy.
  EXPECT_NEAR(d.z[1], r, 1e-9) << "the kernel sank " << r - d.z[1] << " m";
  EXPECT_NEAR(d.u[1], 0.0, 1e-9);
}

// A slip that starts at the friction limit with its slip velocity at round-off on the wrong
// side of its slip sign must still stop where the slip velocity next reaches zero. Hard case 9
// at tolerance 1e-10 (dg_T/dt = +2.5e-14 for a slip sign of -1) had that slip's velocity event
// unarmed: its reversal inside the next step went unseen, and the contact slid on with its
// friction force pushing. Here a disc (radius r, mass m, I = m r^2 / 2) held by a horizontal
// spring at its centre, stretched by x0 so that rolling would need the friction force
// k x0 / 3 = mu m g (1 + excess), starts 1e-12 m into the plate; its contact opens at the
// start of the second advanceTo call, t_l = 1 ns, the spring having given it
// dx/dt = -3 mu g t_l (1 + excess), and the impact stops its contact point, leaving it rolling
// at v_l = -2 mu g t_l (2/3 of that). It slips (sign +1: the contact point moves to -x,
// dg_T/dt = -dx/dt - r w), and 1 ps later its slip velocity is set to -1e-18 m/s, the wrong
// side. With t from the landing, d2(dg_T/dt)/dt2 = -k dx/dt / m and dx/dt = v_l - 2 mu g t, so
// the slip velocity returns to zero where t^2 / 3 + t_l t = 3 excess m / k (t = 0.11 us, inside
// the first step after the change), and there rolling needs less than mu m g: the contact
// sticks. The change also removes the landing's residual slip velocity (9e-17 m/s), which
// moves the stop by 0.5 %: 1 % bounds it. Without the arming the contact never sticks.
// Global scheme: the island scheme keeps its own copy of the state between calls.
TEST(EventDriven, SlipStartedAtTheLimitWithRoundOffOnTheWrongSideSticksWhereItStops) {
  const double r = 1.5e-3, mu = 0.3, k_Npm = 200.0, excess = 1e-8, anchor_m = 0.01;
  Model m = testutil::dropModel(kED, ContactLaw::kRigid, 0.5, mu, r, r, -1e-12, Vec2::Zero());
  m.integrator.islands = false;
  KernelModel& kernel = m.kernels[0];
  const double x0_m = 3.0 * mu * kernel.mass_kg * kG * (1.0 + excess) / k_Npm;
  kernel.pedicel.present = true;
  kernel.pedicel.p_WA_W = kernel.initial_position_m - Vec2(anchor_m, 0.0);
  kernel.pedicel.rest_length_m = anchor_m - x0_m;
  kernel.pedicel.stiffness_Npm = k_Npm;
  kernel.pedicel.damping_Nspm = 0.0;
  kernel.pedicel.detachment_force_N = 1e3;
  compileModel(&m);
  const double t_land_s = 1e-9, tau_s = excess * kernel.mass_kg / k_Npm;
  const double t_stop_s = 1.5 * (std::sqrt(t_land_s * t_land_s + 4.0 * tau_s) - t_land_s);
  Data d;
  resetData(m, &d);
  std::vector<ContactEvent> events;
  for (double t_s : {t_land_s, 1.001 * t_land_s, 30.0 * t_stop_s}) {
    ASSERT_EQ(advanceTo(m, &d, t_s), StepStatus::kOk);
    events.insert(events.end(), d.events.begin(), d.events.end());
    d.events.clear();
    ASSERT_FALSE(d.contacts.empty());
    if (t_s == 1.001 * t_land_s) {
      ASSERT_EQ(d.contacts[0].state, ContactState::kSlip);
      d.u[0] += d.contacts[0].slip_velocity_mps + 1e-18;
    }
  }
  // Landed at t_l, slipped, stuck at t_l + t_stop and stayed stuck.
  ASSERT_EQ(events.size(), 2u);
  EXPECT_EQ(events[0].from, ContactState::kSeparated);
  EXPECT_EQ(events[0].t_s, t_land_s);
  EXPECT_EQ(events[1].from, ContactState::kSlip);
  EXPECT_EQ(events[1].to, ContactState::kStick);
  EXPECT_NEAR(events[1].t_s - t_land_s, t_stop_s, 1e-2 * t_stop_s);
  EXPECT_EQ(d.contacts[0].state, ContactState::kStick);
}

// ---------------------------------------------------------------------------------------------
// Zeno: a kernel dropped from 10 mm with e = 0.5 bounces ever lower; the impact times
// accumulate at t_inf = t0 (1 + 2 e / (1 - e)) (t0 = sqrt(2 h / g)). The Zeno rule makes
// impacts slower than zeno_velocity (1 mm/s) plastic, so the sequence stops after finitely
// many impacts: v_k = e^k v_imp < 1 mm/s for k = 9 here.

TEST(EventDriven, ZenoBouncingComesToRestInFiniteSteps) {
  const double r = 1.5e-3, h0 = 0.01;
  for (ContactLaw law : {ContactLaw::kRigid}) {
    Model m = testutil::dropModel(kED, law, 0.5, 0.5, r, r, h0, Vec2::Zero());
    compileModel(&m);
    Data d;
    testutil::runTo(m, &d, 1.0);
    EXPECT_EQ(d.t_s, 1.0);
    // Finite work: the step count is set by max_step (1e-4 s -> 1e4 steps over 1 s), not by
    // the accumulation; 20 % plus 200 for the event steps.
    EXPECT_LE(d.steps, static_cast<long>(1.2 * 1.0 / m.integrator.max_step_s) + 200);
    // 9 impacts to go below 1 mm/s from 0.443 m/s, +-1 for the rounding of the cut.
    EXPECT_GE(d.stats.impacts, 8);
    EXPECT_LE(d.stats.impacts, 11);
    // The last impact falls just before t_inf: the cut removes at most the flight times after
    // a bounce below v_zeno, sum 2 v_z e^k / g <= 2 v_z / (g (1 - e)) = 0.4 ms.
    const double t0 = std::sqrt(2 * h0 / kG), e = 0.5;
    const double t_inf = t0 * (1 + 2 * e / (1 - e));
    double t_last = 0;
    for (const ContactEvent& ev : d.events)
      if (ev.is_impact) t_last = std::max(t_last, ev.t_s);
    EXPECT_LE(t_last, t_inf + 1e-9);
    EXPECT_GE(t_last, t_inf - 2 * m.integrator.zeno_velocity_mps / (kG * (1 - e)) - 1e-9);
    RecordProperty("t_last_impact", fmt(t_last));
    RecordProperty("t_inf", fmt(t_inf));
    // At rest on the plate, no drift through it (1e-9 m: the projection's accuracy).
    EXPECT_NEAR(d.z[1], r, 1e-9);
    EXPECT_NEAR(d.u[1], 0.0, 1e-9);
    EXPECT_LE(d.stats.max_penetration_m, 1e-9);
  }
}

// ---------------------------------------------------------------------------------------------
// No energy from impacts with friction (docs/model.md §8: Newton's law with friction can
// create energy; the integrator must not let it).

// The pile of test_integrators.cc (ImpactsWithFrictionNeverCreateEnergy), seed 8, to 31 ms,
// checked step by step: with e <= 1, mu > 0, a still drum and no compliant
// contact (which would store energy), mechanicalEnergy can only fall. 1e-10 J (1e-7 of E0)
// is the integration error a step may add.
// Regression guard (seed 8: kernels stacked on the floor, several closed sticking rigid
// contacts on one body): the projection of closed contacts once used residuals evaluated
// before the pass (a Jacobi iteration), which diverged for such coupled rows; the energy rose
// step after step to 4500 times E0 within 3 ms. projectConstraints() now re-evaluates each
// contact after the previous one's correction (Gauss-Seidel).
TEST(EventDriven, MechanicalEnergyNeverRisesInAKernelPile) {
  Model m = testutil::kernelPileModel(kED, ContactLaw::kRigid, 0.5, 0.8, 8u);
  compileModel(&m);
  Data d;
  resetData(m, &d);
  const double E0 = mechanicalEnergy(m, d);
  double E = E0, max_rise = 0, t_max_rise = 0;
  while (d.t_s < 0.031) {
    ASSERT_NE(step(m, &d), StepStatus::kFailed);
    const double E1 = mechanicalEnergy(m, d);
    if (E1 - E > max_rise) {
      max_rise = E1 - E;
      t_max_rise = d.t_s;
    }
    E = E1;
  }
  EXPECT_LE(max_rise, 1e-10) << "at t = " << t_max_rise;
  EXPECT_LE(E, E0);
  // A rigid contact must not be penetrated beyond the projection's accuracy.
  EXPECT_LE(d.stats.max_penetration_m, 1e-9);
}

// ---------------------------------------------------------------------------------------------
// Exact propagation of free teeth (IntegratorParams::exact_free_teeth).

using testutil::referenceFreeMotion;  // free_motion_reference.h

// One mode: q'' + c q' + w2 q = 0 with w2 = omega0^2 + Omega^2 (K_G - 1), c = 2 zeta omega0, has
// the closed form q = exp(-c t / 2) (q0 cos wd t + (qd0 + c q0 / 2) / wd sin wd t). The
// propagator must match it to rounding (1e-12 of the amplitude) from 1 us to 10 ms (200
// periods), at rest and at 800 and 1500 rpm.
TEST(EventDriven, FreeToothPropagatorMatchesOneModeClosedForm) {
  Model m = testutil::defaultSceneModel(kED);
  m.teeth[0].n_modes = 1;
  compileModel(&m);
  const ToothModel& tm = m.teeth[0];
  for (double omega : {0.0, 83.78, 157.08}) {
    internal::ToothPropagator prop;
    ASSERT_TRUE(internal::buildToothPropagator(m, 0, omega, &prop));
    const double w2 = tm.omega0_sq[0] + omega * omega * (tm.K_G(0, 0) - 1.0);
    const double c = tm.damping_coeff[0];
    const double wd = std::sqrt(w2 - 0.25 * c * c);
    const double q0 = 2e-4, qd0 = -3.0;  // [sqrt(kg) m], [sqrt(kg) m/s]
    const double q_scale = std::hypot(q0, qd0 / std::sqrt(w2));
    VecX y0(2), q1(1), qd1(1);
    y0 << q0, qd0;
    for (double t : {1e-6, 1e-5, 1e-4, 1e-3, 1e-2}) {
      internal::propagateTooth(&prop, t, y0.head(1), y0.tail(1), q1, qd1);
      const double e = std::exp(-0.5 * c * t), co = std::cos(wd * t), si = std::sin(wd * t);
      const double b = (qd0 + 0.5 * c * q0) / wd;
      const double q = e * (q0 * co + b * si);
      const double qd = -0.5 * c * q + e * (-q0 * wd * si + b * wd * co);
      EXPECT_NEAR(q1[0], q, 1e-12 * q_scale) << "Omega " << omega << " t " << t;
      EXPECT_NEAR(qd1[0], qd, 1e-12 * q_scale * std::sqrt(w2)) << "Omega " << omega << " t " << t;
    }
  }
}

// Four and eight coupled modes (K_G couples them at speed): the propagator against the
// reference matrix exponential for a random state, per block to 1e-12 of the block's size
// (rounding). A rigid tooth has no propagator.
TEST(EventDriven, FreeToothPropagatorMatchesMatrixExponential) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> uni(-1.0, 1.0);
  for (int n : {4, 8}) {
    Model m = testutil::defaultSceneModel(kED);
    m.teeth[0].n_modes = n;
    compileModel(&m);
    const ToothModel& tm = m.teeth[0];
    for (double omega : {0.0, 83.78, 157.08}) {
      internal::ToothPropagator prop;
      ASSERT_TRUE(internal::buildToothPropagator(m, 0, omega, &prop));
      VecX y0(2 * n);
      for (int i = 0; i < n; ++i) {
        y0[i] = 1e-4 * uni(rng);
        y0[n + i] = 1e-4 * std::sqrt(tm.omega0_sq[i]) * uni(rng);
      }
      VecX q1(n), qd1(n);
      for (double h : {1e-7, 3e-6, 5e-5, 1e-4, 2e-3}) {
        const VecX y1 = referenceFreeMotion(tm, omega, h, y0);
        internal::propagateTooth(&prop, h, y0.head(n), y0.tail(n), q1, qd1);
        EXPECT_LE((q1 - y1.head(n)).cwiseAbs().maxCoeff(), 1e-12 * y1.head(n).cwiseAbs().maxCoeff())
            << n << " modes, Omega " << omega << ", h " << h;
        EXPECT_LE((qd1 - y1.tail(n)).cwiseAbs().maxCoeff(),
                  1e-12 * y1.tail(n).cwiseAbs().maxCoeff())
            << n << " modes, Omega " << omega << ", h " << h;
      }
    }
  }
  Model rigid = testutil::defaultSceneModel(kED);
  rigid.teeth[0].n_modes = 0;
  compileModel(&rigid);
  internal::ToothPropagator prop;
  EXPECT_FALSE(internal::buildToothPropagator(rigid, 0, 83.78, &prop));
}

// A plucked tooth decaying freely at 800 rpm (the kernel sits at the drum axis, far from it):
// the event-driven run with exact propagation against the matrix exponential of the 4 modes
// (1e-9 of the amplitude: rounding over its steps), and against a Dormand-Prince run at a tight
// tolerance (1e-10: 1e-6 of the amplitude after ~5000 steps) that needs many more steps (it
// resolves the ~20 kHz fourth mode). The drive work (the drum holds its speed against the tooth's
// angular momentum) agrees too.
TEST(EventDriven, FreeToothDecayMatchesDormandPrinceAndClosedForm) {
  Model m = testutil::defaultSceneModel(kED);
  m.kernels[0].initial_position_m = Vec2(0.0, 0.0);
  m.integrator.tolerance = 1e-10;
  compileModel(&m);
  const ToothModel& tm = m.teeth[0];
  const int n = tm.n_modes;
  const double omega = m.drum.initial_speed_radps;
  Model m_rk = m;
  m_rk.integrator.exact_free_teeth = false;
  Data d, d_rk;
  resetData(m, &d);
  resetData(m_rk, &d_rk);
  VecX y0(2 * n);
  y0 << 1e-4, -2e-5, 5e-6, 0.0, 0.02, 0.5, -0.3, 0.2;  // [sqrt(kg) m], [sqrt(kg) m/s]
  for (Data* x : {&d, &d_rk}) {
    x->z.head(n) = y0.head(n);
    x->u.head(n) = y0.tail(n);
  }
  const double amp_q = y0.head(n).cwiseAbs().maxCoeff();
  const double amp_tip_m = std::abs(toothDeflection(m, d, 0, tm.length_m));
  for (int i = 1; i <= 10; ++i) {
    const double t = 5e-4 * i;
    ASSERT_EQ(advanceTo(m, &d, t), StepStatus::kOk);
    ASSERT_EQ(advanceTo(m_rk, &d_rk, t), StepStatus::kOk);
    const VecX y = referenceFreeMotion(tm, omega, t, y0);
    EXPECT_LE((d.z.head(n) - y.head(n)).cwiseAbs().maxCoeff(), 1e-9 * amp_q) << "t " << t;
    EXPECT_LE((d_rk.z.head(n) - y.head(n)).cwiseAbs().maxCoeff(), 1e-6 * amp_q) << "t " << t;
    EXPECT_NEAR(toothDeflection(m, d, 0, tm.length_m), toothDeflection(m_rk, d_rk, 0, tm.length_m),
                1e-6 * amp_tip_m)
        << "t " << t;
  }
  EXPECT_EQ(d.stats.impacts, 0);
  EXPECT_LT(10 * d.steps, d_rk.steps);
  EXPECT_NEAR(d.stats.drive_work_J, d_rk.stats.drive_work_J,
              1e-6 * std::abs(d_rk.stats.drive_work_J) + 1e-12);
  RecordProperty("steps_exact", std::to_string(d.steps));
  RecordProperty("steps_dormand_prince", std::to_string(d_rk.steps));
}

// The default scene at its tolerance 1e-6 with and without exact free teeth, both against a
// Dormand-Prince reference at 1e-9: the kernel's exit velocity and the tooth's tip deflection
// every 0.5 ms agree with the reference to the accuracy the plain run has (1e-5 relative),
// the peak normal force as well, and the exact run takes fewer steps.
TEST(EventDriven, ExactFreeTeethAgreeOnTheDefaultScene) {
  Model m = testutil::defaultSceneModel(kED);
  compileModel(&m);
  Model m_rk = m;
  m_rk.integrator.exact_free_teeth = false;
  Model m_ref = m_rk;
  m_ref.integrator.tolerance = 1e-9;
  Data d, d_rk, d_ref;
  resetData(m, &d);
  resetData(m_rk, &d_rk);
  resetData(m_ref, &d_ref);
  const double L = m.teeth[0].length_m;
  double worst_tip_m = 0.0, tip_scale_m = 0.0;
  for (int i = 1; i <= 20; ++i) {
    const double t = 5e-4 * i;
    ASSERT_EQ(advanceTo(m, &d, t), StepStatus::kOk);
    ASSERT_EQ(advanceTo(m_rk, &d_rk, t), StepStatus::kOk);
    ASSERT_EQ(advanceTo(m_ref, &d_ref, t), StepStatus::kOk);
    const double tip_ref = toothDeflection(m_ref, d_ref, 0, L);
    worst_tip_m = std::max(worst_tip_m, std::abs(toothDeflection(m, d, 0, L) - tip_ref));
    tip_scale_m = std::max(tip_scale_m, std::abs(tip_ref));
  }
  ASSERT_EQ(d.stats.impacts, 1);
  ASSERT_EQ(d_ref.stats.impacts, 1);
  const int k = m.kernels[0].dof_offset;
  const double v_ref = d_ref.u.segment<2>(k).norm();
  const double err_exact = std::abs(d.u.segment<2>(k).norm() - v_ref) / v_ref;
  const double err_rk = std::abs(d_rk.u.segment<2>(k).norm() - v_ref) / v_ref;
  EXPECT_LT(err_exact, 1e-5);
  EXPECT_LT(err_rk, 1e-5);
  EXPECT_LT(worst_tip_m, 1e-3 * tip_scale_m);
  EXPECT_NEAR(d.stats.peak_normal_force_N, d_ref.stats.peak_normal_force_N,
              0.02 * d_ref.stats.peak_normal_force_N);
  EXPECT_LT(d.steps, d_rk.steps);
  RecordProperty("exit_speed_error_exact", fmt(err_exact));
  RecordProperty("exit_speed_error_dormand_prince", fmt(err_rk));
  RecordProperty("tip_error_m", fmt(worst_tip_m));
  RecordProperty("steps_exact", std::to_string(d.steps));
  RecordProperty("steps_dormand_prince", std::to_string(d_rk.steps));
}

}  // namespace
}  // namespace threshing_sim
