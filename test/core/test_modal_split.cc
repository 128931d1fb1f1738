// The Lawson split of the modal teeth in contact (IntegratorParams::modal_split,
// src/core/event_driven/modal_split.cc): with no contact force it is the free propagator (closed
// form), on a contact its Dormand-Prince steps converge at fifth order, and the default strike
// under both schemes agrees with a tight reference.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <unsupported/Eigen/MatrixFunctions>
#include <vector>

#include "../../src/core/event_driven/context.h"
#include "sim_test_util.h"
#include "threshing_sim/core/beam.h"
#include "threshing_sim/core/simulator.h"

namespace threshing_sim {
namespace {

constexpr IntegratorType kED = IntegratorType::kEventDriven;

// The default scene with the tooth plucked (y0 = [q; qdot]) and the kernel at the drum axis,
// far from it; every tooth integrated (no free-tooth path), split or not.
Model pluckedModel(int n_modes, bool split) {
  Model m = testutil::defaultSceneModel(kED);
  m.teeth[0].n_modes = n_modes;
  m.kernels[0].initial_position_m = Vec2(0.0, 0.0);
  m.integrator.islands = false;
  m.integrator.exact_free_teeth = false;
  m.integrator.modal_split = split;
  compileModel(&m);
  return m;
}

// One mode with no contact force: the split step is the free propagator, so the run follows the
// closed form q = exp(-c t / 2) (q0 cos wd t + (qd0 + c q0 / 2) / wd sin wd t) to rounding
// (1e-12 of the amplitude) over 5 ms (its steps are those of the broad-phase margin over the
// tooth's speed); plain Dormand-Prince at the same tolerance is off by its error control's share.
TEST(ModalSplit, ZeroContactForceIsTheFreePropagatorOneModeClosedForm) {
  const Model m = pluckedModel(1, true);
  const Model m_rk = pluckedModel(1, false);
  const ToothModel& tm = m.teeth[0];
  const double omega = m.drum.initial_speed_radps;
  const double w2 = tm.omega0_sq[0] + omega * omega * (tm.K_G(0, 0) - 1.0);
  const double c = tm.damping_coeff[0];
  const double wd = std::sqrt(w2 - 0.25 * c * c);
  const double q0 = 2e-4, qd0 = -3.0;  // [sqrt(kg) m], [sqrt(kg) m/s]
  const double q_scale = std::hypot(q0, qd0 / std::sqrt(w2));
  Data d, d_rk;
  resetData(m, &d);
  resetData(m_rk, &d_rk);
  for (Data* x : {&d, &d_rk}) {
    x->z[0] = q0;
    x->u[0] = qd0;
  }
  double worst = 0.0, worst_rk = 0.0;
  for (int i = 1; i <= 10; ++i) {
    const double t = 5e-4 * i;
    ASSERT_EQ(advanceTo(m, &d, t), StepStatus::kOk);
    ASSERT_EQ(advanceTo(m_rk, &d_rk, t), StepStatus::kOk);
    const double e = std::exp(-0.5 * c * t), co = std::cos(wd * t), si = std::sin(wd * t);
    const double b = (qd0 + 0.5 * c * q0) / wd;
    const double q = e * (q0 * co + b * si);
    const double qd = -0.5 * c * q + e * (-q0 * wd * si + b * wd * co);
    worst = std::max(
        {worst, std::abs(d.z[0] - q) / q_scale, std::abs(d.u[0] - qd) / (q_scale * std::sqrt(w2))});
    worst_rk = std::max(worst_rk, std::abs(d_rk.z[0] - q) / q_scale);
  }
  EXPECT_LE(worst, 1e-12);
  EXPECT_GT(worst_rk, 1e-10);  // plain Dormand-Prince: its tolerance's share, not rounding
  RecordProperty("steps_split", std::to_string(d.steps));
  RecordProperty("steps_dormand_prince", std::to_string(d_rk.steps));
}

// Four coupled modes (K_G couples them at speed), no contact force: the split run against the
// matrix exponential of the free equations (balanced as in test_event_driven) to 1e-11 of the
// amplitude, in fewer steps than plain Dormand-Prince (which resolves the fourth mode).
TEST(ModalSplit, ZeroContactForceIsTheFreePropagatorFourModes) {
  const Model m = pluckedModel(4, true);
  const Model m_rk = pluckedModel(4, false);
  const ToothModel& tm = m.teeth[0];
  const int n = tm.n_modes;
  const double omega = m.drum.initial_speed_radps;
  MatX A = MatX::Zero(2 * n, 2 * n);
  A.topRightCorner(n, n).setIdentity();
  A.bottomLeftCorner(n, n) = -omega * omega * tm.K_G;
  A.bottomLeftCorner(n, n).diagonal() += -(tm.omega0_sq.array() - omega * omega).matrix();
  A.bottomRightCorner(n, n).diagonal() = -tm.damping_coeff;
  VecX s = VecX::Ones(2 * n);
  s.head(n) = tm.omega0_sq.cwiseSqrt();
  VecX y0(2 * n);
  y0 << 1e-4, -2e-5, 5e-6, 0.0, 0.02, 0.5, -0.3, 0.2;  // [sqrt(kg) m], [sqrt(kg) m/s]
  Data d, d_rk;
  resetData(m, &d);
  resetData(m_rk, &d_rk);
  for (Data* x : {&d, &d_rk}) {
    x->z.head(n) = y0.head(n);
    x->u.head(n) = y0.tail(n);
  }
  const double amp_q = y0.head(n).cwiseAbs().maxCoeff();
  for (int i = 1; i <= 10; ++i) {
    const double t = 5e-4 * i;
    ASSERT_EQ(advanceTo(m, &d, t), StepStatus::kOk);
    ASSERT_EQ(advanceTo(m_rk, &d_rk, t), StepStatus::kOk);
    const MatX At = s.asDiagonal() * A * s.cwiseInverse().asDiagonal() * t;
    const VecX y = s.cwiseInverse().asDiagonal() * (At.exp() * (s.asDiagonal() * y0));
    EXPECT_LE((d.z.head(n) - y.head(n)).cwiseAbs().maxCoeff(), 1e-11 * amp_q) << "t " << t;
  }
  EXPECT_LT(d.steps, d_rk.steps);
  RecordProperty("steps_split", std::to_string(d.steps));
  RecordProperty("steps_dormand_prince", std::to_string(d_rk.steps));
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

// Fifth order on a contact: the default strike's compliant contact (the tooth's 4 modes, the
// kernel, the Hertz force) stepped over 4 us by 1 to 16 equal split steps against 512 of them;
// the largest error of the tooth's and the kernel's states (scaled as the error control scales
// them) falls at a mean order within [4.5, 6.5] over the ladder (5.6 measured; single halvings
// 4.2 to 7.1 before the asymptote), each halving by at least 2^3.5. The same with plain
// Dormand-Prince.
TEST(ModalSplit, FifthOrderOnTheStrikeContact) {
  for (bool split : {true, false}) {
    Model m = testutil::defaultSceneModel(kED);
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

// The default strike with the split under both schemes against a plain Dormand-Prince
// reference at tolerance 1e-10: the same single impact, the kernel's exit velocity to 1e-5
// relative and the peak normal force to 1e-4. (Its steps, recorded, are those of plain
// Dormand-Prince: the kernel's contact, not the tooth's modes, sets them here.)
TEST(ModalSplit, DefaultStrikeAgreesWithTheReferenceUnderBothSchemes) {
  Model m_ref = testutil::defaultSceneModel(kED);
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
    Model m = testutil::defaultSceneModel(kED);
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
    RecordProperty("steps_split_" + scheme, std::to_string(steps));
    RecordProperty("steps_plain_" + scheme, std::to_string(steps_plain));
  }
}

}  // namespace
}  // namespace threshing_sim
