// Asynchronous core: the exact propagator of an idle kernel on its pedicel, linearised about its
// hanging equilibrium, with the bounds that say where it may be used (pedicel_propagator.cc).
//
// A kernel on its pedicel touching nothing obeys y' = f(y), y = [c_x, c_y, psi, v_x, v_y, omega]
// (the law of pedicelForce in contact/smooth_forces.cc plus gravity). About its static
// equilibrium y_eq (f(y_eq) = 0), y' = A (y - y_eq) + n(y - y_eq), with n the second-order
// remainder. The closed form drops n: y(t) = y_eq + Re(V exp(Lambda t) V^-1 (y0 - y_eq)).
// Kernels of one class (same mass, inertia, attachment point, stem law and gravity) share one
// propagator; the anchor only translates the equilibrium, and so does the rest length, which
// may differ within a class by kRestLengthClassTolerance (relative): unstretched stems
// (rest_length: -1) get theirs from the initial positions, equal but for rounding. A longer stem
// moves the equilibrium along g by the difference, exactly; the state matrix changes by the
// relative difference (the stem's geometric stiffness T / len), negligible at 1e-9.
#pragma once

#include <complex>

#include "../internal.h"

namespace threshing_sim {
namespace internal {

using PedicelVec =
    Eigen::Matrix<double, 6, 1>;  // [c_x, c_y, psi, v_x, v_y, omega] [m, rad, m/s, rad/s]
using PedicelMat = Eigen::Matrix<double, 6, 6>;                  // a matrix over that state [mixed]
using PedicelModes = Eigen::Matrix<std::complex<double>, 6, 1>;  // modal amplitudes [mixed]
using PedicelModeMat = Eigen::Matrix<std::complex<double>, 6, 6>;  // modal matrices [mixed]

constexpr double kRestLengthClassTolerance = 1e-9;  // [-]

// The closed form of one kernel class.
struct PedicelPropagator {
  // --- the class: what the dynamics depend on ---
  double mass_kg = 0;                // m [kg]
  double inertia_kgm2 = 0;           // J [kg m^2]
  Vec2 p_KP_K = Vec2::Zero();        // attachment point, kernel frame [m]
  double stiffness_Npm = 0;          // k [N/m]
  double damping_Nspm = 0;           // c [N s/m]
  double rest_length_m = 0;          // l0 [m]
  double detachment_force_N = 0;     // break threshold [N]
  Vec2 gravity_mps2 = Vec2::Zero();  // g [m/s^2]
  // --- derived ---
  bool valid = false;          // equilibrium found, stable, diagonalisable [-]
  Vec2 p_AC_W = Vec2::Zero();  // equilibrium centre minus anchor, world [m]
  Vec2 down_W = Vec2::Zero();  // g / |g|: where a longer stem moves the equilibrium [-]
  double psi_eq_rad = 0;       // equilibrium angle [rad]
  PedicelModes lambda;         // eigenvalues of A [1/s]
  PedicelModeMat V;            // right eigenvectors, columns [mixed]
  PedicelModeMat V_inv;        // V^-1 [mixed]
  PedicelMat abs_V;            // |V_ji|: the envelope |y_j - y_eq,j| <= sum_i |V_ji||c_i| [mixed]
  PedicelVec inv_scale;        // 1 / amplitude scale per state (rho = max_j E_j / s_j) [1/unit]
  PedicelMat curvature[3];     // 1/2 |d^2 f_k / dy_i dy_j| of the rates k = 3..5 at y_eq
                               // (times the higher-order factor) [rate per unit^2]
  // Second-order error of state j per unit tolerance from modal amplitude products |c_a||c_b|
  // (column 6 a + b): bounded (non-resonant) part [per unit^2] and secular part [per unit^2 s].
  Eigen::Matrix<double, 6, 36> error_bounded;
  Eigen::Matrix<double, 6, 36> error_secular;
  PedicelVec force_slope;   // |dF/dy_j| at y_eq, column norms [N per unit of y_j]
  double force_eq_N = 0;    // |stem force| at y_eq [N]
  double min_period_s = 0;  // shortest modal period [s]
};

// The state's distance from equilibrium, in the closed form's terms.
struct PedicelAmplitude {
  PedicelModes c;                 // modal amplitudes V^-1 (y - y_eq) [mixed]
  PedicelVec envelope;            // E_j >= |y_j(t) - y_eq,j| for all t >= 0 [m, rad, m/s, rad/s]
  double rho = 0;                 // max_j E_j / s_j [-]
  double psi_branch_rad = 0;      // psi_eq + 2 pi n nearest the state's angle [rad]
  Vec2 p_WC_eq_W = Vec2::Zero();  // equilibrium centre, world [m]
};

// Builds the propagator of kernel k's class under gravity g (Newton on the static balance,
// analytic Jacobian, eigendecomposition, bounds). Allocates.
PedicelPropagator buildPedicelPropagator(const KernelModel& k, const Vec2& gravity_mps2);
// Whether kernel k under gravity g belongs to the class of p.
bool samePedicelClass(const PedicelPropagator& p, const KernelModel& k, const Vec2& gravity_mps2);
// Kernel k's state y relative to the equilibrium of its class (anchor of k).
PedicelAmplitude pedicelAmplitude(const PedicelPropagator& p, const KernelModel& k,
                                  const PedicelVec& y);
// Longest span over which the closed form from amplitude `a` stays within tolerance tol and
// the stem force stays below the detachment force: +inf, a finite span, or 0 (not usable).
double pedicelClosedFormSpan(const PedicelPropagator& p, const PedicelAmplitude& a, double tol);
// The state h_s after amplitude `a` by the closed form. Allocates nothing.
PedicelVec propagatePedicel(const PedicelPropagator& p, const PedicelAmplitude& a, double h_s);
// The analytic Jacobian of the kernel's pedicel dynamics f (accelerations in rows 3..5).
PedicelMat pedicelJacobian(const KernelModel& k, const PedicelVec& y);

// The stem force on the kernel [N] and its moment about the centre [N m] (the law of
// pedicelForce in contact/smooth_forces.cc). Inline: the numerical pedicel clock's right-hand side.
// cos_psi, sin_psi: the cosine and sine of the kernel's angle y[2].
inline Vec2 pedicelStemForce(const KernelModel& k, const PedicelVec& y, double cos_psi,
                             double sin_psi, double* moment_Nm) {
  const Vec2& p_KP_K = k.pedicel.p_KP_K;
  const Vec2 r(cos_psi * p_KP_K.x() - sin_psi * p_KP_K.y(),
               sin_psi * p_KP_K.x() + cos_psi * p_KP_K.y());
  const Vec2 v = y.segment<2>(3) + y[5] * Vec2(-r.y(), r.x());
  const Vec2 d = y.head<2>() + r - k.pedicel.p_WA_W;
  const double len = d.norm();
  if (len <= 0.0) {
    *moment_Nm = 0.0;
    return Vec2::Zero();
  }
  const Vec2 dir = d / len;
  const double tension = k.pedicel.stiffness_Npm * (len - k.pedicel.rest_length_m) +
                         k.pedicel.damping_Nspm * dir.dot(v);
  const Vec2 F = -tension * dir;
  *moment_Nm = r.x() * F.y() - r.y() * F.x();
  return F;
}

inline Vec2 pedicelStemForce(const KernelModel& k, const PedicelVec& y, double* moment_Nm) {
  return pedicelStemForce(k, y, std::cos(y[2]), std::sin(y[2]), moment_Nm);
}

// f(y): the kernel's rates on its pedicel under gravity g, with the cosine and sine of its
// angle y[2] given.
inline PedicelVec pedicelRates(const KernelModel& k, const Vec2& gravity_mps2,
                               const PedicelVec& y, double cos_psi, double sin_psi) {
  double moment = 0.0;
  const Vec2 F = pedicelStemForce(k, y, cos_psi, sin_psi, &moment);
  PedicelVec f;
  f.head<3>() = y.tail<3>();
  f.segment<2>(3) = gravity_mps2 + F / k.mass_kg;
  f[5] = moment / k.inertia_kgm2;
  return f;
}

// f(y): the kernel's rates on its pedicel under gravity g.
inline PedicelVec pedicelRates(const KernelModel& k, const Vec2& gravity_mps2,
                               const PedicelVec& y) {
  return pedicelRates(k, gravity_mps2, y, std::cos(y[2]), std::sin(y[2]));
}

}  // namespace internal
}  // namespace threshing_sim
