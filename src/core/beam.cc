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
#include <memory>
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

// Radians of the fastest integrand (phi_n'^2, which turns at 2 beta_n) per sub-interval: the
// 8-point rule integrates it to ~1e-14 at 2.27 rad (176 sub-intervals per length for 64 modes).
constexpr double kRadiansPerSubinterval = 2.267;

// Sub-intervals per tooth length for the K_G, p and H integrals of a tooth whose highest
// retained mode has beta L = beta_L_max: proportional to it, so that few modes cost few points.
int subintervalsPerLength(double beta_L_max) {
  return std::max(1, static_cast<int>(std::ceil(2.0 * beta_L_max / kRadiansPerSubinterval)));
}

// Calls add(x, weight) at the nodes of a composite Gauss-Legendre rule on [a, b]; the number of
// sub-intervals is proportional to (b - a) / length_m so any sub-range is integrated as finely
// as the whole tooth (n_per_length sub-intervals per length; the 1e-9 keeps a rounding excess on
// L / n_stations from adding one).
template <typename AddFn>
void forEachQuadraturePoint(double a_m, double b_m, double length_m, int n_per_length, AddFn add) {
  const int n_sub =
      std::max(1, static_cast<int>(std::ceil(n_per_length * (b_m - a_m) / length_m - 1e-9)));
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

// (1 - sigma_i) / 2 depends only on the mode index, so it is tabulated once for all teeth (for a
// tooth that compileTooth has not given its own, ToothModel::half_one_minus_sigma).
const std::array<double, kMaxModes>& halfOneMinusSigmaTable() {
  static const std::array<double, kMaxModes> table = [] {
    std::array<double, kMaxModes> t{};
    for (int i = 0; i < kMaxModes; ++i) t[i] = halfOneMinusSigma(cantileverBetaL(i));
    return t;
  }();
  return table;
}

// The tooth's (1 - sigma_i) / 2 (compiled: its n modes only), else the table of all modes.
const double* halfOneMinusSigmaOf(const ToothModel& tooth) {
  if (tooth.half_one_minus_sigma.size() >= tooth.n_modes) return tooth.half_one_minus_sigma.data();
  return halfOneMinusSigmaTable().data();
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
  if (!(tooth.quasi_static_speedup >= 1.0))
    throwInvalid("tooth.quasi_static_speedup", "must be >= 1", tooth.quasi_static_speedup);
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

namespace {

// The terms of mode i at z = beta x whose combinations give phi and its derivatives in the
// cancellation-free form: cosh z - sigma sinh z = a e^z + b e^-z with a = (1 - sigma) / 2
// (tabulated to full relative precision) and b = (1 + sigma) / 2. One exponential, one sine and
// one cosine per mode (z = beta x <= beta L ~ 200).
struct ModeTerms {
  double exp_z, exp_minus_z, cos_z, sin_z;  // e^z, e^-z, cos z, sin z [-]
  double a, b, sigma;                       // (1 - sigma) / 2, (1 + sigma) / 2, sigma [-]
};

ModeTerms modeTerms(const ToothModel& tooth, int i, double x_m,
                    const double* half_one_minus_sigma) {
  const double z = tooth.beta_per_m[i] * x_m;
  ModeTerms m;
  m.exp_z = std::exp(z);
  m.exp_minus_z = 1.0 / m.exp_z;
  m.cos_z = std::cos(z);
  m.sin_z = std::sin(z);
  m.sigma = tooth.sigma[i];
  m.a = half_one_minus_sigma[i];
  m.b = 0.5 * (1.0 + m.sigma);
  return m;
}

// e^d, e^-d, cos d, sin d of an angle d = beta dx: the step of the addition theorems.
struct StepTerms {
  double exp_d, exp_minus_d, cos_d, sin_d;
};

StepTerms stepTerms(double d) {
  StepTerms s;
  s.exp_d = std::exp(d);
  s.exp_minus_d = 1.0 / s.exp_d;
  s.cos_d = std::cos(d);
  s.sin_d = std::sin(d);
  return s;
}

// The terms at z + d from those at z: e^(z+d) = e^z e^d, cos(z+d) = cos z cos d - sin z sin d,
// sin(z+d) = sin z cos d + cos z sin d (relative rounding ~1e-16 per step).
ModeTerms advanced(const ModeTerms& m, const StepTerms& d) {
  ModeTerms r = m;
  r.exp_z = m.exp_z * d.exp_d;
  r.exp_minus_z = m.exp_minus_z * d.exp_minus_d;
  r.cos_z = m.cos_z * d.cos_d - m.sin_z * d.sin_d;
  r.sin_z = m.sin_z * d.cos_d + m.cos_z * d.sin_d;
  return r;
}

// Centrifugal stiffening K_G = int N phi' phi'^T, tangential inertia load p = int rho A (R + x) phi
// (axial force N(x) = rho A [R (L - x) + (L^2 - x^2) / 2]) and the foreshortening matrices
// H(x_s) = int_0^{x_s} phi' phi'^T, by one composite rule over the station intervals (each
// point's mode shapes serve all three). Needs the modal constants and stations.
void integrateModes(double R, ToothModel* tooth) {
  ToothModel& t = *tooth;
  const int n = t.n_modes;
  const double L = t.length_m, rhoA = t.mass_per_length_kgpm;
  t.K_G.setZero(n, n);
  t.p_inertia.setZero(n);
  t.H_s.assign(t.n_stations, MatX::Zero(n, n));
  if (n == 0) return;
  const int n_per_length = subintervalsPerLength(t.beta_per_m[n - 1] * L);
  // The stations are equally spaced, so every station interval holds the same rule: the modes'
  // exponential, sine and cosine at the rule's offsets from the interval's start are computed
  // once (nominal interval L / (n_stations - 1)), and a point's terms follow from its interval
  // start's by the addition theorems (advanced): one exponential, sine and cosine per mode and
  // station instead of per quadrature point.
  const double nominal_m = L / (t.n_stations - 1);
  std::vector<StepTerms> offsets;
  forEachQuadraturePoint(0.0, nominal_m, L, n_per_length, [&](double x_m, double) {
    for (int i = 0; i < n; ++i) offsets.push_back(stepTerms(t.beta_per_m[i] * x_m));
  });
  const double* table = halfOneMinusSigmaOf(t);
  std::array<ModeTerms, kMaxModes> start;
  std::array<double, kMaxModes> phi, dphi;
  // K_G and H are symmetric: their lower triangles are summed, then mirrored.
  double* K_G = t.K_G.data();
  for (int s = 1; s < t.n_stations; ++s) {
    MatX& H_matrix = t.H_s[s];
    H_matrix = t.H_s[s - 1];
    double* H = H_matrix.data();
    for (int i = 0; i < n; ++i) start[i] = modeTerms(t, i, t.station_x_m[s - 1], table);
    size_t point = 0;
    forEachQuadraturePoint(
        t.station_x_m[s - 1], t.station_x_m[s], L, n_per_length, [&](double x_m, double weight_m) {
          // (A rounding that gave this interval another sub-interval count: exact terms.)
          const bool nominal = (point + 1) * n <= offsets.size();
          for (int i = 0; i < n; ++i) {
            const ModeTerms m =
                nominal ? advanced(start[i], offsets[point * n + i]) : modeTerms(t, i, x_m, table);
            phi[i] =
                t.norm_C[i] * (m.a * m.exp_z + m.b * m.exp_minus_z - m.cos_z + m.sigma * m.sin_z);
            dphi[i] = t.norm_C[i] * t.beta_per_m[i] *
                      (m.a * m.exp_z - m.b * m.exp_minus_z + m.sin_z + m.sigma * m.cos_z);
          }
          ++point;
          const double axial = rhoA * (R * (L - x_m) + 0.5 * (L * L - x_m * x_m));
          const double w_K = weight_m * axial, w_p = weight_m * rhoA * (R + x_m);
          for (int b = 0; b < n; ++b) {
            for (int a = b; a < n; ++a) {
              const double outer = dphi[a] * dphi[b];
              H[a + b * n] += weight_m * outer;
              K_G[a + b * n] += w_K * outer;
            }
            t.p_inertia[b] += w_p * phi[b];
          }
        });
    for (int b = 0; b < n; ++b)
      for (int a = b + 1; a < n; ++a) H[b + a * n] = H[a + b * n];
  }
  for (int b = 0; b < n; ++b)
    for (int a = b + 1; a < n; ++a) K_G[b + a * n] = K_G[a + b * n];
}

}  // namespace

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
  t.half_one_minus_sigma.resize(n);
  for (int i = 0; i < n; ++i) {
    const double beta_L = cantileverBetaL(i);
    t.half_one_minus_sigma[i] = halfOneMinusSigma(beta_L);
    t.beta_per_m[i] = beta_L / L;
    t.sigma[i] = (std::cosh(beta_L) + std::cos(beta_L)) / (std::sinh(beta_L) + std::sin(beta_L));
    t.norm_C[i] = 1.0 / std::sqrt(rhoA * L);
    t.omega0_sq[i] = std::pow(beta_L, 4) * EI / (rhoA * std::pow(L, 4));
    if (t.quasi_static_from_mode > 0 && i >= t.quasi_static_from_mode) {
      // Shape times s, omega^2 times s^2: phi phi^T / omega^2 kept, modal mass over s^2.
      t.norm_C[i] *= t.quasi_static_speedup;
      t.omega0_sq[i] *= t.quasi_static_speedup * t.quasi_static_speedup;
    }
    t.damping_coeff[i] = 2 * t.damping_ratio * std::sqrt(t.omega0_sq[i]);
  }
  t.rotation_factor.resize(n);
  for (int i = 0; i < n; ++i) t.rotation_factor[i] = sectionRotationFactor(t, t.beta_per_m[i]);

  // Polar inertia of the undeformed tooth about the drum axis: int rho A (R + x)^2 dx.
  t.I0_kgm2 = rhoA * (R * R * L + R * L * L + L * L * L / 3);

  // Stations equally spaced on [0, L] (both ends exact), with phi and phi' there.
  const int n_stations = t.n_stations;
  t.station_x_m.resize(n_stations);
  t.phi_s.resize(n_stations, n);
  t.dphi_s.resize(n_stations, n);
  VecX phi(n), dphi(n);
  for (int s = 0; s < n_stations; ++s) {
    t.station_x_m[s] = L * (static_cast<double>(s) / (n_stations - 1));
    if (n == 0) continue;  // rigid tooth: no mode shapes (a row of a 0-column matrix is UB)
    evaluateModes(t, t.station_x_m[s], &phi, &dphi);
    t.phi_s.row(s) = phi.transpose();
    t.dphi_s.row(s) = dphi.transpose();
  }
  integrateModes(R, &t);
  tabulateModes(&t);
  if (t.beam_model == ToothBeamModel::kLargeDeflection) compileLargeDeflection(&t);
}

void evaluateModes(const ToothModel& tooth, double x_m, VecX* phi, VecX* dphi) {
  const int n = tooth.n_modes;
  const double* table = halfOneMinusSigmaOf(tooth);
  // resize() only allocates when the size changes, so repeated calls are allocation-free.
  phi->resize(n);
  dphi->resize(n);
  const double x = std::clamp(x_m, 0.0, tooth.length_m);
  for (int i = 0; i < n; ++i) {
    const ModeTerms t = modeTerms(tooth, i, x, table);
    // phi / C         = cosh z - sigma sinh z - cos z + sigma sin z
    // phi' / (C beta) = sinh z - sigma cosh z + sin z + sigma cos z
    (*phi)[i] =
        tooth.norm_C[i] * (t.a * t.exp_z + t.b * t.exp_minus_z - t.cos_z + t.sigma * t.sin_z);
    (*dphi)[i] = tooth.norm_C[i] * tooth.beta_per_m[i] *
                 (t.a * t.exp_z - t.b * t.exp_minus_z + t.sin_z + t.sigma * t.cos_z);
  }
}

void evaluateModesOnGrid(const ToothModel& tooth, int n_points, MatX* phi, MatX* dphi) {
  const int n = tooth.n_modes;
  phi->resize(n_points, n);
  dphi->resize(n_points, n);
  if (n == 0) return;
  constexpr int kExactEvery = 8;  // points between exact evaluations
  const double* table = halfOneMinusSigmaOf(tooth);
  const double L = tooth.length_m, dx_m = n_points > 1 ? L / (n_points - 1) : 0.0;
  std::array<StepTerms, kMaxModes> step;
  for (int i = 0; i < n; ++i) step[i] = stepTerms(tooth.beta_per_m[i] * dx_m);
  std::array<ModeTerms, kMaxModes> terms;
  for (int s = 0; s < n_points; ++s) {
    for (int i = 0; i < n; ++i) {
      terms[i] = s % kExactEvery == 0
                     ? modeTerms(tooth, i, n_points > 1 ? L * s / (n_points - 1) : 0.0, table)
                     : advanced(terms[i], step[i]);
      const ModeTerms& t = terms[i];
      (*phi)(s, i) =
          tooth.norm_C[i] * (t.a * t.exp_z + t.b * t.exp_minus_z - t.cos_z + t.sigma * t.sin_z);
      (*dphi)(s, i) = tooth.norm_C[i] * tooth.beta_per_m[i] *
                      (t.a * t.exp_z - t.b * t.exp_minus_z + t.sin_z + t.sigma * t.cos_z);
    }
  }
}

void evaluateModeCurvatures(const ToothModel& tooth, double x_m, VecX* ddphi) {
  const int n = tooth.n_modes;
  const double* table = halfOneMinusSigmaOf(tooth);
  ddphi->resize(n);
  const double x = std::clamp(x_m, 0.0, tooth.length_m);
  for (int i = 0; i < n; ++i) {
    // phi'' / (C beta^2) = cosh z - sigma sinh z + cos z - sigma sin z.
    const ModeTerms t = modeTerms(tooth, i, x, table);
    const double beta = tooth.beta_per_m[i];
    (*ddphi)[i] = tooth.norm_C[i] * beta * beta *
                  (t.a * t.exp_z + t.b * t.exp_minus_z + t.cos_z - t.sigma * t.sin_z);
  }
}

namespace {

// phi, phi', phi'', phi''' of mode i (of n) from its terms, into d[k * n + i]
// [1/(sqrt(kg) m^k)].
void modeDerivatives(const ToothModel& tooth, int i, const ModeTerms& t, double* d) {
  const int n = tooth.n_modes;
  const double beta = tooth.beta_per_m[i];
  const double c0 = tooth.norm_C[i], c1 = c0 * beta, c2 = c1 * beta, c3 = c2 * beta;
  const double cosh_part = t.a * t.exp_z + t.b * t.exp_minus_z;  // cosh z - sigma sinh z
  const double sinh_part = t.a * t.exp_z - t.b * t.exp_minus_z;  // sinh z - sigma cosh z
  d[i] = c0 * (cosh_part - t.cos_z + t.sigma * t.sin_z);
  d[n + i] = c1 * (sinh_part + t.sin_z + t.sigma * t.cos_z);
  d[2 * n + i] = c2 * (cosh_part + t.cos_z - t.sigma * t.sin_z);
  d[3 * n + i] = c3 * (sinh_part - t.sin_z - t.sigma * t.cos_z);
}

// Quintic Hermite basis on one table interval of length h at s in [0, 1]: weights of
// (f, f', f'') at its start (w[0..2]) and end (w[3..5]) for the value (w) and for the
// x-derivative (dw).
struct QuinticHermite {
  double w[6], dw[6];
  QuinticHermite(double s, double h) {
    const double s2 = s * s, s3 = s2 * s, s4 = s3 * s, s5 = s4 * s;
    const double h2 = h * h;
    w[0] = 1 - 10 * s3 + 15 * s4 - 6 * s5;
    w[1] = h * (s - 6 * s3 + 8 * s4 - 3 * s5);
    w[2] = 0.5 * h2 * (s2 - 3 * s3 + 3 * s4 - s5);
    w[3] = 10 * s3 - 15 * s4 + 6 * s5;
    w[4] = h * (-4 * s3 + 7 * s4 - 3 * s5);
    w[5] = 0.5 * h2 * (s3 - 2 * s4 + s5);
    dw[0] = (-30 * s2 + 60 * s3 - 30 * s4) / h;
    dw[1] = 1 - 18 * s2 + 32 * s3 - 15 * s4;
    dw[2] = 0.5 * h * (2 * s - 9 * s2 + 12 * s3 - 5 * s4);
    dw[3] = -dw[0];
    dw[4] = -12 * s2 + 28 * s3 - 15 * s4;
    dw[5] = 0.5 * h * (3 * s2 - 8 * s3 + 5 * s4);
  }
};

}  // namespace

void tabulateModes(ToothModel* tooth) {
  ToothModel& t = *tooth;
  const int n = t.n_modes;
  t.mode_table.reset();
  t.beta4_per_m4.resize(n);
  t.ddphi_bound.setZero(n);
  t.mode_table_intervals = 0;
  t.mode_table_dx_m = 0;
  if (n == 0) return;
  for (int i = 0; i < n; ++i) t.beta4_per_m4[i] = std::pow(t.beta_per_m[i], 4);
  // beta_n h <= 1 / kModeTablePointsPerRadian, rounded up to whole station intervals.
  const int per_station = t.n_stations - 1;
  const double needed = kModeTablePointsPerRadian * t.beta_per_m[n - 1] * t.length_m;
  const int intervals = per_station * static_cast<int>(std::ceil(needed / per_station));
  auto table = std::make_shared<std::vector<double>>(static_cast<size_t>(4) * n * (intervals + 1));
  // Each station's terms are evaluated exactly (at the stations' rounding, L (s / (n_s - 1)), so
  // that each station is a point bit for bit); the points between follow by the addition
  // theorems with the step beta_i L / intervals (22 steps per station interval for the default
  // 4 modes and 9 stations, 400 for 64 modes: ~1e-16 relative rounding each, below the quintic
  // interpolation's ~1e-12 even then; test_beam checks the table against the exact shapes).
  const int per = intervals / per_station;  // table intervals per station interval
  const double* half_one_minus_sigma = halfOneMinusSigmaOf(t);
  std::array<StepTerms, kMaxModes> step;
  for (int i = 0; i < n; ++i) step[i] = stepTerms(t.beta_per_m[i] * (t.length_m / intervals));
  std::array<ModeTerms, kMaxModes> terms;
  for (int j = 0; j <= intervals; ++j) {
    double* d = table->data() + static_cast<size_t>(4) * n * j;
    if (j % per == 0) {
      const double x_m = t.length_m * (static_cast<double>(j / per) / per_station);
      for (int i = 0; i < n; ++i) terms[i] = modeTerms(t, i, x_m, half_one_minus_sigma);
    } else {
      for (int i = 0; i < n; ++i) terms[i] = advanced(terms[i], step[i]);
    }
    for (int i = 0; i < n; ++i) modeDerivatives(t, i, terms[i], d);
  }
  t.ddphi_bound.setZero(n);
  for (int j = 0; j <= intervals; ++j)
    for (int i = 0; i < n; ++i)
      t.ddphi_bound[i] = std::max(
          t.ddphi_bound[i], 1.25 * std::abs((*table)[static_cast<size_t>(4) * n * j + 2 * n + i]));
  t.mode_table = std::move(table);
  t.mode_table_intervals = intervals;
  t.mode_table_dx_m = t.length_m / intervals;
}

void interpolateModes(const ToothModel& tooth, double x_m, double* phi, double* dphi,
                      double* ddphi) {
  const int n = tooth.n_modes;
  if (n == 0) return;
  const double x = std::clamp(x_m, 0.0, tooth.length_m);
  const int last = tooth.mode_table_intervals;
  const double u = x / tooth.mode_table_dx_m;
  const int j = std::clamp(static_cast<int>(u), 0, last - 1);
  const QuinticHermite hb(u - j, tooth.mode_table_dx_m);
  const double* p0 = tooth.mode_table->data() + static_cast<size_t>(4) * n * j;  // point j
  const double* p1 = p0 + 4 * n;                                                 // point j + 1
  for (int i = 0; i < n; ++i) {
    const double f0 = p0[i], d0 = p0[n + i], dd0 = p0[2 * n + i];
    const double f1 = p1[i], d1 = p1[n + i], dd1 = p1[2 * n + i];
    phi[i] =
        hb.w[0] * f0 + hb.w[1] * d0 + hb.w[2] * dd0 + hb.w[3] * f1 + hb.w[4] * d1 + hb.w[5] * dd1;
    dphi[i] = hb.dw[0] * f0 + hb.dw[1] * d0 + hb.dw[2] * dd0 + hb.dw[3] * f1 + hb.dw[4] * d1 +
              hb.dw[5] * dd1;
  }
  if (ddphi == nullptr) return;
  for (int i = 0; i < n; ++i) {
    const double b4 = tooth.beta4_per_m4[i];
    ddphi[i] = hb.w[0] * p0[2 * n + i] + hb.w[1] * p0[3 * n + i] + hb.w[2] * b4 * p0[i] +
               hb.w[3] * p1[2 * n + i] + hb.w[4] * p1[3 * n + i] + hb.w[5] * b4 * p1[i];
  }
}

namespace {

// The table interval holding x (as interpolateModes picks it) and the position u - j in it.
int tableInterval(const ToothModel& tooth, double x_m, double* s) {
  const double x = std::clamp(x_m, 0.0, tooth.length_m);
  const double u = x / tooth.mode_table_dx_m;
  const int j = std::clamp(static_cast<int>(u), 0, tooth.mode_table_intervals - 1);
  *s = u - j;
  return j;
}

// The contractions of table point j with q (DeflectionInterval::at).
void contractPoint(const ToothModel& tooth, const double* q, int j, double* at) {
  const int n = tooth.n_modes;
  const double* p = tooth.mode_table->data() + static_cast<size_t>(4) * n * j;
  for (int k = 0; k < 5; ++k) at[k] = 0.0;
  for (int i = 0; i < n; ++i) {
    at[0] += p[i] * q[i];
    at[1] += p[n + i] * q[i];
    at[2] += p[2 * n + i] * q[i];
    at[3] += p[3 * n + i] * q[i];
    at[4] += tooth.beta4_per_m4[i] * p[i] * q[i];
  }
}

}  // namespace

void interpolateDeflection(const ToothModel& tooth, const double* q, double x_m,
                           DeflectionInterval* interval, double* w, double* w1, double* w2) {
  if (tooth.n_modes == 0) {
    *w = *w1 = *w2 = 0.0;
    return;
  }
  double s = 0;
  const int j = tableInterval(tooth, x_m, &s);
  if (interval->j != j) {
    interval->j = j;
    contractPoint(tooth, q, j, interval->at[0]);
    contractPoint(tooth, q, j + 1, interval->at[1]);
  }
  const QuinticHermite hb(s, tooth.mode_table_dx_m);
  const double* a = interval->at[0];
  const double* b = interval->at[1];
  *w = hb.w[0] * a[0] + hb.w[1] * a[1] + hb.w[2] * a[2] + hb.w[3] * b[0] + hb.w[4] * b[1] +
       hb.w[5] * b[2];
  *w1 = hb.dw[0] * a[0] + hb.dw[1] * a[1] + hb.dw[2] * a[2] + hb.dw[3] * b[0] + hb.dw[4] * b[1] +
        hb.dw[5] * b[2];
  *w2 = hb.w[0] * a[2] + hb.w[1] * a[3] + hb.w[2] * a[4] + hb.w[3] * b[2] + hb.w[4] * b[3] +
        hb.w[5] * b[4];
}

void interpolateModes(const ToothModel& tooth, double x_m, VecX* phi, VecX* dphi) {
  phi->resize(tooth.n_modes);
  dphi->resize(tooth.n_modes);
  interpolateModes(tooth, x_m, phi->data(), dphi->data());
}

void interpolateModeCurvatures(const ToothModel& tooth, double x_m, VecX* ddphi) {
  const int n = tooth.n_modes;
  ddphi->resize(n);
  double phi[kMaxModes], dphi[kMaxModes];
  interpolateModes(tooth, x_m, phi, dphi, ddphi->data());
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
