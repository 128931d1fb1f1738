// Unit tests of the assumed-mode tooth model (beam.h) and toothFrequenciesHz (simulator.h).
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <random>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "threshing_sim/core/beam.h"
#include "threshing_sim/core/constants.h"
#include "threshing_sim/core/simulator.h"

namespace threshing_sim {
namespace {

constexpr double kRpm800_radps = 800 * 2 * kPi / 60;  // 83.776 rad/s

// A measured value with 10 significant digits, for RecordProperty.
std::string fmt(double value) {
  std::ostringstream out;
  out.precision(10);
  out << value;
  return out.str();
}

// A tooth of round section with the given material, compiled on a drum of radius R.
ToothModel makeTooth(double diameter_m, double youngs_modulus_Pa, double density_kgpm3, int n_modes,
                     double drum_radius_m = 0.20, double length_m = 0.06) {
  ToothModel tooth;
  tooth.length_m = length_m;
  tooth.diameter_m = diameter_m;
  tooth.youngs_modulus_Pa = youngs_modulus_Pa;
  tooth.density_kgpm3 = density_kgpm3;
  tooth.n_modes = n_modes;
  compileTooth(drum_radius_m, &tooth);
  return tooth;
}

ToothModel makeNylonTooth(int n_modes, double drum_radius_m = 0.20) {
  return makeTooth(0.010, 3.0e9, 1140, n_modes, drum_radius_m);
}

// Composite Simpson rule with n_intervals (even) on [a, b]: an integrator independent of the
// Gauss-Legendre rule inside beam.cc. f(x) returns an Eigen object.
template <typename F>
auto simpson(double a, double b, int n_intervals, F f) {
  const double h = (b - a) / n_intervals;
  auto sum = (f(a) + f(b)).eval();
  for (int k = 1; k < n_intervals; ++k) sum += (k % 2 == 1 ? 4.0 : 2.0) * f(a + k * h);
  return (sum * (h / 3)).eval();
}

// Simpson with 20000 intervals: for the fastest integrand (phi_12 phi_12, wavenumber
// 2 beta_12 ~ 72 / L) its error is ~ (72 h / L)^4 / 180 ~ 1e-12 relative, well inside the
// tolerances below.
constexpr int kFineIntervals = 20000;

VecX phiAt(const ToothModel& tooth, double x_m) {
  VecX phi, dphi;
  evaluateModes(tooth, x_m, &phi, &dphi);
  return phi;
}

VecX dphiAt(const ToothModel& tooth, double x_m) {
  VecX phi, dphi;
  evaluateModes(tooth, x_m, &phi, &dphi);
  return dphi;
}

VecX ddphiAt(const ToothModel& tooth, double x_m) {
  VecX ddphi;
  evaluateModeCurvatures(tooth, x_m, &ddphi);
  return ddphi;
}

// ---------------------------------------------------------------------------------------------
// 1. Roots of the clamped-free characteristic equation.

TEST(BeamTest, BetaLMatchesTableAndSolvesCharacteristicEquation) {
  // The table is given to 8 decimals, so it is itself rounded by up to 5e-9.
  const double table[4] = {1.87510407, 4.69409113, 7.85475744, 10.99554073};
  for (int i = 0; i < 4; ++i) EXPECT_NEAR(cantileverBetaL(i), table[i], 1e-8) << "mode " << i;

  for (int i = 0; i < 12; ++i) {
    const double z = cantileverBetaL(i);
    // 1 + cos z cosh z = 0 scaled by 1 / cosh z (cosh(36) ~ 2e15 would turn a one-ulp error in
    // z into a residual of ~10): the scaled residual of a full-precision root is ~1e-16.
    EXPECT_NEAR(std::cos(z) + 1 / std::cosh(z), 0.0, 1e-12) << "mode " << i;
    // For i >= 4, cos z = -1 / cosh z puts the root 1 / cosh z (~1e-6 for i = 4) from the
    // asymptote (2i+1) pi / 2; 2 / cosh z bounds it.
    const double asymptote = (2 * i + 1) * kPi / 2;
    if (i >= 4) {
      EXPECT_NEAR(z, asymptote, 2 / std::cosh(asymptote)) << "mode " << i;
    }
  }
  EXPECT_THROW(cantileverBetaL(-1), std::invalid_argument);
}

// ---------------------------------------------------------------------------------------------
// 2. Mode shapes: against the textbook formula, orthonormality and boundary conditions.

TEST(BeamTest, ModeShapesMatchTextbookFormulaForLowModes) {
  const ToothModel tooth = makeNylonTooth(4);
  const double L = tooth.length_m;
  // For beta L <= 11 the textbook form loses at most log10(cosh 11) ~ 4.5 of the 19 digits of
  // long double, so it is a ~1e-14 reference; 1e-12 of the mode's scale C leaves margin.
  for (int i = 0; i < 4; ++i) {
    const long double bL = cantileverBetaL(i);
    const long double sigma = (std::cosh(bL) + std::cos(bL)) / (std::sinh(bL) + std::sin(bL));
    const double C = tooth.norm_C[i];
    for (int k = 0; k <= 20; ++k) {
      const double x = L * k / 20;
      const long double z = bL * x / L;
      const long double phi = std::cosh(z) - std::cos(z) - sigma * (std::sinh(z) - std::sin(z));
      const long double dphi = std::sinh(z) + std::sin(z) - sigma * (std::cosh(z) - std::cos(z));
      const long double ddphi = std::cosh(z) + std::cos(z) - sigma * (std::sinh(z) + std::sin(z));
      const double beta = tooth.beta_per_m[i];
      EXPECT_NEAR(phiAt(tooth, x)[i], C * static_cast<double>(phi), 1e-12 * C);
      EXPECT_NEAR(dphiAt(tooth, x)[i], C * beta * static_cast<double>(dphi), 1e-12 * C * beta);
      EXPECT_NEAR(ddphiAt(tooth, x)[i], C * beta * beta * static_cast<double>(ddphi),
                  1e-12 * C * beta * beta);
    }
  }
}

TEST(BeamTest, ModesAreMassOrthonormal) {
  const ToothModel tooth = makeNylonTooth(12);
  const double rhoA = tooth.mass_per_length_kgpm;
  const MatX mass = simpson(0.0, tooth.length_m, kFineIntervals, [&](double x) {
    const VecX phi = phiAt(tooth, x);
    return (rhoA * phi * phi.transpose()).eval();
  });
  // Quadrature error ~1e-12 and round-off ~1e-14: 1e-9 is a loose bound on the shape accuracy.
  const double error = (mass - MatX::Identity(12, 12)).cwiseAbs().maxCoeff();
  EXPECT_LT(error, 1e-9);
  RecordProperty("max_orthonormality_error", fmt(error));
}

TEST(BeamTest, ModesSatisfyClampedFreeBoundaryConditions) {
  const ToothModel tooth = makeNylonTooth(12);
  const double L = tooth.length_m;
  const VecX phi0 = phiAt(tooth, 0.0), dphi0 = dphiAt(tooth, 0.0), ddphiL = ddphiAt(tooth, L);
  for (int i = 0; i < 12; ++i) {
    const double C = tooth.norm_C[i], beta = tooth.beta_per_m[i];
    // Each value is a sum of O(1) terms times its scale C beta^k, so round-off is ~1e-15 of
    // that scale; 1e-12 leaves room for the beta L rounding amplified by up to beta L ~ 36.
    EXPECT_NEAR(phi0[i], 0.0, 1e-12 * C) << "phi(0), mode " << i;
    EXPECT_NEAR(dphi0[i], 0.0, 1e-12 * C * beta) << "phi'(0), mode " << i;
    EXPECT_NEAR(ddphiL[i], 0.0, 1e-12 * C * beta * beta) << "phi''(L), mode " << i;

    // phi'''(L) by a second-order one-sided difference of phi'' with step h = 1e-4 / beta:
    // truncation ~(beta h)^2 / 3 ~ 3e-9 and round-off ~1e-15 / (beta h) ~ 1e-11 of C beta^3.
    const double h = 1e-4 / beta;
    const double dddphiL =
        (3 * ddphiL[i] - 4 * ddphiAt(tooth, L - h)[i] + ddphiAt(tooth, L - 2 * h)[i]) / (2 * h);
    EXPECT_NEAR(dddphiL, 0.0, 1e-7 * C * beta * beta * beta) << "phi'''(L), mode " << i;
  }
}

TEST(BeamTest, DerivativesAreConsistent) {
  const ToothModel tooth = makeNylonTooth(12);
  const double L = tooth.length_m;
  // Central differences with h = 1e-4 / beta_12: truncation ~(beta h)^2 / 6 <= 2e-9 and
  // round-off ~1e-15 / (beta h) of each derivative's scale C beta^k.
  const double h = 1e-4 / tooth.beta_per_m[11];
  for (double x : {0.1 * L, 0.37 * L, 0.5 * L, 0.81 * L, 0.99 * L}) {
    const VecX dphi_fd = (phiAt(tooth, x + h) - phiAt(tooth, x - h)) / (2 * h);
    const VecX ddphi_fd = (dphiAt(tooth, x + h) - dphiAt(tooth, x - h)) / (2 * h);
    const VecX dphi = dphiAt(tooth, x), ddphi = ddphiAt(tooth, x);
    for (int i = 0; i < 12; ++i) {
      const double C = tooth.norm_C[i], beta = tooth.beta_per_m[i];
      EXPECT_NEAR(dphi_fd[i], dphi[i], 1e-7 * C * beta) << "x " << x << ", mode " << i;
      EXPECT_NEAR(ddphi_fd[i], ddphi[i], 1e-7 * C * beta * beta) << "x " << x << ", mode " << i;
    }
  }
}

TEST(BeamTest, EvaluateModesClampsAndReusesStorage) {
  const ToothModel tooth = makeNylonTooth(6);
  VecX phi(6), dphi(6);
  const double* phi_storage = phi.data();
  const double* dphi_storage = dphi.data();
  evaluateModes(tooth, 2 * tooth.length_m, &phi, &dphi);
  // Right-sized outputs keep their buffers (no allocation on the hot path).
  EXPECT_EQ(phi.data(), phi_storage);
  EXPECT_EQ(dphi.data(), dphi_storage);
  // Beyond the tip the tip values are returned (clamping), exactly.
  EXPECT_EQ(phi, phiAt(tooth, tooth.length_m));
  EXPECT_EQ(dphi, dphiAt(tooth, tooth.length_m));
  EXPECT_EQ(phiAt(tooth, -1.0), phiAt(tooth, 0.0));
  // Wrongly sized outputs are resized.
  VecX small(1), small_d;
  evaluateModes(tooth, 0.03, &small, &small_d);
  EXPECT_EQ(small.size(), 6);
  EXPECT_EQ(small_d.size(), 6);
}

// ---------------------------------------------------------------------------------------------
// Modal integrals and derived fields.

TEST(BeamTest, DerivedFieldsAndModalIntegrals) {
  const double R = 0.20;
  ToothModel tooth;
  tooth.n_modes = 12;
  tooth.mount_angle_rad = 0.7;
  compileTooth(R, &tooth);
  const double L = tooth.length_m, d = tooth.diameter_m;
  const double rhoA = tooth.mass_per_length_kgpm;

  // Section and frame: closed forms, to round-off.
  EXPECT_DOUBLE_EQ(tooth.area_m2, kPi * d * d / 4);
  EXPECT_DOUBLE_EQ(tooth.second_moment_m4, kPi * std::pow(d, 4) / 64);
  EXPECT_DOUBLE_EQ(rhoA, tooth.density_kgpm3 * tooth.area_m2);
  EXPECT_TRUE(tooth.e1_D.isApprox(Vec2(std::cos(0.7), std::sin(0.7)), 1e-15));
  EXPECT_TRUE(tooth.e2_D.isApprox(Vec2(-std::sin(0.7), std::cos(0.7)), 1e-15));
  EXPECT_TRUE(tooth.p_DR_D.isApprox(R * tooth.e1_D, 1e-15));
  EXPECT_NEAR(tooth.damping_coeff[2], 2 * tooth.damping_ratio * std::sqrt(tooth.omega0_sq[2]),
              1e-12 * tooth.damping_coeff[2]);

  // K_G, p and I0 against the independent Simpson rule (~1e-12 relative, see kFineIntervals);
  // 1e-10 relative to the largest entry.
  const MatX K_G = simpson(0.0, L, kFineIntervals, [&](double x) {
    const VecX dphi = dphiAt(tooth, x);
    return (rhoA * (R * (L - x) + (L * L - x * x) / 2) * dphi * dphi.transpose()).eval();
  });
  const VecX p = simpson(0.0, L, kFineIntervals,
                         [&](double x) { return (rhoA * (R + x) * phiAt(tooth, x)).eval(); });
  // Simpson's rule on one interval is exact for the quadratic integrand |p_DR_D + x e1|^2.
  const auto squared_radius = [&](double x) {
    return (tooth.p_DR_D + x * tooth.e1_D).squaredNorm();
  };
  const double I0 =
      rhoA * L / 6 * (squared_radius(0) + 4 * squared_radius(L / 2) + squared_radius(L));
  EXPECT_LT((tooth.K_G - K_G).cwiseAbs().maxCoeff(), 1e-10 * K_G.cwiseAbs().maxCoeff());
  EXPECT_LT((tooth.p_inertia - p).cwiseAbs().maxCoeff(), 1e-10 * p.cwiseAbs().maxCoeff());
  EXPECT_NEAR(tooth.I0_kgm2, I0, 1e-13 * I0);
  EXPECT_TRUE(tooth.K_G.isApprox(tooth.K_G.transpose(), 1e-15));

  // Stations: equally spaced with exact ends, shapes sampled there.
  ASSERT_EQ(tooth.station_x_m.size(), tooth.n_stations);
  EXPECT_EQ(tooth.station_x_m[0], 0.0);
  EXPECT_EQ(tooth.station_x_m[tooth.n_stations - 1], L);
  EXPECT_NEAR(tooth.station_x_m[3], 3 * L / (tooth.n_stations - 1), 1e-16);
  EXPECT_EQ(VecX(tooth.phi_s.row(3).transpose()), phiAt(tooth, tooth.station_x_m[3]));
  EXPECT_EQ(VecX(tooth.dphi_s.row(3).transpose()), dphiAt(tooth, tooth.station_x_m[3]));
}

// The sections' rotation per unit slope (docs/model.md §9b): Timoshenko's quasi-static
// 1 / (1 + (E / kappa G) (I / A) beta_i^2), kappa = 6 (1 + nu) / (7 + 6 nu), falling with the
// mode's wave number; 1 for every mode with Euler-Bernoulli sections.
TEST(BeamTest, SectionRotationFactorsMatchTheShearCorrection) {
  ToothModel tooth;
  tooth.n_modes = 8;
  tooth.poisson_ratio = 0.39;
  compileTooth(0.2, &tooth);
  const double nu = tooth.poisson_ratio, d = tooth.diameter_m;
  const double kappa = 6 * (1 + nu) / (7 + 6 * nu);
  for (int i = 0; i < tooth.n_modes; ++i) {
    const double beta = cantileverBetaL(i) / tooth.length_m;
    const double expected = 1 / (1 + 2 * (1 + nu) / kappa * (d * d / 16) * beta * beta);
    EXPECT_NEAR(tooth.rotation_factor[i], expected, 1e-12) << "mode " << i;
    if (i > 0) {
      EXPECT_LT(tooth.rotation_factor[i], tooth.rotation_factor[i - 1]);
    }
  }
  EXPECT_GT(tooth.rotation_factor[0], 0.97);  // d / L = 1/6: the first mode barely shears
  tooth.section_rotation = ToothSectionRotation::kEulerBernoulli;
  compileTooth(0.2, &tooth);
  EXPECT_EQ(tooth.rotation_factor, VecX::Ones(tooth.n_modes));
}

TEST(BeamTest, StiffnessMatrixIsLambdaPlusOmegaSquaredKgMinusI) {
  const ToothModel tooth = makeNylonTooth(4);
  const MatX K0 = toothStiffness(tooth, 0.0);
  EXPECT_EQ(MatX(K0), MatX(tooth.omega0_sq.asDiagonal()));
  const double omega = 50.0;
  const MatX K = toothStiffness(tooth, omega);
  const MatX expected =
      MatX(tooth.omega0_sq.asDiagonal()) + omega * omega * (tooth.K_G - MatX::Identity(4, 4));
  EXPECT_TRUE(K.isApprox(expected, 1e-15));
}

// ---------------------------------------------------------------------------------------------
// 3. Natural frequencies.

TEST(BeamTest, FrequenciesAtRestMatchClosedForm) {
  const ToothModel tooth = makeNylonTooth(6);
  const double EI = tooth.youngs_modulus_Pa * tooth.second_moment_m4;
  const double rhoA = tooth.mass_per_length_kgpm;
  const double scale = std::sqrt(EI / (rhoA * std::pow(tooth.length_m, 4)));
  const VecX f_Hz = toothFrequenciesHz(tooth, 0.0);
  ASSERT_EQ(f_Hz.size(), 6);
  // At rest the stiffness is diagonal: the eigen-solver returns it to round-off.
  for (int i = 0; i < 6; ++i) {
    const double bL = cantileverBetaL(i);
    EXPECT_NEAR(f_Hz[i], bL * bL / (2 * kPi) * scale, 1e-12 * f_Hz[i]) << "mode " << i;
  }
}

TEST(BeamTest, FrequenciesMatchPhysicsMdIllustrations) {
  // docs/model.md §3, L = 60 mm, R = 200 mm, 800 rpm; the stated values have 3 digits,
  // so they are checked within 1 %. Four modes: the coupling through K_G to modes 5-12 lowers
  // the rotating rubber frequency by only 3e-4 (34.446 -> 34.435 Hz).
  const ToothModel rubber = makeTooth(0.010, 1.5e6, 950, 4);
  const double rubber_rest_Hz = toothFrequenciesHz(rubber, 0.0)[0];
  const double rubber_rot_Hz = toothFrequenciesHz(rubber, kRpm800_radps)[0];
  EXPECT_NEAR(rubber_rest_Hz, 15.4, 0.01 * 15.4);
  EXPECT_NEAR(rubber_rot_Hz, 34.4, 0.01 * 34.4);

  const ToothModel nylon = makeNylonTooth(4);
  const double nylon_Hz = toothFrequenciesHz(nylon, kRpm800_radps)[0];
  EXPECT_NEAR(nylon_Hz, 630, 0.01 * 630);

  const ToothModel steel = makeTooth(0.005, 206e9, 7850, 4);
  const double steel_Hz = toothFrequenciesHz(steel, kRpm800_radps)[0];
  EXPECT_NEAR(steel_Hz, 995, 0.01 * 995);

  RecordProperty("rubber_rest_Hz", fmt(rubber_rest_Hz));
  RecordProperty("rubber_800rpm_Hz", fmt(rubber_rot_Hz));
  RecordProperty("nylon_800rpm_Hz", fmt(nylon_Hz));
  RecordProperty("steel_800rpm_Hz", fmt(steel_Hz));
}

TEST(BeamTest, FrequenciesAreAscendingAndSofteningClampsToZero) {
  const ToothModel rubber = makeTooth(0.010, 1.5e6, 950, 6);
  const VecX f_Hz = toothFrequenciesHz(rubber, kRpm800_radps);
  for (int i = 1; i < f_Hz.size(); ++i) EXPECT_LT(f_Hz[i - 1], f_Hz[i]);

  // The zero-order model (K_G dropped) keeps only -Omega^2 I and softens: omega_i^2 - Omega^2.
  // Above the first rest frequency that eigenvalue is negative and is reported as 0 Hz.
  ToothModel zero_order = rubber;
  zero_order.K_G.setZero();
  const double omega1_radps = std::sqrt(zero_order.omega0_sq[0]);
  const VecX f_soft_Hz = toothFrequenciesHz(zero_order, 0.5 * omega1_radps);
  EXPECT_NEAR(f_soft_Hz[0], std::sqrt(0.75) * omega1_radps / (2 * kPi), 1e-12 * f_soft_Hz[0]);
  const VecX f_unstable_Hz = toothFrequenciesHz(zero_order, 2 * omega1_radps);
  EXPECT_EQ(f_unstable_Hz[0], 0.0);
  EXPECT_GT(f_unstable_Hz[1], 0.0);
}

// ---------------------------------------------------------------------------------------------
// 4. Southwell coefficient of the first mode.

TEST(BeamTest, SouthwellCoefficient) {
  // K_G is linear in R: K_G(R) = K_G(0) + (R / L) dK_G/d(R/L), so the radii 0 and L give the
  // slope exactly. Reference values 1.1933 and 1.5709 are given to 4 decimals (rounding <= 5e-5).
  const ToothModel at_axis = makeNylonTooth(4, 0.0);
  const ToothModel at_L = makeNylonTooth(4, at_axis.length_m);
  const double k0 = at_axis.K_G(0, 0);
  const double slope = at_L.K_G(0, 0) - k0;
  EXPECT_NEAR(k0, 1.1933, 1e-4);
  EXPECT_NEAR(slope, 1.5709, 1e-4);
  RecordProperty("K_G11_R0", fmt(k0));
  RecordProperty("K_G11_slope", fmt(slope));
}

// ---------------------------------------------------------------------------------------------
// 5. Static tip deflection converges to F L^3 / (3 E I).

TEST(BeamTest, StaticTipDeflectionConverges) {
  const double F_N = 1.0;
  double previous_error = 1.0;
  double error_6 = 0, error_12 = 0;
  for (int n = 1; n <= 12; ++n) {
    const ToothModel tooth = makeNylonTooth(n);
    const double L = tooth.length_m;
    const double exact_m = F_N * L * L * L / (3 * tooth.youngs_modulus_Pa * tooth.second_moment_m4);
    // Modal statics: q_i = F phi_i(L) / omega_i^2, w(L) = sum phi_i(L) q_i.
    const VecX phi_L = phiAt(tooth, L);
    const double w_L = (phi_L.array().square() * F_N / tooth.omega0_sq.array()).sum();
    const double error = (exact_m - w_L) / exact_m;
    // Each mode adds a positive term, so the error falls monotonically from above.
    EXPECT_GT(error, 0.0) << "n " << n;
    EXPECT_LT(error, previous_error) << "n " << n;
    previous_error = error;
    if (n == 6) error_6 = error;
    if (n == 12) error_12 = error;
  }
  // phi_i(L)^2 = 4 / (rho A L) for every mode, so w(L) / exact = 12 sum_{i<=n} (beta_i L)^-4 and
  // the truncation error 12 sum_{i>n} (beta_i L)^-4 ~ 0.041 / n^3 is 2.4e-5 at n = 12: 1e-4 is
  // an honest bound.
  EXPECT_LT(error_12, 1e-4);
  // The n^-3 rate: doubling n divides the error by ~8 (the asymptote is reached slowly, so the
  // band is [6, 10]).
  EXPECT_GT(error_6 / error_12, 6.0);
  EXPECT_LT(error_6 / error_12, 10.0);
  RecordProperty("tip_deflection_rel_error_n6", fmt(error_6));
  RecordProperty("tip_deflection_rel_error_n12", fmt(error_12));
}

// ---------------------------------------------------------------------------------------------
// 6. Foreshortening matrix H(x).

TEST(BeamTest, HAtStationsMatchesIndependentQuadrature) {
  ToothModel tooth;
  tooth.n_modes = 12;
  tooth.n_stations = 7;
  compileTooth(0.2, &tooth);
  ASSERT_EQ(static_cast<int>(tooth.H_s.size()), 7);
  EXPECT_EQ(tooth.H_s[0], MatX::Zero(12, 12));
  for (int s = 1; s < 7; ++s) {
    const MatX H = simpson(0.0, tooth.station_x_m[s], kFineIntervals, [&](double x) {
      const VecX dphi = dphiAt(tooth, x);
      return (dphi * dphi.transpose()).eval();
    });
    // Simpson ~1e-12 relative (see kFineIntervals); 1e-10 of the largest entry.
    EXPECT_LT((tooth.H_s[s] - H).cwiseAbs().maxCoeff(), 1e-10 * H.cwiseAbs().maxCoeff())
        << "station " << s;
  }
}

// The quadrature of K_G, p and H scales with the highest retained mode (few modes, few points):
// at every mode count it matches a 4x finer composite 8-point Gauss rule with 176 sub-intervals
// per length (the old fixed rule) to 1e-12 of the largest entry.
TEST(BeamTest, ModalIntegralsMatchAFineRuleAtEveryModeCount) {
  constexpr double kNode[8] = {-0.96028985649753623168, -0.79666647741362673959,
                               -0.52553240991632898582, -0.18343464249564980494,
                               0.18343464249564980494,  0.52553240991632898582,
                               0.79666647741362673959,  0.96028985649753623168};
  constexpr double kWeight[8] = {0.10122853629037625915, 0.22238103445337447054,
                                 0.31370664587788728734, 0.36268378337836198297,
                                 0.36268378337836198297, 0.31370664587788728734,
                                 0.22238103445337447054, 0.10122853629037625915};
  const double R = 0.2;
  for (int n : {1, 2, 4, 6, 12, 24, 64}) {
    const ToothModel t = makeNylonTooth(n, R);
    const double L = t.length_m, rhoA = t.mass_per_length_kgpm;
    const int n_sub = 4 * 176;
    MatX K_G = MatX::Zero(n, n), H = MatX::Zero(n, n);
    VecX p = VecX::Zero(n);
    const int last = t.n_stations - 1;
    for (int k = 0; k < n_sub; ++k) {
      for (int g = 0; g < 8; ++g) {
        const double x = (k + 0.5 + 0.5 * kNode[g]) * L / n_sub, w = 0.5 * kWeight[g] * L / n_sub;
        const VecX phi = phiAt(t, x), dphi = dphiAt(t, x);
        K_G += w * rhoA * (R * (L - x) + (L * L - x * x) / 2) * dphi * dphi.transpose();
        p += w * rhoA * (R + x) * phi;
        if (k < n_sub / last * 5) H += w * dphi * dphi.transpose();  // up to station 5
      }
    }
    EXPECT_LT((t.K_G - K_G).cwiseAbs().maxCoeff(), 1e-12 * K_G.cwiseAbs().maxCoeff()) << n;
    EXPECT_LT((t.p_inertia - p).cwiseAbs().maxCoeff(), 1e-12 * p.cwiseAbs().maxCoeff()) << n;
    EXPECT_LT((t.H_s[5] - H).cwiseAbs().maxCoeff(), 1e-12 * H.cwiseAbs().maxCoeff()) << n;
  }
}

TEST(BeamTest, InterpolateHIsExactAtStationsAndLinearBetween) {
  const ToothModel tooth = makeNylonTooth(5);
  MatX H;
  for (int s = 0; s < tooth.n_stations; ++s) {
    interpolateH(tooth, tooth.station_x_m[s], &H);
    EXPECT_EQ(H, tooth.H_s[s]) << "station " << s;
  }
  // Midway: the average of the neighbours (round-off only).
  const double x_mid = 0.5 * (tooth.station_x_m[2] + tooth.station_x_m[3]);
  interpolateH(tooth, x_mid, &H);
  EXPECT_TRUE(H.isApprox(0.5 * (tooth.H_s[2] + tooth.H_s[3]), 1e-14));
  // Outside [0, L]: clamped to the end stations.
  interpolateH(tooth, -0.01, &H);
  EXPECT_EQ(H, tooth.H_s.front());
  interpolateH(tooth, 1.0, &H);
  EXPECT_EQ(H, tooth.H_s.back());
}

// ---------------------------------------------------------------------------------------------
// 7. Validation.

void expectInvalid(ToothModel tooth, const std::string& field, double drum_radius_m = 0.2) {
  try {
    compileTooth(drum_radius_m, &tooth);
    ADD_FAILURE() << "no exception for " << field;
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find(field), std::string::npos) << e.what();
  }
}

TEST(BeamTest, CompileToothRejectsNonPhysicalValues) {
  ToothModel tooth;
  tooth.length_m = -0.01;
  expectInvalid(tooth, "tooth.length");
  tooth = ToothModel();
  tooth.diameter_m = 0;
  expectInvalid(tooth, "tooth.diameter");
  tooth = ToothModel();
  tooth.n_modes = -1;
  expectInvalid(tooth, "tooth.n_modes");
  tooth.n_modes = kMaxModes + 1;
  expectInvalid(tooth, "tooth.n_modes");
  tooth = ToothModel();
  tooth.damping_ratio = 1.5;
  expectInvalid(tooth, "tooth.damping_ratio");
  tooth = ToothModel();
  tooth.youngs_modulus_Pa = std::nan("");
  expectInvalid(tooth, "tooth.youngs_modulus");
  tooth = ToothModel();
  tooth.density_kgpm3 = 0;
  expectInvalid(tooth, "tooth.density");
  tooth = ToothModel();
  tooth.n_stations = 1;
  expectInvalid(tooth, "tooth.n_stations");
  tooth = ToothModel();
  tooth.poisson_ratio = 0.5;
  expectInvalid(tooth, "tooth.poisson_ratio");
  expectInvalid(ToothModel(), "drum.radius", -0.1);

  // The message states the rule and the offending value.
  tooth = ToothModel();
  tooth.length_m = -0.01;
  try {
    compileTooth(0.2, &tooth);
    ADD_FAILURE() << "no exception for a negative length";
  } catch (const std::invalid_argument& e) {
    EXPECT_EQ(std::string(e.what()), "tooth.length: must be > 0 (got -0.01)");
  }
}

// ---------------------------------------------------------------------------------------------
// 8. Rigid tooth (no modes).

TEST(BeamTest, RigidToothHasEmptyModalData) {
  const ToothModel tooth = makeNylonTooth(0);
  EXPECT_EQ(tooth.beta_per_m.size(), 0);
  EXPECT_EQ(tooth.sigma.size(), 0);
  EXPECT_EQ(tooth.norm_C.size(), 0);
  EXPECT_EQ(tooth.omega0_sq.size(), 0);
  EXPECT_EQ(tooth.damping_coeff.size(), 0);
  EXPECT_EQ(tooth.K_G.size(), 0);
  EXPECT_EQ(tooth.p_inertia.size(), 0);
  EXPECT_GT(tooth.I0_kgm2, 0.0);
  EXPECT_EQ(tooth.station_x_m.size(), tooth.n_stations);
  EXPECT_EQ(tooth.phi_s.rows(), tooth.n_stations);
  EXPECT_EQ(tooth.phi_s.cols(), 0);
  EXPECT_EQ(tooth.dphi_s.cols(), 0);
  ASSERT_EQ(static_cast<int>(tooth.H_s.size()), tooth.n_stations);
  for (const MatX& H : tooth.H_s) EXPECT_EQ(H.size(), 0);

  VecX phi(3), dphi(3);
  evaluateModes(tooth, 0.03, &phi, &dphi);
  EXPECT_EQ(phi.size(), 0);
  MatX H;
  interpolateH(tooth, 0.03, &H);
  EXPECT_EQ(H.size(), 0);
  EXPECT_EQ(toothStiffness(tooth, 80.0).size(), 0);
  EXPECT_EQ(toothFrequenciesHz(tooth, 80.0).size(), 0);
  EXPECT_EQ(tooth.mode_table_intervals, 0);
  EXPECT_EQ(tooth.mode_table, nullptr);
  interpolateModes(tooth, 0.03, &phi, &dphi);
  EXPECT_EQ(phi.size(), 0);
}

// ---------------------------------------------------------------------------------------------
// The mode table (interpolateModes): the step's phi, phi', phi'' without exp, sin or cos.

// Largest interpolation error of the table over `samples` random x (and the ends), per
// derivative order, relative to each mode's scale 2 C_i beta_i^k (|phi_i^(k)| <= ~2 C beta^k).
std::array<double, 3> tableError(const ToothModel& tooth, int samples, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> uniform(0.0, tooth.length_m);
  std::array<double, 3> worst{0, 0, 0};
  VecX phi, dphi, ddphi, t_phi, t_dphi, t_ddphi(tooth.n_modes);
  for (int k = 0; k < samples + 2; ++k) {
    const double x = k == 0 ? 0.0 : k == 1 ? tooth.length_m : uniform(rng);
    evaluateModes(tooth, x, &phi, &dphi);
    evaluateModeCurvatures(tooth, x, &ddphi);
    t_phi.resize(tooth.n_modes);
    t_dphi.resize(tooth.n_modes);
    interpolateModes(tooth, x, t_phi.data(), t_dphi.data(), t_ddphi.data());
    for (int i = 0; i < tooth.n_modes; ++i) {
      const double scale = 2 * tooth.norm_C[i], beta = tooth.beta_per_m[i];
      worst[0] = std::max(worst[0], std::abs(t_phi[i] - phi[i]) / scale);
      worst[1] = std::max(worst[1], std::abs(t_dphi[i] - dphi[i]) / (scale * beta));
      worst[2] = std::max(worst[2], std::abs(t_ddphi[i] - ddphi[i]) / (scale * beta * beta));
    }
  }
  return worst;
}

TEST(BeamTest, ModeTableMatchesEvaluateModesForOneTo64Modes) {
  for (int n : {1, 2, 3, 4, 6, 8, 12, 16, 24, 32, 48, 64}) {
    const ToothModel tooth = makeNylonTooth(n);
    // The density rule: beta_n h <= 1 / kModeTablePointsPerRadian, whole station intervals,
    // and a few thousand points at most (compile cost).
    EXPECT_LE(tooth.beta_per_m[n - 1] * tooth.mode_table_dx_m, 1.0 / kModeTablePointsPerRadian);
    EXPECT_EQ(tooth.mode_table_intervals % (tooth.n_stations - 1), 0);
    EXPECT_LE(tooth.mode_table_intervals, 3500);
    ASSERT_NE(tooth.mode_table, nullptr);
    EXPECT_EQ(tooth.mode_table->size(), 4u * n * (tooth.mode_table_intervals + 1));
    // A copy of the tooth (an island's sub-model) shares the table.
    const ToothModel copy = tooth;
    EXPECT_EQ(copy.mode_table.get(), tooth.mode_table.get());
    const std::array<double, 3> err = tableError(tooth, 4000, 1000u + n);
    EXPECT_LT(err[0], 5e-12) << n << " modes: phi";
    EXPECT_LT(err[1], 1e-10) << n << " modes: phi'";
    EXPECT_LT(err[2], 5e-12) << n << " modes: phi''";
    RecordProperty("table_error_" + std::to_string(n) + "_modes",
                   fmt(err[0]) + " " + fmt(err[1]) + " " + fmt(err[2]));
  }
}

TEST(BeamTest, ModeTableSlopeIsTheDerivativeOfItsValue) {
  // phi' of the table is the derivative of its phi: a central difference of the interpolated
  // phi agrees with it to the difference's own error, across table intervals too.
  const ToothModel tooth = makeNylonTooth(8);
  VecX phi_a, phi_b, dphi_a, dphi_b, phi, dphi;
  const double h = 1e-6 * tooth.mode_table_dx_m;
  for (int k = 1; k < 50; ++k) {
    const double x = tooth.length_m * k / 50.3;
    interpolateModes(tooth, x - h, &phi_a, &dphi_a);
    interpolateModes(tooth, x + h, &phi_b, &dphi_b);
    interpolateModes(tooth, x, &phi, &dphi);
    const VecX fd = (phi_b - phi_a) / (2 * h);
    for (int i = 0; i < tooth.n_modes; ++i) {
      EXPECT_NEAR(fd[i], dphi[i], 1e-6 * 2 * tooth.norm_C[i] * tooth.beta_per_m[i]);
    }
  }
  // Continuous at a table point: both sides' limits agree to rounding.
  const double x_j = 3 * tooth.mode_table_dx_m;
  interpolateModes(tooth, std::nextafter(x_j, 0.0), &phi_a, &dphi_a);
  interpolateModes(tooth, x_j, &phi_b, &dphi_b);
  for (int i = 0; i < tooth.n_modes; ++i) {
    EXPECT_NEAR(phi_a[i], phi_b[i], 1e-13 * tooth.norm_C[i]);
    EXPECT_NEAR(dphi_a[i], dphi_b[i], 1e-12 * tooth.norm_C[i] * tooth.beta_per_m[i]);
  }
}

TEST(BeamTest, ModeTableIsExactAtTheStations) {
  // Every station is a table point: the step's phi there is the compiled phi_s to rounding.
  const ToothModel tooth = makeNylonTooth(6);
  VecX phi, dphi;
  for (int s = 0; s < tooth.n_stations; ++s) {
    interpolateModes(tooth, tooth.station_x_m[s], &phi, &dphi);
    for (int i = 0; i < tooth.n_modes; ++i) {
      EXPECT_NEAR(phi[i], tooth.phi_s(s, i), 1e-14 * tooth.norm_C[i]) << s;
      EXPECT_NEAR(dphi[i], tooth.dphi_s(s, i), 1e-13 * tooth.norm_C[i] * tooth.beta_per_m[i]);
    }
  }
}

}  // namespace
// interpolateDeflection (the contact phase's warm narrow phase): w, w', w'' from one table
// interval contracted with q equal phi . q, phi' . q, phi'' . q of interpolateModes to
// rounding, also when the interval held changes between calls, at the table points and ends.
TEST(BeamTest, DeflectionFromTheContractedTableMatchesTheModes) {
  for (int n : {1, 4, 12}) {
    const ToothModel tooth = makeNylonTooth(n);
    std::mt19937 rng(7);
    std::uniform_real_distribution<double> coord(-1e-4, 1e-4);
    VecX q(n);
    for (int i = 0; i < n; ++i) q[i] = coord(rng) / (i + 1);
    std::vector<double> xs = {0.0, tooth.length_m, tooth.mode_table_dx_m, 0.5 * tooth.length_m};
    std::uniform_real_distribution<double> along(0.0, tooth.length_m);
    for (int k = 0; k < 200; ++k) xs.push_back(along(rng));
    DeflectionInterval interval;  // kept across the calls, as the narrow phase keeps it
    double scale0 = 0, scale1 = 0, scale2 = 0, err0 = 0, err1 = 0, err2 = 0;
    for (double x : xs) {
      VecX phi(n), dphi(n), ddphi(n);
      interpolateModes(tooth, x, phi.data(), dphi.data(), ddphi.data());
      double w = 0, w1 = 0, w2 = 0;
      interpolateDeflection(tooth, q.data(), x, &interval, &w, &w1, &w2);
      err0 = std::max(err0, std::abs(w - phi.dot(q)));
      err1 = std::max(err1, std::abs(w1 - dphi.dot(q)));
      err2 = std::max(err2, std::abs(w2 - ddphi.dot(q)));
      scale0 = std::max(scale0, phi.cwiseAbs().dot(q.cwiseAbs()));
      scale1 = std::max(scale1, dphi.cwiseAbs().dot(q.cwiseAbs()));
      scale2 = std::max(scale2, ddphi.cwiseAbs().dot(q.cwiseAbs()));
    }
    EXPECT_LT(err0, 1e-14 * scale0) << n << " modes";
    EXPECT_LT(err1, 1e-12 * scale1) << n << " modes";  // the slope weights go as 1/dx
    EXPECT_LT(err2, 1e-14 * scale2) << n << " modes";
    RecordProperty("relative_error_w_" + std::to_string(n), fmt(err0 / scale0));
    RecordProperty("relative_error_w1_" + std::to_string(n), fmt(err1 / scale1));
    RecordProperty("relative_error_w2_" + std::to_string(n), fmt(err2 / scale2));
  }
}

}  // namespace threshing_sim
