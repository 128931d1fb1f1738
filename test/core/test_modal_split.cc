// The Lawson split of the modal teeth in contact (IntegratorParams::modal_split,
// src/core/event_driven/modal_split.cc): with no contact force it is the free propagator (closed
// form), on a contact its Dormand-Prince steps converge at fifth order, and the default strike
// under both schemes agrees with a tight reference.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include "../../src/core/event_driven/context.h"
#include "free_motion_reference.h"
#include "sim_test_util.h"
#include "threshing_sim/core/beam.h"
#include "threshing_sim/core/simulator.h"

namespace threshing_sim {
namespace {

constexpr IntegratorType kED = IntegratorType::kEventDriven;

// The default scene with the kernel at the drum axis, far from the tooth, and every tooth
// integrated (no free-tooth path), split or not; its data a nanosecond in (workspace laid out).
Model farKernelModel(int n_modes, bool split) {
  Model m = testutil::defaultSceneModel(kED);
  m.teeth[0].n_modes = n_modes;
  m.kernels[0].initial_position_m = Vec2(0.0, 0.0);
  m.integrator.islands = false;
  m.integrator.exact_free_teeth = false;
  m.integrator.modal_split = split;
  compileModel(&m);
  return m;
}

// One trial step of length h from the tooth state y0 = [q; qdot] (no contact): the tooth's end
// state [q; qdot] and the step's error norm.
VecX freeTrialStep(const Model& m, const VecX& y0, double h, double* err) {
  Data d;
  resetData(m, &d);
  EXPECT_EQ(advanceTo(m, &d, 1e-9), StepStatus::kOk);
  const int n = m.teeth[0].n_modes;
  d.z.head(n) = y0.head(n);
  d.u.head(n) = y0.tail(n);
  internal::event_driven::Ctx c{m, d, *d.ws};
  VecX z1(d.z.size()), u1(d.u.size());
  double torque = 0;
  EXPECT_TRUE(internal::event_driven::dopriStep(c, d.t_s, h, d.z, d.u, &z1, &u1, err, &torque));
  VecX y1(2 * n);
  y1 << z1.head(n), u1.head(n);
  return y1;
}

// One mode with no contact force: a split step (the mode turning by 2 to 40 rad over it, beyond
// the split's threshold of a radian) is the free propagator, the closed form
// q = exp(-c t / 2) (q0 cos wd t + (qd0 + c q0 / 2) / wd sin wd t) to rounding (1e-12 of the
// amplitude), with an error estimate at rounding; a plain Dormand-Prince step of those lengths is
// far off (beyond its stability bound).
TEST(ModalSplit, ZeroContactForceIsTheFreePropagatorOneModeClosedForm) {
  const Model m = farKernelModel(1, true);
  const Model m_rk = farKernelModel(1, false);
  const ToothModel& tm = m.teeth[0];
  const double omega = m.drum.initial_speed_radps;
  const double w2 = tm.omega0_sq[0] + omega * omega * (tm.K_G(0, 0) - 1.0);
  const double c = tm.damping_coeff[0];
  const double wd = std::sqrt(w2 - 0.25 * c * c);
  const double q0 = 2e-4, qd0 = -3.0;  // [sqrt(kg) m], [sqrt(kg) m/s]
  const double q_scale = std::hypot(q0, qd0 / std::sqrt(w2));
  VecX y0(2);
  y0 << q0, qd0;
  for (double t : {5e-4, 2e-3, 1e-2}) {
    double err = -1, err_rk = -1;
    const VecX y = freeTrialStep(m, y0, t, &err);
    const VecX y_rk = freeTrialStep(m_rk, y0, t, &err_rk);
    const double e = std::exp(-0.5 * c * t), co = std::cos(wd * t), si = std::sin(wd * t);
    const double b = (qd0 + 0.5 * c * q0) / wd;
    const double q = e * (q0 * co + b * si);
    const double qd = -0.5 * c * q + e * (-q0 * wd * si + b * wd * co);
    EXPECT_NEAR(y[0], q, 1e-12 * q_scale) << "t " << t;
    EXPECT_NEAR(y[1], qd, 1e-12 * q_scale * std::sqrt(w2)) << "t " << t;
    EXPECT_LE(err, 1e-9) << "t " << t;  // rounding (the kernel's fall too), far below 1
    EXPECT_GT(std::abs(y_rk[0] - q), 1e-3 * q_scale) << "t " << t;
  }
}

// Four coupled modes (K_G couples them at speed), no contact force: split steps of 10 us to 1 ms
// against the matrix exponential of the free equations (free_motion_reference.h) to
// 1e-11 of the amplitude.
TEST(ModalSplit, ZeroContactForceIsTheFreePropagatorFourModes) {
  const Model m = farKernelModel(4, true);
  const ToothModel& tm = m.teeth[0];
  const int n = tm.n_modes;
  const double omega = m.drum.initial_speed_radps;
  VecX y0(2 * n);
  y0 << 1e-4, -2e-5, 5e-6, 0.0, 0.02, 0.5, -0.3, 0.2;  // [sqrt(kg) m], [sqrt(kg) m/s]
  const double amp_q = y0.head(n).cwiseAbs().maxCoeff();
  for (double t : {1e-5, 1e-4, 1e-3}) {
    double err = -1;
    const VecX y1 = freeTrialStep(m, y0, t, &err);
    const VecX y = testutil::referenceFreeMotion(tm, omega, t, y0);
    EXPECT_LE((y1.head(n) - y.head(n)).cwiseAbs().maxCoeff(), 1e-11 * amp_q) << "t " << t;
    EXPECT_LE(err, 1e-9) << "t " << t;  // rounding (the kernel's fall too), far below 1
  }
}

// The default strike's state in its compliant tooth-kernel contact, a few microseconds after it
// opened; the data (and its workspace: candidates, pair memory) as the integrator left it.
void strikeInContact(const Model& m, Data* d) {
  resetData(m, d);
  for (double t = 1e-6;; t += 1e-6) {
    ASSERT_EQ(advanceTo(m, d, t), StepStatus::kOk);
    bool active = false;
    for (const auto& kv : d->ws->memory)
      active = active || kv.second.state != ContactState::kSeparated;
    if (active) {
      ASSERT_EQ(advanceTo(m, d, t + 3e-6), StepStatus::kOk);
      return;
    }
    ASSERT_LT(t, 5e-3) << "the tooth never touched the kernel";
  }
}

// The end state [z; u] after n equal Dormand-Prince trial steps over H from the data's state,
// under the index sets of the contact (as the integrator steps a smooth phase).
VecX fixedSteps(const Model& m, Data* d, double H, int n) {
  internal::event_driven::Ctx c{m, *d, *d->ws};
  VecX z = d->z, u = d->u, z1(z.size()), u1(u.size());
  double err = 0, torque = 0;
  for (int i = 0; i < n; ++i) {
    EXPECT_TRUE(internal::event_driven::dopriStep(c, d->t_s + i * (H / n), H / n, z, u, &z1, &u1,
                                                  &err, &torque));
    z = z1;
    u = u1;
  }
  VecX y(z.size() + u.size());
  y << z, u;
  return y;
}

// Fifth order on a contact: the default strike's compliant contact (the tooth's modes, the
// kernel, the Hertz force) stepped over 4 us by 1 to 16 equal steps against 512 of them;
// the largest error of the tooth's and the kernel's states (scaled as the error control scales
// them) falls at a mean order within [4.5, 6.5] over the ladder (5.6 measured; single halvings
// 4.2 to 7.1 before the asymptote), each halving by at least 2^3.5: split with 20 modes, plain
// Dormand-Prince with the default 4.
TEST(ModalSplit, FifthOrderOnTheStrikeContact) {
  for (bool split : {true, false}) {
    Model m = testutil::defaultSceneModel(kED);
    // Split: 20 modes (modes: auto), whose fastest (4.2e6 rad/s) turns by 1 to 17 rad over the
    // steps below, where plain Dormand-Prince is unstable; plain: the default 4.
    if (split) m.teeth[0].n_modes = 20;
    m.integrator.islands = false;
    m.integrator.modal_split = split;
    compileModel(&m);
    Data d;
    strikeInContact(m, &d);
    const double H = 4e-6;
    const VecX ref = fixedSteps(m, &d, H, 512);
    const int nd = m.n_dof;
    auto scaledError = [&](const VecX& y) {
      double e = 0.0;
      for (int i = 0; i < 2 * nd; ++i)
        e = std::max(e, std::abs(y[i] - ref[i]) / ((i < nd ? 1e-2 : 1.0) + std::abs(ref[i])));
      return e;
    };
    std::vector<double> errors;
    for (int n : {1, 2, 4, 8, 16}) errors.push_back(scaledError(fixedSteps(m, &d, H, n)));
    const char* name = split ? "split" : "plain";
    for (size_t i = 0; i + 1 < errors.size(); ++i)
      EXPECT_GE(std::log2(errors[i] / errors[i + 1]), 3.5)
          << name << ", steps " << (1 << i) << ": " << errors[i] << " -> " << errors[i + 1];
    ASSERT_GT(errors.back(), 1e-13) << name << ": the ladder reaches rounding";
    const double mean_order = std::log2(errors.front() / errors.back()) / (errors.size() - 1);
    EXPECT_GE(mean_order, 4.5) << name;
    EXPECT_LE(mean_order, 6.5) << name;
    RecordProperty(split ? "errors_split" : "errors_plain",
                   testutil::fmt(errors.front()) + " .. " + testutil::fmt(errors.back()));
  }
}

// The default strike with 20 modes (config/scenes/single_strike.yaml's modes: auto) with the
// split under both schemes against a plain Dormand-Prince reference at tolerance 1e-10: the same
// single impact, the kernel's exit velocity to 1e-5 relative and the peak normal force to 1e-4,
// in fewer steps than plain Dormand-Prince at the same tolerance (whose steps the 20th mode,
// 670 kHz, limits).
Model strike20() {
  Model m = testutil::defaultSceneModel(kED);
  m.teeth[0].n_modes = 20;
  return m;
}
TEST(ModalSplit, StrikeWithTwentyModesAgreesWithTheReferenceUnderBothSchemes) {
  Model m_ref = strike20();
  m_ref.integrator.islands = false;
  m_ref.integrator.modal_split = false;
  m_ref.integrator.tolerance = 1e-10;
  compileModel(&m_ref);
  Data d_ref;
  resetData(m_ref, &d_ref);
  ASSERT_EQ(advanceTo(m_ref, &d_ref, 5e-3), StepStatus::kOk);
  const int k = m_ref.kernels[0].dof_offset;
  const double v_ref = d_ref.u.segment<2>(k).norm();
  for (bool islands : {false, true}) {
    Model m = strike20();
    m.integrator.islands = islands;
    m.integrator.modal_split = true;
    compileModel(&m);
    Model m_plain = m;
    m_plain.integrator.modal_split = false;
    Data d, d_plain;
    resetData(m, &d);
    resetData(m_plain, &d_plain);
    ASSERT_EQ(advanceTo(m, &d, 5e-3), StepStatus::kOk);
    ASSERT_EQ(advanceTo(m_plain, &d_plain, 5e-3), StepStatus::kOk);
    const std::string scheme = islands ? "islands" : "global";
    EXPECT_EQ(d.stats.impacts, d_ref.stats.impacts) << scheme;
    EXPECT_NEAR(d.u.segment<2>(k).norm(), v_ref, 1e-5 * v_ref) << scheme;
    EXPECT_NEAR(d.stats.peak_normal_force_N, d_ref.stats.peak_normal_force_N,
                1e-4 * d_ref.stats.peak_normal_force_N)
        << scheme;
    // Integrator steps: the global ones and those inside islands.
    const long steps = d.steps + d.stats.scheduler.island_steps;
    const long steps_plain = d_plain.steps + d_plain.stats.scheduler.island_steps;
    EXPECT_LT(steps, steps_plain) << scheme;
    RecordProperty("steps_split_" + scheme, std::to_string(steps));
    RecordProperty("steps_plain_" + scheme, std::to_string(steps_plain));
  }
}

}  // namespace
}  // namespace threshing_sim
