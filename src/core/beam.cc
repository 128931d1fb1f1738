// threshing_sim core: assumed-mode model of a clamped-free Euler-Bernoulli tooth on a drum.
//
// Mode shapes are evaluated in the cancellation-free form
//   cosh z - sigma sinh z = ((1 - sigma) e^z + (1 + sigma) e^-z) / 2,
// where (1 - sigma) ~ e^-(beta L) is computed directly, so every term stays O(1) for all modes.

#include "threshing_sim/core/beam.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>

#include "eigen_solvers.h"
#include "internal.h"
#include "modal_propagator.h"
#include "threshing_sim/core/constants.h"
#include "threshing_sim/core/large_deflection.h"
#include "threshing_sim/core/simulator.h"

namespace threshing_sim {
namespace {

// 8-point Gauss-Legendre rule on [-1, 1] (exact for polynomials of degree 15).
constexpr int kGaussPoints = 8;
constexpr std::array<double, kGaussPoints> kGaussNode = {
    -0.96028985649753623168, -0.79666647741362673959, -0.52553240991632898582,
    -0.18343464249564980494, 0.18343464249564980494,  0.52553240991632898582,
    0.79666647741362673959,  0.96028985649753623168};
constexpr std::array<double, kGaussPoints> kGaussWeight = {
    0.10122853629037625915, 0.22238103445337447054, 0.31370664587788728734, 0.36268378337836198297,
    0.36268378337836198297, 0.31370664587788728734, 0.22238103445337447054, 0.10122853629037625915};

// Sub-intervals per tooth length: with beta_64 L ~ 200, the fastest integrand (phi_64'^2) turns
// by ~2.3 rad per sub-interval, where the 8-point rule is accurate to ~1e-14.
constexpr int kSubintervalsPerLength = 176;

// Calls add(x, weight) at the nodes of a composite Gauss-Legendre rule on [a, b]; the number of
// sub-intervals is proportional to (b - a) / length_m so any sub-range is integrated as finely
// as the whole tooth (the 1e-9 keeps a rounding excess on L / n_stations from adding one).
template <typename AddFn>
void forEachQuadraturePoint(double a_m, double b_m, double length_m, AddFn add) {
  const int n_sub = std::max(
      1, static_cast<int>(std::ceil(kSubintervalsPerLength * (b_m - a_m) / length_m - 1e-9)));
  const double half_width_m = 0.5 * (b_m - a_m) / n_sub;
  for (int k = 0; k < n_sub; ++k) {
    const double mid_m = a_m + (2 * k + 1) * half_width_m;
    for (int g = 0; g < kGaussPoints; ++g) {
      add(mid_m + half_width_m * kGaussNode[g], half_width_m * kGaussWeight[g]);
    }
  }
}

// (1 - sigma_i) / 2 for the i-th mode, where sigma = (cosh bL + cos bL) / (sinh bL + sin bL).
// Computed as (-e^-bL + sin bL - cos bL) / (2 (sinh bL + sin bL)): no cancellation, full
// relative precision even when it is ~1e-16 (mode 12).
double halfOneMinusSigma(double beta_L) {
  return (-std::exp(-beta_L) + std::sin(beta_L) - std::cos(beta_L)) /
         (2.0 * (std::sinh(beta_L) + std::sin(beta_L)));
}

// (1 - sigma_i) / 2 depends only on the mode index, so it is tabulated once for all teeth.
const std::array<double, kMaxModes>& halfOneMinusSigmaTable() {
  static const std::array<double, kMaxModes> table = [] {
    std::array<double, kMaxModes> t{};
    for (int i = 0; i < kMaxModes; ++i) t[i] = halfOneMinusSigma(cantileverBetaL(i));
    return t;
  }();
  return table;
}

[[noreturn]] void throwInvalid(const char* field, const char* rule, double value) {
  std::ostringstream message;
  message << field << ": " << rule << " (got " << value << ")";
  throw std::invalid_argument(message.str());
}

void requireFinite(const char* field, double value) {
  if (!std::isfinite(value)) throwInvalid(field, "must be finite", value);
}

void requirePositive(const char* field, double value) {
  requireFinite(field, value);
  if (!(value > 0)) throwInvalid(field, "must be > 0", value);
}

void validateTooth(double drum_radius_m, const ToothModel& tooth) {
  requireFinite("drum.radius", drum_radius_m);
  if (!(drum_radius_m >= 0)) throwInvalid("drum.radius", "must be >= 0", drum_radius_m);
  requireFinite("tooth.mount_angle", tooth.mount_angle_rad);
  requirePositive("tooth.length", tooth.length_m);
  requirePositive("tooth.diameter", tooth.diameter_m);
  requirePositive("tooth.youngs_modulus", tooth.youngs_modulus_Pa);
  requirePositive("tooth.density", tooth.density_kgpm3);
  if (!(tooth.damping_ratio >= 0 && tooth.damping_ratio < 1)) {
    throwInvalid("tooth.damping_ratio", "must be in [0, 1)", tooth.damping_ratio);
  }
  if (!(tooth.poisson_ratio >= 0 && tooth.poisson_ratio < 0.5)) {
    throwInvalid("tooth.poisson_ratio", "must be in [0, 0.5)", tooth.poisson_ratio);
  }
  if (tooth.n_modes < 0 || tooth.n_modes > kMaxModes) {
    throwInvalid("tooth.n_modes", "must be in [0, 64]", tooth.n_modes);
  }
  if (tooth.n_stations < 2) throwInvalid("tooth.n_stations", "must be >= 2", tooth.n_stations);
}

}  // namespace

double cantileverBetaL(int i) {
  if (i < 0) throwInvalid("mode index", "must be >= 0", i);
  // Starting guess: the tabulated roots, then the asymptote (2i + 1) pi / 2 (0-based i).
  constexpr std::array<double, 4> kTabulated = {1.87510407, 4.69409113, 7.85475744, 10.99554073};
  double z = i < 4 ? kTabulated[i] : (2 * i + 1) * kPi / 2;

  // Newton on the scaled characteristic equation cos z + 1 / cosh z = 0 (same roots as
  // 1 + cos z cosh z = 0, but O(1) in size, so it converges to full precision).
  for (int iter = 0; iter < 50; ++iter) {
    const double sech = 1.0 / std::cosh(z);
    const double residual = std::cos(z) + sech;
    const double slope = -std::sin(z) - sech * std::tanh(z);
    const double step = residual / slope;
    z -= step;
    if (std::abs(step) <= 2 * std::numeric_limits<double>::epsilon() * z) break;
  }
  return z;
}

// Section rotation per unit slope (docs/model.md §9b). A shear-flexible (Timoshenko) beam bent
// quasi-statically into a wave of number beta turns its sections by
// psi = w' / (1 + (E / kappa G) (I / A) beta^2): the shear takes up the rest of the slope.
// Euler-Bernoulli (psi = w') lets the slopes of high modes grow with beta, so the friction
// couple's reach into them, and the stick forces, never converge in the mode count.
// kappa = 6 (1 + nu) / (7 + 6 nu): the shear coefficient of a solid circular section.
double sectionRotationFactor(const ToothModel& t, double beta_per_m) {
  if (t.section_rotation == ToothSectionRotation::kEulerBernoulli) return 1.0;
  const double nu = t.poisson_ratio;
  const double kappa = 6.0 * (1.0 + nu) / (7.0 + 6.0 * nu);
  const double E_over_kappa_G = 2.0 * (1.0 + nu) / kappa;   // G = E / (2 (1 + nu))
  const double r_g_sq_m2 = t.second_moment_m4 / t.area_m2;  // I / A = d^2 / 16
  return 1.0 / (1.0 + E_over_kappa_G * r_g_sq_m2 * beta_per_m * beta_per_m);
}

void compileTooth(double drum_radius_m, ToothModel* tooth) {
  validateTooth(drum_radius_m, *tooth);
  ToothModel& t = *tooth;
  const double R = drum_radius_m;
  const double L = t.length_m;
  const int n = t.n_modes;

  // Round section properties.
  t.area_m2 = kPi * t.diameter_m * t.diameter_m / 4;
  t.second_moment_m4 = kPi * std::pow(t.diameter_m, 4) / 64;
  t.mass_per_length_kgpm = t.density_kgpm3 * t.area_m2;
  const double rhoA = t.mass_per_length_kgpm;
  const double EI = t.youngs_modulus_Pa * t.second_moment_m4;

  // Root and axes in the drum frame: the tooth stands radially at mounting angle alpha.
  t.e1_D = Vec2(std::cos(t.mount_angle_rad), std::sin(t.mount_angle_rad));
  t.e2_D = Vec2(-t.e1_D.y(), t.e1_D.x());
  t.p_DR_D = R * t.e1_D;

  // Modal constants. The clamped-free shape with C = 1 has int_0^L phi^2 dx = L, so
  // C = 1 / sqrt(rho A L) mass-normalises every mode (checked numerically in the tests).
  t.beta_per_m.resize(n);
  t.sigma.resize(n);
  t.norm_C.resize(n);
  t.omega0_sq.resize(n);
  t.damping_coeff.resize(n);
  for (int i = 0; i < n; ++i) {
    const double beta_L = cantileverBetaL(i);
    t.beta_per_m[i] = beta_L / L;
    t.sigma[i] = (std::cosh(beta_L) + std::cos(beta_L)) / (std::sinh(beta_L) + std::sin(beta_L));
    t.norm_C[i] = 1.0 / std::sqrt(rhoA * L);
    t.omega0_sq[i] = std::pow(beta_L, 4) * EI / (rhoA * std::pow(L, 4));
    t.damping_coeff[i] = 2 * t.damping_ratio * std::sqrt(t.omega0_sq[i]);
  }
  t.rotation_factor.resize(n);
  for (int i = 0; i < n; ++i) t.rotation_factor[i] = sectionRotationFactor(t, t.beta_per_m[i]);

  // Centrifugal stiffening K_G = int N phi' phi'^T and tangential inertia load
  // p = int rho A (R + x) phi, with the axial force N(x) = rho A [R (L - x) + (L^2 - x^2) / 2].
  t.K_G.setZero(n, n);
  t.p_inertia.setZero(n);
  VecX phi(n), dphi(n);
  forEachQuadraturePoint(0.0, L, L, [&](double x_m, double weight_m) {
    evaluateModes(t, x_m, &phi, &dphi);
    const double axial_force = rhoA * (R * (L - x_m) + 0.5 * (L * L - x_m * x_m));
    t.K_G.noalias() += (weight_m * axial_force) * dphi * dphi.transpose();
    t.p_inertia += (weight_m * rhoA * (R + x_m)) * phi;
  });

  // Polar inertia of the undeformed tooth about the drum axis: int rho A (R + x)^2 dx.
  t.I0_kgm2 = rhoA * (R * R * L + R * L * L + L * L * L / 3);

  // Stations equally spaced on [0, L] (both ends exact), with phi and phi' there.
  const int n_stations = t.n_stations;
  t.station_x_m.resize(n_stations);
  t.phi_s.resize(n_stations, n);
  t.dphi_s.resize(n_stations, n);
  for (int s = 0; s < n_stations; ++s) {
    t.station_x_m[s] = L * (static_cast<double>(s) / (n_stations - 1));
    if (n == 0) continue;  // rigid tooth: no mode shapes (a row of a 0-column matrix is UB)
    evaluateModes(t, t.station_x_m[s], &phi, &dphi);
    t.phi_s.row(s) = phi.transpose();
    t.dphi_s.row(s) = dphi.transpose();
  }

  // Foreshortening matrices H(x_s) = int_0^{x_s} phi' phi'^T, accumulated station to station.
  t.H_s.assign(n_stations, MatX::Zero(n, n));
  for (int s = 1; s < n_stations; ++s) {
    MatX& H = t.H_s[s];
    H = t.H_s[s - 1];
    forEachQuadraturePoint(t.station_x_m[s - 1], t.station_x_m[s], L,
                           [&](double x_m, double weight_m) {
                             evaluateModes(t, x_m, &phi, &dphi);
                             H.noalias() += weight_m * dphi * dphi.transpose();
                           });
  }
  if (t.beam_model == ToothBeamModel::kLargeDeflection) compileLargeDeflection(&t);
}

void evaluateModes(const ToothModel& tooth, double x_m, VecX* phi, VecX* dphi) {
  const int n = tooth.n_modes;
  // resize() only allocates when the size changes, so repeated calls are allocation-free.
  phi->resize(n);
  dphi->resize(n);
  const double x = std::clamp(x_m, 0.0, tooth.length_m);
  const auto& half_one_minus_sigma = halfOneMinusSigmaTable();
  for (int i = 0; i < n; ++i) {
    // One exponential per mode: e^z and e^-z = 1 / e^z, with z = beta x <= beta L ~ 36.
    const double beta = tooth.beta_per_m[i];
    const double z = beta * x;
    const double exp_z = std::exp(z);
    const double exp_minus_z = 1.0 / exp_z;
    const double cos_z = std::cos(z);
    const double sin_z = std::sin(z);
    const double sigma = tooth.sigma[i];
    const double a = half_one_minus_sigma[i];  // (1 - sigma) / 2
    const double b = 0.5 * (1.0 + sigma);      // (1 + sigma) / 2

    // phi / C      = cosh z - sigma sinh z - cos z + sigma sin z
    // phi' / (C beta) = sinh z - sigma cosh z + sin z + sigma cos z
    (*phi)[i] = tooth.norm_C[i] * (a * exp_z + b * exp_minus_z - cos_z + sigma * sin_z);
    (*dphi)[i] = tooth.norm_C[i] * beta * (a * exp_z - b * exp_minus_z + sin_z + sigma * cos_z);
  }
}

void evaluateModeCurvatures(const ToothModel& tooth, double x_m, VecX* ddphi) {
  const int n = tooth.n_modes;
  ddphi->resize(n);
  const double x = std::clamp(x_m, 0.0, tooth.length_m);
  const auto& half_one_minus_sigma = halfOneMinusSigmaTable();
  for (int i = 0; i < n; ++i) {
    // phi'' / (C beta^2) = cosh z - sigma sinh z + cos z - sigma sin z, cancellation-free.
    const double beta = tooth.beta_per_m[i];
    const double z = beta * x;
    const double exp_z = std::exp(z);
    const double sigma = tooth.sigma[i];
    const double a = half_one_minus_sigma[i];
    const double b = 0.5 * (1.0 + sigma);
    (*ddphi)[i] =
        tooth.norm_C[i] * beta * beta * (a * exp_z + b / exp_z + std::cos(z) - sigma * std::sin(z));
  }
}

void interpolateH(const ToothModel& tooth, double x_m, MatX* H) {
  const VecX& xs = tooth.station_x_m;
  const int last = static_cast<int>(xs.size()) - 1;
  const double x = std::clamp(x_m, 0.0, tooth.length_m);

  // Interval [x_s, x_{s+1}] holding x: guess from the equal spacing, then correct against the
  // stored station positions so that x == x_s gives weight exactly 0 on the next station.
  int s = std::clamp(static_cast<int>(x / tooth.length_m * last), 0, last - 1);
  while (s > 0 && x < xs[s]) --s;
  while (s < last - 1 && x >= xs[s + 1]) ++s;

  // Linear blend of the two neighbouring station matrices.
  const double t = (x - xs[s]) / (xs[s + 1] - xs[s]);
  *H = (1.0 - t) * tooth.H_s[s] + t * tooth.H_s[s + 1];
}

namespace {

// Cubic Hermite shape functions of a beam element of length h at s in [0, 1]: values N,
// slopes dN/dx and curvatures d2N/dx2, for the element dofs (w_a, w'_a, w_b, w'_b).
void hermiteShapes(double s, double h, Eigen::Vector4d* N, Eigen::Vector4d* dN,
                   Eigen::Vector4d* ddN) {
  const double s2 = s * s, s3 = s2 * s;
  *N << 1 - 3 * s2 + 2 * s3, h * (s - 2 * s2 + s3), 3 * s2 - 2 * s3, h * (s3 - s2);
  *dN << (-6 * s + 6 * s2) / h, 1 - 4 * s + 3 * s2, (6 * s - 6 * s2) / h, 3 * s2 - 2 * s;
  *ddN << (-6 + 12 * s) / (h * h), (-4 + 6 * s) / h, (6 - 12 * s) / (h * h), (6 * s - 2) / h;
}

// Stiffness of the clamped-free rotating beam on n_el equal Hermite elements, root dofs
// removed: dofs (w_1, w'_1, ..., w_n, w'_n) [N/m, N, N m].
MatX rotatingBeamStiffness(const ToothModel& t, double R, double omega_radps, int n_el) {
  const double L = t.length_m, h = L / n_el;
  const double EI = t.youngs_modulus_Pa * t.second_moment_m4, rhoA = t.mass_per_length_kgpm;
  const double w2 = omega_radps * omega_radps;
  // 4-point Gauss-Legendre on [0, 1]: exact for the degree-6 integrands below.
  constexpr double kNode[4] = {0.06943184420297371, 0.33000947820757187, 0.66999052179242813,
                               0.93056815579702629};
  constexpr double kWeight[4] = {0.17392742256872693, 0.32607257743127307, 0.32607257743127307,
                                 0.17392742256872693};
  const int n_full = 2 * (n_el + 1);
  MatX K = MatX::Zero(n_full, n_full);
  Eigen::Vector4d N, dN, ddN;
  for (int e = 0; e < n_el; ++e) {
    Eigen::Matrix4d Ke = Eigen::Matrix4d::Zero();
    for (int g = 0; g < 4; ++g) {
      hermiteShapes(kNode[g], h, &N, &dN, &ddN);
      const double x = (e + kNode[g]) * h;
      const double axial_N = rhoA * w2 * (R * (L - x) + 0.5 * (L * L - x * x));
      Ke += kWeight[g] * h *
            (EI * ddN * ddN.transpose() + axial_N * dN * dN.transpose() -
             rhoA * w2 * N * N.transpose());
    }
    K.block<4, 4>(2 * e, 2 * e) += Ke;
  }
  return K.bottomRightCorner(n_full - 2, n_full - 2);
}

}  // namespace

StationFlexibility staticFlexibility(const ToothModel& tooth, double drum_radius_m,
                                     double omega_radps, int n_points, int n_elements) {
  // Element count a multiple of the point intervals, so that every point is a node.
  const int per = n_elements > 0 ? std::max(1, n_elements / (n_points - 1))
                                 : (256 + n_points - 2) / (n_points - 1);
  const int n_el = per * (n_points - 1);
  const Eigen::PartialPivLU<MatX> lu(
      rotatingBeamStiffness(tooth, drum_radius_m, omega_radps, n_el));
  StationFlexibility f;
  f.ww.setZero(n_points);
  f.wt.setZero(n_points);
  f.tt.setZero(n_points);
  VecX load = VecX::Zero(2 * n_el);
  for (int s = 1; s < n_points; ++s) {
    const int dof = 2 * (s * per - 1);  // w of node s * per (node 0, the root, is removed)
    load.setZero();
    load[dof] = 1.0;
    const VecX under_force = lu.solve(load);
    load.setZero();
    load[dof + 1] = 1.0;
    const VecX under_couple = lu.solve(load);
    f.ww[s] = under_force[dof];
    f.wt[s] = 0.5 * (under_force[dof + 1] + under_couple[dof]);  // equal by reciprocity
    f.tt[s] = under_couple[dof + 1];
  }
  return f;
}

StationFlexibility modalFlexibility(const ToothModel& tooth, double omega_radps, int n_points) {
  StationFlexibility f;
  f.ww.setZero(n_points);
  f.wt.setZero(n_points);
  f.tt.setZero(n_points);
  if (tooth.n_modes == 0) return f;
  const Eigen::PartialPivLU<MatX> lu(toothStiffness(tooth, omega_radps));
  VecX phi, dphi;
  for (int s = 0; s < n_points; ++s) {
    evaluateModes(tooth, tooth.length_m * s / (n_points - 1), &phi, &dphi);
    const VecX k_phi = lu.solve(phi), k_dphi = lu.solve(dphi);
    f.ww[s] = phi.dot(k_phi);
    f.wt[s] = 0.5 * (phi.dot(k_dphi) + dphi.dot(k_phi));
    f.tt[s] = dphi.dot(k_dphi);
  }
  return f;
}

StationFlexibility residualFlexibility(const ToothModel& tooth, double drum_radius_m,
                                       double omega_radps) {
  const int n_pt = kResidualPoints;
  StationFlexibility r;
  if (tooth.n_modes == 0) {
    r.ww.setZero(n_pt);
    r.wt.setZero(n_pt);
    r.tt.setZero(n_pt);
    return r;
  }
  const StationFlexibility exact = staticFlexibility(tooth, drum_radius_m, omega_radps, n_pt);
  const StationFlexibility modal = modalFlexibility(tooth, omega_radps, n_pt);
  r.ww = exact.ww - modal.ww;
  r.wt = exact.wt - modal.wt;
  r.tt = exact.tt - modal.tt;
  // Rounding can leave a block slightly indefinite where the modes capture nearly everything
  // (the root): clamp to the nearest positive semidefinite block.
  for (int s = 0; s < n_pt; ++s) {
    r.ww[s] = std::max(r.ww[s], 0.0);
    r.tt[s] = std::max(r.tt[s], 0.0);
    const double limit = std::sqrt(r.ww[s] * r.tt[s]);
    r.wt[s] = std::clamp(r.wt[s], -limit, limit);
  }
  return r;
}

void compileResidual(double drum_radius_m, double omega_radps, ToothModel* tooth) {
  ToothModel& t = *tooth;
  StationFlexibility r;
  if (t.static_correction) {
    r = residualFlexibility(t, drum_radius_m, omega_radps);
  } else {
    r.ww = r.wt = r.tt = VecX::Zero(kResidualPoints);
  }
  t.residual_omega_radps = omega_radps;
  t.residual_ww = r.ww;
  t.residual_wt = r.wt;
  t.residual_tt = r.tt;
  // The truncated modes start at omega_{n+1}; a change of Omega^2 by 1e-3 of its square moves
  // their static flexibility by about 1e-3.
  const double EI = t.youngs_modulus_Pa * t.second_moment_m4;
  t.residual_speed_window_radps2 = 1e-3 * std::pow(cantileverBetaL(t.n_modes), 4) * EI /
                                   (t.mass_per_length_kgpm * std::pow(t.length_m, 4));
}

double residualAt(const VecX& table, double length_m, double x_m) {
  const int last = static_cast<int>(table.size()) - 1;
  const double u = std::clamp(x_m / length_m, 0.0, 1.0) * last;
  const int s = std::min(static_cast<int>(u), last - 1);
  const double f = u - s;
  return (1 - f) * table[s] + f * table[s + 1];
}

MatX toothStiffness(const ToothModel& tooth, double omega_radps) {
  const int n = tooth.n_modes;
  const double omega_sq = omega_radps * omega_radps;
  MatX K = omega_sq * (tooth.K_G - MatX::Identity(n, n));
  K.diagonal() += tooth.omega0_sq;
  return K;
}

VecX toothFrequenciesHz(const ToothModel& tooth, double omega_radps) {
  if (tooth.n_modes == 0) return VecX();
  // Eigenvalues of the symmetric stiffness (identity modal mass) are omega^2, ascending; a
  // negative one (rotational softening instability) is reported as 0 Hz.
  const Eigen::SelfAdjointEigenSolver<MatX> solver(toothStiffness(tooth, omega_radps),
                                                   Eigen::EigenvaluesOnly);
  return solver.eigenvalues().cwiseMax(0.0).cwiseSqrt() / (2 * kPi);
}

namespace internal {

bool buildToothPropagator(const Model& m, int tooth, double omega_radps, ToothPropagator* prop) {
  const ToothModel& tm = m.teeth[tooth];
  const int n = tm.n_modes;
  // The large-deflection rod is nonlinear: always integrated.
  if (tm.beam_model == ToothBeamModel::kLargeDeflection) return prop->valid = false;
  if (prop->omega_radps == omega_radps && prop->n_modes == n) return prop->valid;
  prop->omega_radps = omega_radps;
  prop->n_modes = n;
  prop->valid = false;
  if (n == 0) return false;
  // State matrix of the free tooth, as smoothForces forms its acceleration (unit modal mass),
  // in balanced coordinates y_s = diag(s) y with s = [sqrt|S_ii|; 1]: the entries of A grow
  // with omega_i^2 (~1e10 for a fourth nylon mode), those of A_s only with omega_i, which keeps
  // its eigenvectors well conditioned.
  const int n2 = 2 * n;
  const MatX S = toothStiffness(tm, omega_radps);
  VecX s = VecX::Ones(n2);
  for (int i = 0; i < n; ++i) s[i] = std::sqrt(std::max(std::abs(S(i, i)), 1.0));
  MatX A = MatX::Zero(n2, n2);
  A.topRightCorner(n, n).setIdentity();
  A.bottomLeftCorner(n, n) = -S;
  A.bottomRightCorner(n, n).diagonal() = -tm.damping_coeff;
  prop->c.resize(n2);
  prop->valid = decomposeStateMatrix(A, s, &prop->lambda, &prop->V, &prop->V_inv);
  return prop->valid;
}

void propagateTooth(ToothPropagator* prop, double h_s, const Eigen::Ref<const VecX>& q0,
                    const Eigen::Ref<const VecX>& qd0, Eigen::Ref<VecX> q1, Eigen::Ref<VecX> qd1) {
  const ToothPropagator& p = *prop;
  modalAmplitudes(p.V_inv, p.n_modes, q0, qd0, prop->c);
  modalEvaluate(p.lambda, p.V, p.n_modes, h_s, prop->c, prop->c, q1, qd1);
}

}  // namespace internal

}  // namespace threshing_sim
