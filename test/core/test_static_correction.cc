// Unit tests of the static correction of the truncated modes (docs/model.md §9b): the exact
// static flexibility of the rotating cantilever, the modal and residual parts, the series Hertz
// law that carries the residual, and the automatic mode count.
#include <gtest/gtest.h>

#include <Eigen/LU>
#include <cmath>
#include <random>
#include <vector>

#include "../../src/core/internal.h"
#include "sim_test_util.h"
#include "threshing_sim/core/beam.h"
#include "threshing_sim/core/model.h"
#include "threshing_sim/core/simulator.h"
#include "threshing_sim/scene/scene_loader.h"

namespace threshing_sim {
namespace {

constexpr double kRpm800_radps = 83.776;

// The polyurethane tooth of config/bench/knead_polyurethane.yaml on a 0.14 m drum.
ToothModel polyurethaneTooth(int n_modes) {
  ToothModel t;
  t.youngs_modulus_Pa = 5e6;
  t.density_kgpm3 = 1200;
  t.poisson_ratio = 0.49;
  t.n_modes = n_modes;
  compileTooth(0.14, &t);
  return t;
}

// At rest the flexibility under a load at the same point has the closed form of docs/model.md §9b:
// w = x^3 / (3 EI), w under a couple = w' under a force = x^2 / (2 EI), w' under a couple x / EI.
TEST(StaticCorrection, ExactFlexibilityMatchesClosedFormAtRest) {
  const ToothModel t = polyurethaneTooth(6);
  const double EI = t.youngs_modulus_Pa * t.second_moment_m4;
  const int n = kResidualPoints;
  const StationFlexibility f = staticFlexibility(t, 0.14, 0.0, n);
  for (int j = 1; j < n; ++j) {
    const double x = t.length_m * j / (n - 1);
    EXPECT_NEAR(f.ww[j], x * x * x / (3 * EI), 1e-7 * x * x * x / (3 * EI)) << j;
    EXPECT_NEAR(f.wt[j], x * x / (2 * EI), 1e-7 * x * x / (2 * EI)) << j;
    EXPECT_NEAR(f.tt[j], x / EI, 1e-7 * x / EI) << j;
  }
  EXPECT_EQ(f.ww[0], 0.0);
}

// The dense reference the banded solver replaced: the full Hermite stiffness of the rotating
// cantilever (root dofs removed) by 4-point Gauss quadrature, factored by partial-pivoting LU,
// one solve per load; in long double (like the banded solver: in double the condensation of
// stiff elements leaves ~1e-9 of rounding).
using MatL = Eigen::Matrix<long double, Eigen::Dynamic, Eigen::Dynamic>;
using VecL = Eigen::Matrix<long double, Eigen::Dynamic, 1>;
using Vec4L = Eigen::Matrix<long double, 4, 1>;
StationFlexibility denseStaticFlexibility(const ToothModel& t, double R, double omega, int n_points,
                                          int per) {
  const int n_el = per * (n_points - 1);
  const long double L = t.length_m, h = L / n_el;
  const long double EI = static_cast<long double>(t.youngs_modulus_Pa) * t.second_moment_m4;
  const long double rhoA = t.mass_per_length_kgpm, w2 = static_cast<long double>(omega) * omega;
  // Gauss-Legendre 4-point nodes and weights on [0, 1] in long double.
  const long double r = std::sqrt(6.0L / 5), q = std::sqrt(30.0L);
  const long double u[2] = {std::sqrt((3 - 2 * r) / 7), std::sqrt((3 + 2 * r) / 7)};
  const long double node[4] = {(1 - u[1]) / 2, (1 - u[0]) / 2, (1 + u[0]) / 2, (1 + u[1]) / 2};
  const long double weight[4] = {(18 - q) / 72, (18 + q) / 72, (18 + q) / 72, (18 - q) / 72};
  const int n_full = 2 * (n_el + 1);
  MatL K = MatL::Zero(n_full, n_full);
  for (int e = 0; e < n_el; ++e) {
    for (int g = 0; g < 4; ++g) {
      const long double s = node[g], s2 = s * s, s3 = s2 * s;
      Vec4L N, dN, ddN;
      N << 1 - 3 * s2 + 2 * s3, h * (s - 2 * s2 + s3), 3 * s2 - 2 * s3, h * (s3 - s2);
      dN << (-6 * s + 6 * s2) / h, 1 - 4 * s + 3 * s2, (6 * s - 6 * s2) / h, 3 * s2 - 2 * s;
      ddN << (-6 + 12 * s) / (h * h), (-4 + 6 * s) / h, (6 - 12 * s) / (h * h), (6 * s - 2) / h;
      const long double x = (e + s) * h;
      const long double axial_N = rhoA * w2 * (R * (L - x) + (L * L - x * x) / 2);
      K.block<4, 4>(2 * e, 2 * e) += weight[g] * h *
                                     (EI * ddN * ddN.transpose() + axial_N * dN * dN.transpose() -
                                      rhoA * w2 * N * N.transpose());
    }
  }
  const Eigen::PartialPivLU<MatL> lu(K.bottomRightCorner(n_full - 2, n_full - 2));
  StationFlexibility f;
  f.ww.setZero(n_points);
  f.wt.setZero(n_points);
  f.tt.setZero(n_points);
  for (int s = 1; s < n_points; ++s) {
    const int dof = 2 * (s * per - 1);
    VecL load = VecL::Zero(2 * n_el);
    load[dof] = 1;
    const VecL under_force = lu.solve(load);
    load.setZero();
    load[dof + 1] = 1;
    const VecL under_couple = lu.solve(load);
    f.ww[s] = static_cast<double>(under_force[dof]);
    f.wt[s] = static_cast<double>((under_force[dof + 1] + under_couple[dof]) / 2);
    f.tt[s] = static_cast<double>(under_couple[dof + 1]);
  }
  return f;
}

// The banded L D L^T with selected inversion gives the dense solution (soft and stiff teeth, at
// rest and fast) to 1e-9, the dense LU's rounding (even in long double: ~6e-12 off the closed
// form at rest; the double one the library used was ~1e-10 off). At rest the cubic Hermite
// element reproduces w = x^2 (3 xi - x) / (6 EI) under nodal loads at any element count: the
// banded solve meets it to 1e-13 with one element per interval, to 3e-10 with the default 256
// (its long double rounding, ~1e-19 cond(K) ~ 1e-19 (L / h)^4).
TEST(StaticCorrection, BandedSolveMatchesDenseReferenceAndClosedForm) {
  ToothModel nylon;
  nylon.n_modes = 4;
  compileTooth(0.20, &nylon);
  for (const ToothModel& t : {polyurethaneTooth(6), nylon}) {
    for (double omega : {0.0, kRpm800_radps, 400.0}) {
      for (int per : {1, 8}) {
        const int n = kResidualPoints;
        const StationFlexibility banded = staticFlexibility(t, 0.14, omega, n, per * (n - 1));
        const StationFlexibility dense = denseStaticFlexibility(t, 0.14, omega, n, per);
        for (int j = 1; j < n; ++j) {
          EXPECT_NEAR(banded.ww[j], dense.ww[j], 1e-9 * dense.ww[j]) << omega << " " << j;
          EXPECT_NEAR(banded.wt[j], dense.wt[j], 1e-9 * dense.wt[j]) << omega << " " << j;
          EXPECT_NEAR(banded.tt[j], dense.tt[j], 1e-9 * dense.tt[j]) << omega << " " << j;
        }
      }
    }
    const double EI = t.youngs_modulus_Pa * t.second_moment_m4;
    for (int per : {1, 8}) {
      const StationFlexibility coarse =
          staticFlexibility(t, 0.14, 0.0, kResidualPoints, per * (kResidualPoints - 1));
      for (int j = 1; j < kResidualPoints; ++j) {
        const double x = t.length_m * j / (kResidualPoints - 1);
        EXPECT_NEAR(coarse.ww[j], x * x * x / (3 * EI),
                    (per == 1 ? 1e-13 : 3e-10) * x * x * x / (3 * EI))
            << j;
        EXPECT_NEAR(coarse.wt[j], x * x / (2 * EI), (per == 1 ? 1e-13 : 3e-10) * x * x / (2 * EI))
            << j;
        EXPECT_NEAR(coarse.tt[j], x / EI, (per == 1 ? 1e-13 : 3e-10) * x / EI) << j;
      }
    }
  }
}

// The residual flexibility tabulated over the drum speed (ToothModel::residual_panels) and
// interpolated in Omega^2 matches the direct computation at 61 speeds across
// [0, speed_bound] (node or not), at every point, to 2e-8 of the static flexibility's largest
// entry (the table's tolerance is 1e-8; its estimate is recorded); at the compiled speed it is
// the compiled table exactly, and a target beyond the bound is clamped to it.
TEST(StaticCorrection, SpeedTableMatchesDirectResidual) {
  struct Case {
    ToothModel tooth;
    double R;
  };
  ToothModel nylon;
  nylon.n_modes = 4;
  compileTooth(0.20, &nylon);
  for (Case c :
       {Case{nylon, 0.20}, Case{polyurethaneTooth(6), 0.14}, Case{polyurethaneTooth(16), 0.14}}) {
    ToothModel& t = c.tooth;
    const double bound = 400.0;
    compileResidual(c.R, kRpm800_radps, bound, &t);
    ASSERT_FALSE(t.residual_panels.empty());
    EXPECT_LE(t.residual_table_error, 1e-8);
    EXPECT_EQ(t.residual_panels.back().u_hi_radps2, bound * bound);
    const StationFlexibility rest = staticFlexibility(t, c.R, 0.0, kResidualPoints);
    const double scale[3] = {rest.ww.maxCoeff(), rest.wt.maxCoeff(), rest.tt.maxCoeff()};
    for (int k = 0; k <= 60; ++k) {
      const double omega = bound * k / 60.0;
      const StationFlexibility direct = residualFlexibility(t, c.R, omega);
      for (int s = 0; s < kResidualPoints; ++s) {
        const double x = t.length_m * s / (kResidualPoints - 1);
        double ww, wt, tt;
        residualAtSpeed(t, omega, x, &ww, &wt, &tt);
        EXPECT_NEAR(ww, direct.ww[s], 2e-8 * scale[0]) << omega << " " << s;
        EXPECT_NEAR(wt, direct.wt[s], 2e-8 * scale[1]) << omega << " " << s;
        EXPECT_NEAR(tt, direct.tt[s], 2e-8 * scale[2]) << omega << " " << s;
      }
    }
    double ww, wt, tt;
    residualAtSpeed(t, kRpm800_radps, 0.7 * t.length_m, &ww, &wt, &tt);
    EXPECT_EQ(ww, residualAt(t.residual_ww, t.length_m, 0.7 * t.length_m));
    EXPECT_EQ(tt, residualAt(t.residual_tt, t.length_m, 0.7 * t.length_m));
  }
  Model m;
  m.drum.max_speed_radps = 150.0;
  compileModel(&m);
  EXPECT_EQ(m.drum.speed_bound_radps, 150.0);
  Data d;
  resetData(m, &d);
  setDrumTarget(m, &d, 1e4);
  EXPECT_EQ(d.omega_target_radps, 150.0);
  setDrumTarget(m, &d, -1e4);
  EXPECT_EQ(d.omega_target_radps, -150.0);
}

// Alike teeth at other mount angles share the first one's compiled data (compiled once) but for
// their root and axes, and those are what compileTooth and compileResidual give each of them;
// another material compiles its own.
TEST(StaticCorrection, AlikeTeethShareTheResidualTables) {
  Model m;
  m.teeth.resize(3);
  m.teeth[1].mount_angle_rad = 2.0;
  m.teeth[2].youngs_modulus_Pa = 2e9;
  compileModel(&m);
  ToothModel direct;
  direct.mount_angle_rad = 2.0;
  compileTooth(m.drum.radius_m, &direct);
  compileResidual(m.drum.radius_m, m.drum.initial_speed_radps, m.drum.speed_bound_radps, &direct);
  EXPECT_EQ(m.teeth[1].e1_D, direct.e1_D);
  EXPECT_EQ(m.teeth[1].e2_D, direct.e2_D);
  EXPECT_EQ(m.teeth[1].p_DR_D, direct.p_DR_D);
  EXPECT_EQ(m.teeth[1].K_G, direct.K_G);
  EXPECT_EQ(m.teeth[1].H_s[3], direct.H_s[3]);
  EXPECT_EQ(m.teeth[1].p_inertia, direct.p_inertia);
  EXPECT_EQ(m.teeth[1].residual_ww, direct.residual_ww);
  EXPECT_EQ(m.teeth[1].residual_nodes_tt, direct.residual_nodes_tt);
  EXPECT_EQ(m.teeth[1].residual_nodes_ww, m.teeth[0].residual_nodes_ww);
  EXPECT_NE(m.teeth[2].residual_ww[kResidualPoints - 1],
            m.teeth[0].residual_ww[kResidualPoints - 1]);
}

// Rotating at 800 rpm: the centrifugal tension stiffens the soft tooth (tip flexibility about
// half the static one), and the finite-element solution is converged: doubling the elements
// moves it by < 3e-6 (the slope under a couple, most; against a residual of >= 1 % of it).
TEST(StaticCorrection, ExactFlexibilityIsConvergedWhenRotating) {
  const ToothModel t = polyurethaneTooth(6);
  const double EI = t.youngs_modulus_Pa * t.second_moment_m4;
  const double L = t.length_m;
  const int n = kResidualPoints;
  const StationFlexibility coarse = staticFlexibility(t, 0.14, kRpm800_radps, n, 256);
  const StationFlexibility fine = staticFlexibility(t, 0.14, kRpm800_radps, n, 512);
  for (int j = 1; j < n; ++j) {
    EXPECT_NEAR(coarse.ww[j], fine.ww[j], 3e-6 * fine.ww[j]) << j;
    EXPECT_NEAR(coarse.wt[j], fine.wt[j], 3e-6 * fine.wt[j]) << j;
    EXPECT_NEAR(coarse.tt[j], fine.tt[j], 3e-6 * fine.tt[j]) << j;
  }
  EXPECT_LT(fine.ww[n - 1], 0.6 * L * L * L / (3 * EI));
  EXPECT_GT(fine.ww[n - 1], 0.3 * L * L * L / (3 * EI));
}

// Modal + residual = exact at any mode count; the residual shrinks as modes are added (the
// slope term slowest), and 64 modes alone approach the exact flexibility (a converged
// discretisation by a second, independent route).
TEST(StaticCorrection, ResidualCompletesTheModesAndShrinks) {
  for (double omega : {0.0, kRpm800_radps}) {
    const ToothModel t64 = polyurethaneTooth(64);
    const StationFlexibility exact = staticFlexibility(t64, 0.14, omega, kResidualPoints);
    const StationFlexibility modal64 = modalFlexibility(t64, omega, kResidualPoints);
    const int tip = kResidualPoints - 1;
    EXPECT_NEAR(modal64.ww[tip], exact.ww[tip], 1e-5 * exact.ww[tip]);
    EXPECT_NEAR(modal64.wt[tip], exact.wt[tip], 1e-3 * exact.wt[tip]);
    EXPECT_NEAR(modal64.tt[tip], exact.tt[tip], 2e-2 * exact.tt[tip]);
    double previous_tt = INFINITY;
    for (int n : {2, 4, 8, 16, 32}) {
      const ToothModel t = polyurethaneTooth(n);
      const StationFlexibility modal = modalFlexibility(t, omega, kResidualPoints);
      const StationFlexibility r = residualFlexibility(t, 0.14, omega);
      for (int j = 1; j < kResidualPoints; ++j) {
        EXPECT_GE(r.ww[j], 0.0);
        EXPECT_GE(r.tt[j], 0.0);
        EXPECT_LE(r.wt[j] * r.wt[j], r.ww[j] * r.tt[j] * (1 + 1e-12));
        // Where it is not clamped, the sum is the exact flexibility.
        if (r.ww[j] > 0) {
          EXPECT_NEAR(modal.ww[j] + r.ww[j], exact.ww[j], 1e-12 * exact.ww[j]);
        }
        if (r.tt[j] > 0) {
          EXPECT_NEAR(modal.tt[j] + r.tt[j], exact.tt[j], 1e-12 * exact.tt[j]);
        }
      }
      EXPECT_LT(r.tt[tip], previous_tt) << n;
      previous_tt = r.tt[tip];
    }
    // Slope residual falls like 1/n: still ~5 % of the slope flexibility at 16 modes.
    const ToothModel t16 = polyurethaneTooth(16);
    EXPECT_GT(residualFlexibility(t16, 0.14, omega).tt[tip], 0.01 * exact.tt[tip]);
  }
}

// The compiled tooth carries the residual at the drum's speed; off, or for a rigid tooth, it
// is zero.
TEST(StaticCorrection, CompileModelFillsTheResidualTables) {
  Model m;
  m.drum.radius_m = 0.14;
  m.teeth.resize(3);
  for (ToothModel& t : m.teeth) {
    t.youngs_modulus_Pa = 5e6;
    t.density_kgpm3 = 1200;
    t.n_modes = 6;
  }
  m.teeth[1].static_correction = false;
  m.teeth[2].n_modes = 0;
  compileModel(&m);
  const int tip = kResidualPoints - 1;
  const StationFlexibility r =
      residualFlexibility(m.teeth[0], m.drum.radius_m, m.drum.initial_speed_radps);
  // The scene's speed is read from the table: within its tolerance of the static flexibility.
  const StationFlexibility rest =
      staticFlexibility(m.teeth[0], m.drum.radius_m, 0.0, kResidualPoints);
  for (int s = 0; s < kResidualPoints; ++s) {
    EXPECT_NEAR(m.teeth[0].residual_ww[s], r.ww[s], 2e-8 * rest.ww.maxCoeff()) << s;
    EXPECT_NEAR(m.teeth[0].residual_wt[s], r.wt[s], 2e-8 * rest.wt.maxCoeff()) << s;
    EXPECT_NEAR(m.teeth[0].residual_tt[s], r.tt[s], 2e-8 * rest.tt.maxCoeff()) << s;
  }
  EXPECT_GT(m.teeth[0].residual_tt[tip], 0.0);
  EXPECT_EQ(m.teeth[0].residual_omega_radps, m.drum.initial_speed_radps);
  EXPECT_EQ(m.teeth[1].residual_tt.cwiseAbs().maxCoeff(), 0.0);
  EXPECT_EQ(m.teeth[2].residual_tt.cwiseAbs().maxCoeff(), 0.0);
}

// The Hertz law with a spring r in series: without damping F = K (delta - r F)^{3/2} exactly;
// r = 0 is the plain Hunt-Crossley law; the force is softer with the spring; its rate is the
// time derivative along a trajectory.
TEST(StaticCorrection, SeriesHertzLawAndItsRate) {
  ContactParams params;
  params.hc_damping_factor = 0.0;
  internal::ContactGeom g;
  g.params = &params;
  const double K = 2e5, delta = 1e-3, r = 2e-5;
  g.gap_m = -delta;
  g.vn = 0.0;
  g.residual_mpN = r;
  const double F = internal::compliantNormalForce(g, K, 1.0, 1e-2);
  EXPECT_NEAR(F, K * std::pow(delta - r * F, 1.5), 1e-12 * F);
  EXPECT_LT(F, K * std::pow(delta, 1.5));
  g.residual_mpN = 0.0;
  EXPECT_EQ(internal::compliantNormalForce(g, K, 1.0, 1e-2), K * delta * std::sqrt(delta));

  // Rate: delta(t) = delta0 + v t + a t^2 / 2 with damping, central difference in t.
  params.hc_damping_factor = 0.3;
  g.residual_mpN = r;
  const double v = 2.0, a = -3e4, dt = 1e-9;
  auto at = [&](double t) {
    internal::ContactGeom h = g;
    h.gap_m = -(delta + v * t + 0.5 * a * t * t);
    h.vn = -(v + a * t);
    return h;
  };
  const double numeric = (internal::compliantNormalForce(at(dt), K, 1.5, 1e-2) -
                          internal::compliantNormalForce(at(-dt), K, 1.5, 1e-2)) /
                         (2 * dt);
  const double analytic = internal::compliantNormalForceRate(at(0), K, 1.5, 1e-2, -a);
  EXPECT_NEAR(analytic, numeric, 1e-5 * std::abs(numeric));

  // With the residual itself changing, r(t) = r + r' t (the contact point sliding).
  const double r_rate = 0.4 * r / 1e-4;  // 40 % of r over a contact time of 0.1 ms [m/(N s)]
  auto at_r = [&](double t) {
    internal::ContactGeom h = at(t);
    h.residual_mpN = r + r_rate * t;
    return h;
  };
  const double numeric_r = (internal::compliantNormalForce(at_r(dt), K, 1.5, 1e-2) -
                            internal::compliantNormalForce(at_r(-dt), K, 1.5, 1e-2)) /
                           (2 * dt);
  const double analytic_r = internal::compliantNormalForceRate(at_r(0), K, 1.5, 1e-2, -a, r_rate);
  EXPECT_NEAR(analytic_r, numeric_r, 1e-5 * std::abs(numeric_r));
  EXPECT_GT(std::abs(analytic_r - analytic), 1e-3 * std::abs(analytic));  // r' matters
}

// The residual table's C^1 interpolant (residualSmoothAt): through the table's values, its
// derivative continuous across the points and equal to the interpolant's slope, monotone and
// of the table's sign, exact on straight lines.
TEST(StaticCorrection, ResidualInterpolantIsSmooth) {
  const ToothModel t = polyurethaneTooth(4);
  const StationFlexibility r = residualFlexibility(t, 0.14, kRpm800_radps);
  const double L = t.length_m, h = L / (kResidualPoints - 1);
  double d_dx = 0.0, d_left = 0.0, d_right = 0.0;
  for (int j = 0; j < kResidualPoints; ++j) {
    const double x = j * h;
    EXPECT_NEAR(internal::residualSmoothAt(r.ww, L, x, &d_dx), r.ww[j], 1e-14 * r.ww.maxCoeff());
    if (j == 0 || j + 1 == kResidualPoints) continue;
    const double eps = 1e-9 * h;
    internal::residualSmoothAt(r.ww, L, x - eps, &d_left);
    internal::residualSmoothAt(r.ww, L, x + eps, &d_right);
    const double scale = r.ww.maxCoeff() / L;
    EXPECT_NEAR(d_left, d_right, 1e-6 * scale) << "slope jumps at point " << j;
  }
  // Between the points: the derivative is that of the values; no undershoot below zero.
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> uni(0.0, L);
  for (int trial = 0; trial < 200; ++trial) {
    const double x = uni(rng), eps = 1e-7 * L;
    const double v = internal::residualSmoothAt(r.ww, L, x, &d_dx);
    const double fd = (internal::residualSmoothAt(r.ww, L, x + eps, &d_left) -
                       internal::residualSmoothAt(r.ww, L, x - eps, &d_right)) /
                      (2 * eps);
    EXPECT_NEAR(d_dx, fd, 1e-5 * r.ww.maxCoeff() / L) << x;
    EXPECT_GE(v, 0.0) << x;
  }
  // A straight line stays one.
  VecX line(kResidualPoints);
  for (int j = 0; j < kResidualPoints; ++j) line[j] = 2.0 + 3.0 * j * h;
  EXPECT_NEAR(internal::residualSmoothAt(line, L, 0.37 * L, &d_dx), 2.0 + 3.0 * 0.37 * L, 1e-13);
  EXPECT_NEAR(d_dx, 3.0, 1e-12);
}

// The residual along n and its gradient (ContactGeom::residual_mpN, the sides' w_r and
// residual_dtheta_mpNprad) against central differences of the narrow phase's residual along a
// motion of the tooth's modes, the kernel and the drum: R' = w_r . u + Omega dR/dtheta. The
// kernel slides along the tooth (x* moves) and turns the normal; random states along the side.
TEST(StaticCorrection, ResidualGradientMatchesCentralDifferences) {
  Model m;
  m.drum.radius_m = 0.20;
  m.drum.initial_speed_radps = 83.78;
  m.teeth = {testutil::nylonTooth(4)};
  m.kernels = {testutil::makeKernel(5.0e-3, 1.3e-3, Vec2(0.235, 0.012))};
  compileModel(&m);
  const ToothModel& tm = m.teeth[0];
  const PairId pair{PairKind::kToothKernel, 0, 0};
  const int o = m.kernels[0].dof_offset;
  auto residualAt = [&](const VecX& z, const VecX& u, double theta, internal::ContactGeom* g) {
    Workspace ws;
    internal::updateStations(m, z, theta, &ws);
    internal::Drive dr;
    dr.theta_rad = theta;
    dr.omega_radps = m.drum.initial_speed_radps;
    internal::evaluateContact(m, z, u, dr, pair, &ws, g);
    return g->residual_mpN;
  };
  std::mt19937 rng(23);
  std::uniform_real_distribution<double> uni(-1.0, 1.0);
  for (int trial = 0; trial < 20; ++trial) {
    VecX z = VecX::Zero(m.n_dof), u = VecX::Zero(m.n_dof);
    const double theta = 0.03 + 0.2 * uni(rng), x_c = 0.03 + 0.022 * uni(rng);
    for (int i = 0; i < 4; ++i) {
      z[tm.dof_offset + i] = 5e-5 * uni(rng) / (i + 1);
      u[tm.dof_offset + i] = 0.1 * uni(rng) / (i + 1);
    }
    const Vec2 c_D(0.2 + x_c, 0.005 + 1.3e-3 + 1e-4 * uni(rng));
    z.segment<2>(o) = Vec2(std::cos(theta) * c_D.x() - std::sin(theta) * c_D.y(),
                           std::sin(theta) * c_D.x() + std::cos(theta) * c_D.y());
    z[o + 2] = theta + 0.5 * uni(rng);
    u.segment<2>(o) = Vec2(20.0 * uni(rng), 20.0 * uni(rng));
    u[o + 2] = 3000.0 * uni(rng);
    internal::ContactGeom g;
    const double R = residualAt(z, u, theta, &g);
    ASSERT_GT(R, 0.0);
    double analytic = m.drum.initial_speed_radps * g.residual_dtheta_mpNprad;
    for (const internal::BodyJac& s : g.side)
      analytic += s.w_r.dot(u.segment(internal::bodyDofOffset(m, s.body), s.w_r.size()));
    const double eps_s = 1e-8;
    auto along = [&](double dt) {
      internal::ContactGeom h;
      return residualAt(z + dt * u, u, theta + dt * m.drum.initial_speed_radps, &h);
    };
    const double fd = (along(eps_s) - along(-eps_s)) / (2 * eps_s);
    // Relative to the rate of a residual that changes by itself over 1 ms.
    EXPECT_NEAR(analytic, fd, 1e-4 * std::abs(fd) + 1e-6 * R / 1e-3)
        << "trial " << trial << ", x* " << g.tooth_x_m;
  }
}

// modes: auto picks more modes for a softer tooth (slower modes against the contact), never
// fewer than 2 or more than kMaxModes, and records the contact time it used.
TEST(StaticCorrection, AutomaticModeCount) {
  auto chosen = [](double E_Pa, double tolerance) {
    Model m;
    m.drum.radius_m = 0.14;
    m.integrator.tolerance = tolerance;
    m.teeth.resize(1);
    m.teeth[0].youngs_modulus_Pa = E_Pa;
    m.teeth[0].n_modes = kAutoModes;
    m.kernels.resize(1);
    compileModel(&m);
    EXPECT_TRUE(m.teeth[0].modes_auto);
    EXPECT_GT(m.teeth[0].contact_time_s, 0.0);
    return m.teeth[0].n_modes;
  };
  const int steel = chosen(2.06e11, 1e-6), nylon = chosen(3e9, 1e-6), pu = chosen(5e6, 1e-6);
  EXPECT_GE(steel, 2);
  EXPECT_LT(steel, nylon);
  EXPECT_LT(nylon, pu);
  EXPECT_LE(pu, kMaxModes);
  // A coarse tolerance asks for fewer.
  EXPECT_LT(chosen(3e9, 1e-2), nylon);
  // Without kernels: 4.
  Model m;
  m.teeth.resize(1);
  m.teeth[0].n_modes = kAutoModes;
  compileModel(&m);
  EXPECT_EQ(m.teeth[0].n_modes, 4);
}

// The residual's cut-off (docs/model.md §9b, "When the truncated modes are not fast"): the
// rubber tooth of hard case 07 at 4 modes leaves out its truncated modes slower than the
// contact, pi / t_c (at rest), and its residual is the static flexibility minus those m modes;
// the default nylon tooth at 4 modes, automatic counts and a tooth without correction are not
// cut.
TEST(StaticCorrection, ResidualLeavesOutTruncatedModesSlowerThanTheContact) {
  Model nylon = testutil::defaultSceneModel();
  compileModel(&nylon);
  EXPECT_EQ(nylon.teeth[0].residual_modes, 4);
  Model rubber = testutil::defaultSceneModel();
  rubber.drum.initial_speed_radps = 157.08;
  ToothModel& r = rubber.teeth[0];
  r.diameter_m = 0.006;
  r.youngs_modulus_Pa = 1.5e6;
  r.density_kgpm3 = 950.0;
  r.poisson_ratio = 0.49;
  Model auto_count = rubber, off = rubber;
  compileModel(&rubber);
  const ToothModel& t = rubber.teeth[0];
  const int m = t.residual_modes;
  ASSERT_GT(m, t.n_modes);
  ASSERT_GT(t.residual_contact_time_s, 0.0);
  // Modes n + 1 .. m below pi / t_c at rest, mode m + 1 above.
  ToothModel wide = t;
  wide.n_modes = m + 1;
  compileTooth(rubber.drum.radius_m, &wide);
  const double omega_c = kPi / t.residual_contact_time_s;
  for (int j = t.n_modes; j < m; ++j) EXPECT_LT(std::sqrt(wide.omega0_sq[j]), omega_c) << j;
  EXPECT_GE(std::sqrt(wide.omega0_sq[m]), omega_c);
  // The residual is the static flexibility less the m modes' part, where not clamped.
  wide.n_modes = m;
  compileTooth(rubber.drum.radius_m, &wide);
  const double omega = rubber.drum.initial_speed_radps;
  const StationFlexibility exact =
      staticFlexibility(t, rubber.drum.radius_m, omega, kResidualPoints);
  const StationFlexibility modal = modalFlexibility(wide, omega, kResidualPoints);
  const int tip = kResidualPoints - 1;
  EXPECT_NEAR(t.residual_ww[tip], exact.ww[tip] - modal.ww[tip], 1e-9 * exact.ww[tip]);
  // Smaller than the residual of all truncated modes.
  ToothModel uncut = t;
  uncut.residual_modes = 0;
  EXPECT_LT(t.residual_ww[tip],
            0.5 * residualFlexibility(uncut, rubber.drum.radius_m, omega).ww[tip]);
  auto_count.teeth[0].n_modes = kAutoModes;
  compileModel(&auto_count);
  EXPECT_EQ(auto_count.teeth[0].residual_modes, auto_count.teeth[0].n_modes);
  off.teeth[0].static_correction = false;
  compileModel(&off);
  EXPECT_EQ(off.teeth[0].residual_modes, off.teeth[0].n_modes);
}

// The quasi-static diagnostic (ToothModel::quasi_static_from_mode): the modes from that index on
// run s times faster with their modal mass over s^2, and keep their static flexibility, so the
// tooth's static response is unchanged at any speedup.
TEST(StaticCorrection, QuasiStaticModesKeepTheirStaticFlexibility) {
  const ToothModel plain = polyurethaneTooth(12);
  ToothModel fast;
  fast.youngs_modulus_Pa = plain.youngs_modulus_Pa;
  fast.density_kgpm3 = plain.density_kgpm3;
  fast.poisson_ratio = plain.poisson_ratio;
  fast.n_modes = 12;
  fast.quasi_static_from_mode = 6;
  fast.quasi_static_speedup = 10.0;
  compileTooth(0.14, &fast);
  for (int i = 0; i < 12; ++i) {
    const double s = i < 6 ? 1.0 : 10.0;
    EXPECT_NEAR(fast.omega0_sq[i], s * s * plain.omega0_sq[i], 1e-12 * fast.omega0_sq[i]) << i;
  }
  for (double omega : {0.0, kRpm800_radps}) {
    const StationFlexibility a = modalFlexibility(plain, omega, kResidualPoints);
    const StationFlexibility b = modalFlexibility(fast, omega, kResidualPoints);
    const int tip = kResidualPoints - 1;
    // At speed the modes' centrifugal softening -Omega^2 goes with their mass (1e-5 of omega_7^2).
    const double tol = omega == 0.0 ? 1e-9 : 1e-5;
    for (int j = 1; j <= tip; ++j) {
      EXPECT_NEAR(b.ww[j], a.ww[j], tol * a.ww[tip]) << omega << " " << j;
      EXPECT_NEAR(b.wt[j], a.wt[j], tol * std::abs(a.wt[tip])) << omega << " " << j;
      EXPECT_NEAR(b.tt[j], a.tt[j], tol * a.tt[tip]) << omega << " " << j;
    }
  }
  fast.quasi_static_speedup = 0.5;
  EXPECT_THROW(compileTooth(0.14, &fast), std::invalid_argument);
}

// Peak tooth forces [N] (normal, tangential) on the kernel of config/bench/knead_polyurethane.yaml
// at tolerance 1e-9 with n modes, the modes from index quasi_from on made quasi-static (speedup
// 10; 0: none), and the given extra overrides.
std::pair<double, double> kneadPeaks(int n, int quasi_from, std::vector<std::string> extra = {}) {
  extra.insert(extra.end(), {"teeth.*.modes=" + std::to_string(n), "integrator.tolerance=1e-9",
                             "integrator.islands=false"});
  Model m = loadScene(
      std::string(THRESHING_SIM_SOURCE_DIR) + "/config/bench/knead_polyurethane.yaml", extra);
  m.teeth[0].quasi_static_from_mode = quasi_from;
  m.teeth[0].quasi_static_speedup = 10.0;
  compileModel(&m);
  Data d;
  testutil::runTo(m, &d, m.duration_s);
  EXPECT_EQ(d.stats.failure.cause, FailureCause::kNone);
  return {d.stats.kernel_tooth_peaks[0].normal_force_N,
          d.stats.kernel_tooth_peaks[0].tangential_force_N};
}

// What a complete static correction can reach on the polyurethane knead (docs/convergence.md,
// "Static correction against the mode count"): with modes 7 to 24 made quasi-static (the
// massless springs of the correction, every geometric coupling included), the peak normal force
// is more than 10 % off the 24-mode tooth (itself within 0.3 % of 64 modes), further than the 6
// retained modes alone: the truncated modes' inertia carries the stick phase. Without tooth
// friction the same quasi-static modes are within 1.5 %; with friction, from 17 on within 3 %.
TEST(StaticCorrection, KneadNeedsTheTruncatedModesInertia) {
  const auto ref = kneadPeaks(24, 0), six = kneadPeaks(6, 0), quasi = kneadPeaks(24, 6);
  std::printf(
      "knead peaks F_N, F_T [N]: 24 modes %.4f %.4f; 6 modes %.4f %.4f; 24 modes, 7-24 "
      "quasi-static %.4f %.4f\n",
      ref.first, ref.second, six.first, six.second, quasi.first, quasi.second);
  EXPECT_GT(std::abs(quasi.first - ref.first), 0.1 * ref.first);
  EXPECT_GT(std::abs(quasi.first - ref.first), std::abs(six.first - ref.first));
  // Quasi-static from higher modes on: the premise holds from about 16 retained modes.
  for (int from : {8, 12, 16}) {
    const auto q = kneadPeaks(24, from);
    std::printf("24 modes, %d-24 quasi-static: %.4f %.4f\n", from + 1, q.first, q.second);
    if (from == 16) {
      EXPECT_NEAR(q.first, ref.first, 0.03 * ref.first);
    }
  }
  const std::vector<std::string> smooth = {"contact.tooth_kernel.friction=0"};
  const auto ref0 = kneadPeaks(24, 0, smooth), quasi0 = kneadPeaks(24, 6, smooth);
  std::printf("without tooth friction: 24 modes %.4f N; 7-24 quasi-static %.4f N\n", ref0.first,
              quasi0.first);
  EXPECT_NEAR(quasi0.first, ref0.first, 0.015 * ref0.first);
}

}  // namespace
}  // namespace threshing_sim
