// threshing_sim core: assumed-mode model of a clamped-free Euler-Bernoulli tooth on a drum.
//
// Modes are mass-normalised, int_0^L rho A phi_i phi_j dx = delta_ij, so the modal mass matrix
// is the identity. With drum speed Omega the bending equations are (docs/model.md §3)
//   q'' + D q' + [Lambda + Omega^2 (K_G - I)] q = -dOmega/dt p + Q.
#pragma once

#include "threshing_sim/core/model.h"

namespace threshing_sim {

// beta_i L of the i-th (0-based) clamped-free mode: 1.87510407, 4.69409113, ... [-]
double cantileverBetaL(int i);

// Fills the derived fields of `tooth` (section, modal constants, K_G, p, I0, stations,
// phi/dphi/H at the stations) for a root at distance drum_radius_m from the drum axis.
// Throws std::invalid_argument naming the field on a non-physical value.
void compileTooth(double drum_radius_m, ToothModel* tooth);

// Mode shapes at x in [0, L]: phi(x) [1/sqrt(kg)] and phi'(x) [1/(sqrt(kg) m)], each of size
// n_modes. Evaluated in a form that stays accurate for high modes (no cosh - cos cancellation).
void evaluateModes(const ToothModel& tooth, double x_m, VecX* phi, VecX* dphi);

// Second derivative phi''(x) [1/(sqrt(kg) m^2)] (bending moment EI phi'' q).
void evaluateModeCurvatures(const ToothModel& tooth, double x_m, VecX* ddphi);

// H(x) = int_0^x phi' phi'^T d xi (n x n) [1/(kg m)], linearly interpolated between stations.
void interpolateH(const ToothModel& tooth, double x_m, MatX* H);

// Stiffness matrix at drum speed Omega: Lambda + Omega^2 (K_G - I) [1/s^2].
MatX toothStiffness(const ToothModel& tooth, double omega_radps);

}  // namespace threshing_sim
