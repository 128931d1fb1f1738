// The large-deflection tooth (teeth.*.model: large_deflection): statics against the elastica,
// its kinematics and dynamics against finite differences and the energy they conserve.
#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <string>
#include <vector>

#include "sim_test_util.h"
#include "threshing_sim/core/beam.h"
#include "threshing_sim/core/large_deflection.h"
#include "threshing_sim/core/model.h"
#include "threshing_sim/core/simulator.h"

namespace threshing_sim {
namespace {

// The elastica of a cantilever under a tip force P at right angles to its undeformed axis:
// with s in units of L, theta'' = -alpha cos theta, theta(0) = 0, theta'(1) = 0, alpha = PL^2/EI.
// Shooting on theta'(0) (bisection, RK4 with 4000 steps, ~1e-14). Returns (deflection along P,
// shortening, tip rotation), all over L or in rad.
struct Elastica {
  double deflection = 0, shortening = 0, rotation = 0;
};

// Integrates from theta'(0) = k0; returns theta'(1) and fills the tip state.
double shoot(double alpha, double k0, Elastica* out) {
  constexpr int kSteps = 4000;
  const double h = 1.0 / kSteps;
  // y = (theta, theta', x, y)
  double y[4] = {0.0, k0, 0.0, 0.0};
  auto f = [alpha](const double* s, double* d) {
    d[0] = s[1];
    d[1] = -alpha * std::cos(s[0]);
    d[2] = std::cos(s[0]);
    d[3] = std::sin(s[0]);
  };
  for (int i = 0; i < kSteps; ++i) {
    double k1[4], k2[4], k3[4], k4[4], t[4];
    f(y, k1);
    for (int j = 0; j < 4; ++j) t[j] = y[j] + 0.5 * h * k1[j];
    f(t, k2);
    for (int j = 0; j < 4; ++j) t[j] = y[j] + 0.5 * h * k2[j];
    f(t, k3);
    for (int j = 0; j < 4; ++j) t[j] = y[j] + h * k3[j];
    f(t, k4);
    for (int j = 0; j < 4; ++j) y[j] += h / 6.0 * (k1[j] + 2 * k2[j] + 2 * k3[j] + k4[j]);
  }
  out->deflection = y[3];
  out->shortening = 1.0 - y[2];
  out->rotation = y[0];
  return y[1];
}

Elastica elastica(double alpha) {
  // theta'(1) falls as theta'(0) rises; the root curvature lies in (0, alpha].
  double lo = 0.0, hi = alpha;
  Elastica e;
  for (int it = 0; it < 200 && hi - lo > 1e-14; ++it) {
    const double mid = 0.5 * (lo + hi);
    (shoot(alpha, mid, &e) > 0.0 ? hi : lo) = mid;
  }
  shoot(alpha, 0.5 * (lo + hi), &e);
  return e;
}

ToothModel ldTooth(int shapes) {
  ToothModel t;
  t.beam_model = ToothBeamModel::kLargeDeflection;
  t.n_modes = shapes;
  t.length_m = 0.06;
  t.diameter_m = 0.01;
  t.youngs_modulus_Pa = 3e9;
  t.density_kgpm3 = 1140;
  compileTooth(0.2, &t);
  return t;
}

TEST(LargeDeflection, ElasticaReferenceMatchesPublishedTable) {
  // docs/model.md §9b (Bisshopp & Drucker 1945, 5 digits).
  const double table[5][4] = {{0.5, 0.16214, 0.01592, 0.24453},
                              {1.0, 0.30172, 0.05643, 0.46135},
                              {2.0, 0.49346, 0.16064, 0.78175},
                              {5.0, 0.71379, 0.38763, 1.21537},
                              {10.0, 0.81061, 0.55500, 1.43029}};
  for (const auto& row : table) {
    const Elastica e = elastica(row[0]);
    EXPECT_NEAR(e.deflection, row[1], 6e-6) << "alpha " << row[0];
    EXPECT_NEAR(e.shortening, row[2], 6e-6) << "alpha " << row[0];
    EXPECT_NEAR(e.rotation, row[3], 6e-6) << "alpha " << row[0];
  }
}

// The target of issue 12: tip deflections within 1e-3 L of the elastica for alpha = 1, 2, 5,
// with 4, 6 and 8 shape functions; the table to alpha = 10 is printed (docs/large_deflection.md).
TEST(LargeDeflection, TipLoadMatchesElastica) {
  for (int shapes : {4, 6, 8}) {
    const ToothModel t = ldTooth(shapes);
    const double L = t.length_m;
    const double EI = t.youngs_modulus_Pa * t.second_moment_m4;
    for (double alpha : {0.5, 1.0, 2.0, 5.0, 10.0}) {
      const Elastica e = elastica(alpha);
      const Vec2 tip = ldStaticTipLoad(t, Vec2(0.0, alpha * EI / (L * L)));
      ASSERT_TRUE(tip.allFinite()) << "alpha " << alpha;
      const double err_v = tip.y() / L - e.deflection;
      const double err_h = -tip.x() / L - e.shortening;
      std::printf(
          "LD_TABLE shapes %d alpha %5.2f vertical %.6f (elastica %.6f, error %+.1e L) "
          "horizontal %.6f (elastica %.6f, error %+.1e L)\n",
          shapes, alpha, tip.y() / L, e.deflection, err_v, -tip.x() / L, e.shortening, err_h);
      if (alpha <= 5.0) {
        EXPECT_LT(std::abs(err_v), 1e-3) << "alpha " << alpha;
        EXPECT_LT(std::abs(err_h), 1e-3) << "alpha " << alpha;
      }
    }
  }
}

// dr/dq of the centreline against central differences of r(q) (step 1e-6: truncation
// ~1e-11 L), and the rod's mass matrix
// against its kinetic energy: T = 1/2 qd^T M qd at rest (Omega = 0).
TEST(LargeDeflection, JacobianAndMassMatchTheirDefinitions) {
  const ToothModel t = ldTooth(5);
  VecX q(5), qd(5);
  q << 0.7, -0.3, 0.2, 0.1, -0.05;
  qd << 3.0, -1.0, 2.0, 0.5, 1.5;
  LdConfig cfg;
  ldConfigure(t, q.data(), &cfg);
  for (double s : {0.0, 0.013, 0.03, 0.0451, 0.06}) {
    LdJac J;
    ldPoint(t, cfg, s, nullptr, nullptr, &J);
    for (int i = 0; i < 5; ++i) {
      const double eps = 1e-6;
      VecX qp = q, qm = q;
      qp[i] += eps;
      qm[i] -= eps;
      LdConfig cp, cm;
      ldConfigure(t, qp.data(), &cp);
      ldConfigure(t, qm.data(), &cm);
      const Vec2 fd = (ldPoint(t, cp, s, nullptr, nullptr, nullptr) -
                       ldPoint(t, cm, s, nullptr, nullptr, nullptr)) /
                      (2 * eps);
      EXPECT_LT((fd - J.col(i)).norm(), 1e-8 * t.length_m) << "s " << s << " i " << i;
    }
  }
  LdMat M;
  double T = 0;
  ldDynamics(t, cfg, q.data(), qd.data(), 0.0, 0.0, &M, nullptr, &T, nullptr);
  EXPECT_NEAR(T, 0.5 * qd.dot(M * qd), 1e-14 * T);
  // Positive definite: the smallest eigenvalue of the symmetric M is positive.
  EXPECT_LT((M - M.transpose()).norm(), 1e-14 * M.norm());
  EXPECT_GT(Eigen::SelfAdjointEigenSolver<MatX>(MatX(M)).eigenvalues().minCoeff(), 0.0);
}

// Centrifugal stiffening, exactly: the rod linearised about its straight (radial) shape on a
// turning drum has the modal tooth's frequencies. Soft rubber tooth of docs/model.md §3
// (d 10 mm, E 1.5 MPa, rho 950, L 60 mm, R 200 mm): 15.4 Hz at rest, 34.4 Hz at 800 rpm.
TEST(LargeDeflection, LinearisedRodHasTheRotatingModalFrequencies) {
  for (double omega : {0.0, 83.78}) {
    ToothModel rod = ldTooth(8);
    ToothModel modal;
    for (ToothModel* t : {&rod, &modal}) {
      t->youngs_modulus_Pa = 1.5e6;
      t->density_kgpm3 = 950;
      t->n_modes = 8;
      t->damping_ratio = 0.0;
    }
    compileTooth(0.2, &rod);
    compileTooth(0.2, &modal);
    const int n = 8;
    // Stiffness -df/dq at q = 0 by central differences (f is smooth; step 1e-7 rad).
    MatX K(n, n);
    const VecX zero = VecX::Zero(n);
    for (int j = 0; j < n; ++j) {
      VecX qp = zero, qm = zero;
      qp[j] = 1e-7;
      qm[j] = -1e-7;
      LdConfig cp, cm;
      ldConfigure(rod, qp.data(), &cp);
      ldConfigure(rod, qm.data(), &cm);
      LdVec fp, fm;
      ldDynamics(rod, cp, qp.data(), zero.data(), omega, 0.0, nullptr, &fp, nullptr, nullptr);
      ldDynamics(rod, cm, qm.data(), zero.data(), omega, 0.0, nullptr, &fm, nullptr, nullptr);
      K.col(j) = -(fp - fm) / 2e-7;
    }
    LdConfig c0;
    ldConfigure(rod, zero.data(), &c0);
    LdMat M;
    ldDynamics(rod, c0, zero.data(), zero.data(), omega, 0.0, &M, nullptr, nullptr, nullptr);
    const MatX Ks = 0.5 * (K + K.transpose());
    Eigen::GeneralizedSelfAdjointEigenSolver<MatX> eig(Ks, MatX(M));
    const double f_rod = std::sqrt(eig.eigenvalues()[0]) / (2 * testutil::kPi);
    const double f_modal = toothFrequenciesHz(modal, omega)[0];
    std::printf("LD_FREQUENCY omega %.2f rad/s: rod %.4f Hz, modal %.4f Hz\n", omega, f_rod,
                f_modal);
    EXPECT_NEAR(f_rod, f_modal, 1e-4 * f_modal) << "omega " << omega;
    EXPECT_NEAR(f_rod, omega == 0.0 ? 15.4 : 34.4, 0.05);
  }
}

// The rod's shear-corrected sections (docs/model.md §9b): the filter S scales each mode of the
// rod linearised at rest by the factor of its wave number, S V_j = f_j V_j with K V = M0 V
// omega^2 and beta_j = (omega_j^2 rho A / EI)^{1/4}; with Euler-Bernoulli sections S = I.
TEST(LargeDeflection, SectionRotationFilterScalesTheLinearisedModes) {
  ToothModel rod = ldTooth(8);
  compileTooth(0.2, &rod);
  const int n = rod.n_modes;
  const VecX zero = VecX::Zero(n);
  LdConfig c0;
  ldConfigure(rod, zero.data(), &c0);
  LdMat M;
  ldDynamics(rod, c0, zero.data(), zero.data(), 0.0, 0.0, &M, nullptr, nullptr, nullptr);
  Eigen::GeneralizedSelfAdjointEigenSolver<MatX> eig(rod.ld_K, MatX(M));
  const double EI = rod.youngs_modulus_Pa * rod.second_moment_m4;
  for (int j = 0; j < n; ++j) {
    const VecX v = eig.eigenvectors().col(j);
    const double beta = std::pow(eig.eigenvalues()[j] * rod.mass_per_length_kgpm / EI, 0.25);
    const double f = sectionRotationFactor(rod, beta);
    EXPECT_LT((rod.ld_rotation_filter * v - f * v).norm(), 1e-9 * v.norm()) << "mode " << j;
    EXPECT_LT(f, 1.0);
  }
  rod.section_rotation = ToothSectionRotation::kEulerBernoulli;
  compileTooth(0.2, &rod);
  EXPECT_EQ(rod.ld_rotation_filter, MatX::Identity(n, n));
}

// The island scheme takes rods: a rod touching nothing has no exact free motion (it is
// nonlinear), so it is integrated in an island of its own, by the global integrator on its
// sub-system, and kernels join it as they join a modal tooth's island. The default strike with
// the rod (4 shape functions), under both integrators: the same impacts in the same order, and
// the peak forces, the tip deflection, the kernel's exit velocity and the energy (final
// mechanical energy, drive work) within the global scheme's own error estimate (its change
// with the knob refined: tolerance / 100, or dt / 2), or ten times the event-driven tolerance
// relative to the value. It was refused (a model error) before.
struct SchemeRun {
  Model m;
  Data d;
  std::vector<PairId> impacts;  // impact events' pairs, in time order
  std::vector<double> outputs;  // compared quantities (see schemeOutputNames)
};

const char* const kSchemeOutputNames[] = {
    "peak normal force [N]",       "peak tangential force [N]",
    "max tip deflection [L]",      "exit velocity x [m/s]",
    "exit velocity y [m/s]",       "exit spin [rad/s]",
    "final mechanical energy [J]", "drive work [J]"};

SchemeRun rodStrike(IntegratorType type, bool islands, bool refined) {
  SchemeRun r;
  r.m = testutil::defaultSceneModel(type);
  r.m.integrator.islands = islands;
  r.m.teeth[0].beam_model = ToothBeamModel::kLargeDeflection;
  if (refined) {
    r.m.integrator.tolerance /= 100;
    r.m.integrator.dt_s /= 2;
  }
  compileModel(&r.m);
  resetData(r.m, &r.d);
  EXPECT_NE(advanceTo(r.m, &r.d, r.m.duration_s), StepStatus::kFailed) << "t = " << r.d.t_s;
  for (const ContactEvent& e : r.d.events)
    if (e.is_impact || e.to == ContactState::kImpact) r.impacts.push_back(e.pair);
  const RunStats& st = r.d.stats;
  const int k0 = r.m.kernels[0].dof_offset;
  r.outputs = {st.peak_normal_force_N,
               st.peak_tangential_force_N,
               st.max_tip_deflection_ratio,
               r.d.u[k0],
               r.d.u[k0 + 1],
               r.d.u[k0 + 2],
               mechanicalEnergy(r.m, r.d),
               st.drive_work_J};
  return r;
}

void expectIslandsAgreeOnTheRodStrike(IntegratorType type) {
  const SchemeRun g = rodStrike(type, false, false), a = rodStrike(type, true, false);
  const SchemeRun gf = rodStrike(type, false, true), af = rodStrike(type, true, true);
  EXPECT_GT(a.d.stats.scheduler.islands_built, 0);
  EXPECT_GE(g.d.stats.impacts, 1);
  EXPECT_EQ(a.d.stats.impacts, g.d.stats.impacts);
  EXPECT_TRUE(a.impacts == g.impacts) << a.impacts.size() << " against " << g.impacts.size();
  EXPECT_LE(a.d.stats.max_energy_gain_at_impact_J, 0.0);
  const bool ed = type == IntegratorType::kEventDriven;
  for (size_t q = 0; q < g.outputs.size(); ++q) {
    const double og = g.outputs[q], oa = a.outputs[q];
    const double estimate = std::abs(og - gf.outputs[q]) + std::abs(oa - af.outputs[q]);
    const double tol = ed ? 10.0 * g.m.integrator.tolerance * std::abs(og) : 0.0;
    const double floor = 1e-9 * (std::abs(og) + 1e-3);
    const double bound = std::max({3.0 * estimate, tol, floor});
    std::printf("LD_ISLANDS %s %-28s global %.9g islands %.9g (%+.2e, bound %.2e)\n",
                ed ? "event_driven " : "time_stepping", kSchemeOutputNames[q], og, oa, oa - og,
                bound);
    EXPECT_LE(std::abs(oa - og), bound)
        << kSchemeOutputNames[q] << ": global " << og << ", islands " << oa << ", refined "
        << gf.outputs[q] << " and " << af.outputs[q];
  }
}

TEST(LargeDeflection, IslandSchemeAgreesWithTheGlobalOneEventDriven) {
  expectIslandsAgreeOnTheRodStrike(IntegratorType::kEventDriven);
}
TEST(LargeDeflection, IslandSchemeAgreesWithTheGlobalOneTimeStepping) {
  expectIslandsAgreeOnTheRodStrike(IntegratorType::kTimeStepping);
}

struct StrikeResult {
  double peak_normal_N = 0, peak_tangential_N = 0, max_tip_ratio = 0;
  Vec2 exit_velocity_mps = Vec2::Zero();
};

StrikeResult strike(IntegratorType type, ToothBeamModel beam,
                    ToothSectionRotation rotation = ToothSectionRotation::kEulerBernoulli) {
  Model m = testutil::defaultSceneModel(type);
  m.integrator.islands = false;
  m.teeth[0].beam_model = beam;
  // Euler-Bernoulli sections by default: the rod's own (Kirchhoff) kinematics, of which the
  // modal tooth is the exact small-deflection limit. The shear-corrected filters of the two
  // differ (the rod's linearised modes are Ritz approximations of the cantilever's).
  m.teeth[0].section_rotation = rotation;
  compileModel(&m);
  Data d;
  testutil::runTo(m, &d, m.duration_s);
  StrikeResult r;
  r.peak_normal_N = d.stats.peak_normal_force_N;
  r.peak_tangential_N = d.stats.peak_tangential_force_N;
  r.max_tip_ratio = d.stats.max_tip_deflection_ratio;
  r.exit_velocity_mps = testutil::kernelVelocity(m, d, 0);
  // No impact gains energy.
  EXPECT_LE(d.stats.max_energy_gain_at_impact_J, 0.0);
  return r;
}

// At small deflection (the default strike bends the nylon tooth 0.0013 L) the rod and the
// modal tooth (4 shape functions, 4 modes) agree on the forces and the exit velocity to 1 %.
void expectSmallDeflectionAgreement(IntegratorType type) {
  const StrikeResult modal = strike(type, ToothBeamModel::kModal);
  const StrikeResult rod = strike(type, ToothBeamModel::kLargeDeflection);
  EXPECT_LT(rod.max_tip_ratio, 0.02);
  const double dn = rod.peak_normal_N / modal.peak_normal_N - 1;
  const double dt = rod.peak_tangential_N / modal.peak_tangential_N - 1;
  const double dv =
      (rod.exit_velocity_mps - modal.exit_velocity_mps).norm() / modal.exit_velocity_mps.norm();
  std::printf(
      "LD_AGREEMENT %s: peak normal %.4f vs %.4f N (%+.2e), peak tangential %.4f vs "
      "%.4f N (%+.2e), exit velocity (%.4f, %.4f) vs (%.4f, %.4f) m/s (%.2e), tip "
      "%.2e L\n",
      type == IntegratorType::kEventDriven ? "event_driven" : "time_stepping", rod.peak_normal_N,
      modal.peak_normal_N, dn, rod.peak_tangential_N, modal.peak_tangential_N, dt,
      rod.exit_velocity_mps.x(), rod.exit_velocity_mps.y(), modal.exit_velocity_mps.x(),
      modal.exit_velocity_mps.y(), dv, rod.max_tip_ratio);
  EXPECT_LT(std::abs(dn), 0.01);
  EXPECT_LT(std::abs(dt), 0.01);
  EXPECT_LT(dv, 0.01);
  // With the shear-corrected default on both: still within 1 % (0.35 % and 0.34 % event-driven,
  // 0.47 % and 0.69 % time stepping when measured).
  const StrikeResult modal_s =
      strike(type, ToothBeamModel::kModal, ToothSectionRotation::kShearCorrected);
  const StrikeResult rod_s =
      strike(type, ToothBeamModel::kLargeDeflection, ToothSectionRotation::kShearCorrected);
  std::printf(
      "LD_AGREEMENT_SHEAR_CORRECTED peak normal %.4f vs %.4f N, tangential %.4f vs "
      "%.4f N\n",
      rod_s.peak_normal_N, modal_s.peak_normal_N, rod_s.peak_tangential_N,
      modal_s.peak_tangential_N);
  EXPECT_NEAR(rod_s.peak_normal_N, modal_s.peak_normal_N, 0.01 * modal_s.peak_normal_N);
  EXPECT_NEAR(rod_s.peak_tangential_N, modal_s.peak_tangential_N, 0.01 * modal_s.peak_tangential_N);
  EXPECT_NE(modal_s.peak_tangential_N, modal.peak_tangential_N);  // the factor is in use
}

TEST(LargeDeflection, SmallDeflectionAgreesWithModalEventDriven) {
  expectSmallDeflectionAgreement(IntegratorType::kEventDriven);
}
TEST(LargeDeflection, SmallDeflectionAgreesWithModalTimeStepping) {
  expectSmallDeflectionAgreement(IntegratorType::kTimeStepping);
}

// Energy: the default strike with an elastic contact (e = 1, no friction) and an undamped
// rod: the drive's work closes the balance E(end) - E(0) = W_drive to the integrators'
// accuracy, and no impact gains energy. Event-driven at tolerance 1e-9; time stepping
// (theta = 0.5) at h = 1e-7.
void expectEnergyBalanceCloses(IntegratorType type, double tol_J) {
  Model m = testutil::defaultSceneModel(type);
  m.integrator.islands = false;
  m.integrator.tolerance = 1e-9;
  m.integrator.dt_s = 1e-7;
  m.duration_s = 2e-3;
  m.teeth[0].beam_model = ToothBeamModel::kLargeDeflection;
  m.teeth[0].damping_ratio = 0.0;
  m.contact[static_cast<int>(PairKind::kToothKernel)] = {ContactLaw::kCompliant, 1.0, 0.0};
  compileModel(&m);
  Data d;
  testutil::runTo(m, &d, m.duration_s);
  ASSERT_GE(d.stats.impacts, 1);
  const double balance = mechanicalEnergy(m, d) - d.stats.energy_initial_J - d.stats.drive_work_J;
  std::printf("LD_ENERGY %s: E(end) - E(0) - W_drive = %.3e J (kernel %.3e J, drive %.3e J)\n",
              type == IntegratorType::kEventDriven ? "event_driven" : "time_stepping", balance,
              kernelKineticEnergy(m, d), d.stats.drive_work_J);
  EXPECT_LT(std::abs(balance), tol_J);
  // An elastic episode returns its energy: a gain only at round-off of the 1 J system.
  EXPECT_LE(d.stats.max_energy_gain_at_impact_J, 1e-11);
}

TEST(LargeDeflection, EnergyBalanceClosesEventDriven) {
  expectEnergyBalanceCloses(IntegratorType::kEventDriven, 1e-6);
}
TEST(LargeDeflection, EnergyBalanceClosesTimeStepping) {
  expectEnergyBalanceCloses(IntegratorType::kTimeStepping, 1e-5);
}

}  // namespace
}  // namespace threshing_sim
