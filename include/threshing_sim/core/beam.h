// threshing_sim core: assumed-mode model of a clamped-free Euler-Bernoulli tooth on a drum.
//
// Modes are mass-normalised, int_0^L rho A phi_i phi_j dx = delta_ij, so the modal mass matrix
// is the identity. With drum speed Omega the bending equations are (docs/model.md §3)
//   q'' + D q' + [Lambda + Omega^2 (K_G - I)] q = -dOmega/dt p + Q.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <vector>

#include "threshing_sim/core/constants.h"
#include "threshing_sim/core/model.h"

namespace threshing_sim {

// Points x_j = L j / (kResidualPoints - 1) at which the residual flexibility is tabulated.
constexpr int kResidualPoints = 33;

// Quasi-static flexibility of a tooth at equally spaced points x_j = L j / (n - 1) for a
// transverse load at the same point (docs/model.md §9b): the deflection w and slope w'
// under a unit force and a unit couple (a load on w'): ww [m/N], wt = w under a couple = w'
// under a force [1/N], tt [1/(N m)].
struct StationFlexibility {
  VecX ww, wt, tt;  // one entry per point
};

// beta_i L of the i-th (0-based) clamped-free mode: 1.87510407, 4.69409113, ... [-]
double cantileverBetaL(int i);

// Section rotation per unit slope of a wave of number beta_per_m in the tooth (docs/model.md
// §9b): 1 / (1 + (E / kappa G) (I / A) beta^2) for shear-corrected sections, 1 for
// Euler-Bernoulli ones. Needs the tooth's area and second moment (compiled).
double sectionRotationFactor(const ToothModel& t, double beta_per_m);

// Fills the derived fields of `tooth` (section, modal constants, K_G, p, I0, stations,
// phi/dphi/H at the stations) for a root at distance drum_radius_m from the drum axis.
// Throws std::invalid_argument naming the field on a non-physical value.
void compileTooth(double drum_radius_m, ToothModel* tooth);

// Mode shapes at x in [0, L]: phi(x) [1/sqrt(kg)] and phi'(x) [1/(sqrt(kg) m)], each of size
// n_modes. Evaluated in a form that stays accurate for high modes (no cosh - cos cancellation).
void evaluateModes(const ToothModel& tooth, double x_m, VecX* phi, VecX* dphi);

// evaluateModes at the n_points points x_s = L s / (n_points - 1) into the rows of *phi and
// *dphi (n_points x n_modes): every 8th point evaluated exactly, those between by the addition
// theorems from it (relative rounding ~1e-16 per point; one exponential, sine and cosine per
// mode every 8 points).
void evaluateModesOnGrid(const ToothModel& tooth, int n_points, MatX* phi, MatX* dphi);

// Second derivative phi''(x) [1/(sqrt(kg) m^2)] (bending moment EI phi'' q).
void evaluateModeCurvatures(const ToothModel& tooth, double x_m, VecX* ddphi);

// Table points per radian of the highest mode's wave, 1 / (beta_n h): the quintic Hermite
// interpolation is then accurate to ~1.3e-12 of each mode's scale 2 C_i beta_i^k in value and
// curvature and to ~7e-11 in slope, whose error falls only as h^5 (measured over 1 to 64
// modes in test_beam; 12.5 points left the slope at 2.3e-10). 64 modes: 3200 intervals.
constexpr double kModeTablePointsPerRadian = 16.0;

// Fills the mode table of a tooth whose modal constants and stations are compiled
// (compileTooth calls it): an interval count that is a multiple of the station intervals
// (every station is a table point) with beta_n L / intervals <= 1 / kModeTablePointsPerRadian.
void tabulateModes(ToothModel* tooth);

// phi(x) [1/sqrt(kg)] and phi'(x) [1/(sqrt(kg) m)] as evaluateModes gives them, from the mode
// table without a transcendental function: phi is the quintic Hermite interpolant of the
// table's phi, phi', phi'' and phi' is its exact derivative (so the slope is the derivative
// of the value, as the contact's power balance needs); both are continuous in x and exact to
// rounding at the table points. ddphi (may be null): phi''(x) [1/(sqrt(kg) m^2)], the quintic
// Hermite interpolant of phi'', phi''' and beta^4 phi. Arrays of n_modes entries.
void interpolateModes(const ToothModel& tooth, double x_m, double* phi, double* dphi,
                      double* ddphi = nullptr);
// The same into vectors (resized to n_modes; allocation-free when they have that size).
void interpolateModes(const ToothModel& tooth, double x_m, VecX* phi, VecX* dphi);
// phi''(x) from the table (as the ddphi of interpolateModes) [1/(sqrt(kg) m^2)].
void interpolateModeCurvatures(const ToothModel& tooth, double x_m, VecX* ddphi);

// One interval of the mode table contracted with the modal coordinates q: at its two points,
// phi . q, phi' . q, phi'' . q, phi''' . q and (beta^4 phi) . q [1/m^(k-1)] (interpolateDeflection
// fills it for the interval it needs and reuses it while the interval stays; q must not change).
struct DeflectionInterval {
  int j = -1;                 // the table interval [x_j, x_{j+1}] held (-1: none) [-]
  double at[2][5] = {{0.0}};  // the contractions at x_j and x_{j+1} [1/m^(k-1)]
};
// The deflection w(x) = phi(x) . q [m] and its derivatives w' [-] and w'' [1/m] from the mode
// table, equal to interpolateModes's phi, phi', phi'' dotted with q (to rounding) for the cost
// of one interval's contraction (5 dot products of n at each end, kept in *interval) and a
// few scalar operations per call. q: n_modes coordinates [sqrt(kg) m].
void interpolateDeflection(const ToothModel& tooth, const double* q, double x_m,
                           DeflectionInterval* interval, double* w, double* w1, double* w2);

// H(x) = int_0^x phi' phi'^T d xi (n x n) [1/(kg m)], linearly interpolated between stations.
void interpolateH(const ToothModel& tooth, double x_m, MatX* H);

// Exact static flexibility of the rotating cantilever at n_points equally spaced points, from
// EI w'''' - (N w')' - rho A Omega^2 w = load, clamped at x = 0, free at x = L (the operator of
// the modal equations, so the modal flexibility tends to it as modes are added), by cubic
// Hermite finite elements fine enough that it is converged to ~1e-9 (n_elements <= 0: the
// default, at least 256 elements). Needs the section fields of compileTooth.
StationFlexibility staticFlexibility(const ToothModel& tooth, double drum_radius_m,
                                     double omega_radps, int n_points, int n_elements = 0);

// staticFlexibility at many drum speeds of one tooth: the stiffness's bending and rotational (per
// Omega^2) bands are assembled once, each call combines, factors and inverts them (banded
// L D L^T, selected inversion, in long double).
class StaticFlexibilitySolver {
 public:
  StaticFlexibilitySolver(const ToothModel& tooth, double drum_radius_m, int n_points,
                          int n_elements = 0);
  StationFlexibility operator()(double omega_radps) const;

 private:
  int n_points_ = 0;                                  // points x_j [-]
  int per_ = 1;                                       // elements per point interval [-]
  long double h_m_ = 0;                               // element length [m]
  std::vector<std::array<long double, 4>> bending_;   // band of the bending stiffness [N/m]
  std::vector<std::array<long double, 4>> rotation_;  // band per Omega^2 [N s^2/m]
};

// The part of it that the n retained modes represent: Phi_n^T K_n^-1 Phi_n (K_n full, from
// toothStiffness), at the same points. Needs compileTooth.
StationFlexibility modalFlexibility(const ToothModel& tooth, double omega_radps, int n_points);

// Residual flexibility of the truncated modes (static minus modal, clamped so that each
// point's 2 x 2 block stays positive semidefinite) at drum speed omega_radps, at
// kResidualPoints points. Zero for a rigid tooth (n_modes = 0 means rigid, not "all modes
// truncated"). With a cut-off (ToothModel::residual_modes > n_modes) the modes up to
// residual_modes are subtracted: the slow truncated ones are in neither part. Needs compileTooth.
StationFlexibility residualFlexibility(const ToothModel& tooth, double drum_radius_m,
                                       double omega_radps);

// Rounding can leave a residual block slightly indefinite where the modes capture nearly
// everything (the root): clamps (ww, wt, tt) to the nearest positive semidefinite block.
inline void clampResidualBlock(double* ww, double* wt, double* tt) {
  *ww = std::max(*ww, 0.0);
  *tt = std::max(*tt, 0.0);
  const double limit = std::sqrt(*ww * *tt);
  *wt = std::clamp(*wt, -limit, limit);
}

// Fills the residual_* fields of a compiled tooth: the (unclamped) residual over Omega^2 in
// [0, max(speed_bound, |omega|)^2], at the Chebyshev-Lobatto nodes in Omega^2 of panels
// (residual_panels, residual_nodes_*) refined until the interpolant is within 1e-8 of the
// largest entry of the static flexibility at rest (or 10 x the static solve's rounding, if
// larger; residual_table_error: the estimate), and the tables at drum speed omega_radps
// interpolated from it (residualFlexibility to that tolerance, clamped point by point). Zeros and no panels without static correction or modes (src/core/residual_table.cc).
void compileResidual(double drum_radius_m, double omega_radps, double speed_bound_radps,
                     ToothModel* tooth);

// The residual flexibility block (ww [m/N], wt [1/N], tt [1/(N m)]) of a compiled tooth at
// material point x_m for drum speed omega_radps: the compiled tables at residual_omega_radps,
// else the interpolation in Omega^2 (clamped to the table's range), clamped to a positive
// semidefinite block at the two neighbouring points and blended linearly. Allocation-free.
void residualAtSpeed(const ToothModel& tooth, double omega_radps, double x_m, double* ww,
                     double* wt, double* tt);

// The entries first .. first + count - 1 of the ww table (w under a force at the same point
// [m/N], at the points of residualFlexibility) for drum speed omega_radps, read as
// residualAtSpeed reads them: the compiled table at residual_omega_radps, else each point
// interpolated in Omega^2 and clamped. Allocation-free.
void residualWwAtSpeed(const ToothModel& tooth, double omega_radps, int first, int count,
                       double* ww);

// The barycentric Lagrange basis ell[0..n_nodes) of the Chebyshev-Lobatto nodes
// x_j = cos(pi j / (n_nodes - 1)) at x in [-1, 1] (sums to 1; exact at the nodes).
void lobattoBasis(int n_nodes, double x, double* ell);

// A table at kResidualPoints equally spaced points on [0, length_m] (one of those above)
// linearly interpolated at x_m.
double residualAt(const VecX& table, double length_m, double x_m);

// Stiffness matrix at drum speed Omega: Lambda + Omega^2 (K_G - I) [1/s^2].
MatX toothStiffness(const ToothModel& tooth, double omega_radps);

}  // namespace threshing_sim
