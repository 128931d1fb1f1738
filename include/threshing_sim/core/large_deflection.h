// threshing_sim core: a geometrically exact planar tooth (inextensible Kirchhoff rod) for
// large deflections, selected per tooth by `teeth.*.model: large_deflection`.
//
// The section angle along the rod is a Ritz sum theta(s) = sum_i q_i phi_i(s) with
// phi_i(s) = (1/L) int_0^s P_{i-1}(2 sigma / L - 1) d sigma (P: Legendre polynomials), so the
// clamp theta(0) = 0 holds for any q, the curvatures phi_i' are orthogonal and the elastic
// stiffness EI int phi_i' phi_j' ds is constant and diagonal. Positions are exact geometry,
// r(s) = b + int_0^s (cos theta, sin theta) d sigma in the tooth frame T (axes e1 along the
// undeformed tooth, e2 = J e1, origin on the drum axis, root at b), integrated by collocation:
// 8 intervals of 8 Gauss-Legendre nodes, with the integral inside an interval taken from the
// Lagrange interpolant of (cos, sin)(theta) on its nodes (spectral integration matrix). The
// rod's mass sits on the same 64 nodes (node weight rho A w_a), so the discrete system is a
// set of particles whose positions are exact functions of q: its mass matrix M(q), velocity
// terms, centrifugal, Coriolis and Euler loads follow from D'Alembert's principle without
// approximation, and the energy of the free rod is conserved exactly by its equations
//   M(q) q'' = -K q - D q' - sum_a m_a J_a^T [a_a + 2 Omega J v_a + dOmega/dt J r_a - Omega^2 r_a]
// (J_a = dr_a/dq, v_a = J_a q', a_a = dJ_a/dt q', all in the rotating tooth frame).
#pragma once

#include <Eigen/Core>

#include "threshing_sim/core/model.h"

namespace threshing_sim {

constexpr int kLdIntervals = 8;                    // collocation intervals along the rod [-]
constexpr int kLdGauss = 8;                        // Gauss nodes per interval [-]
constexpr int kLdNodes = kLdIntervals * kLdGauss;  // mass and collocation nodes [-]
constexpr int kLdMaxShapes = 12;                   // most Ritz shape functions (teeth.*.modes)
constexpr int kLdAutoShapes = 6;                   // shape functions of teeth.*.modes: auto

// 2 x n Jacobian of a point (dr/dq, tooth frame) [m/rad], n <= kLdMaxShapes.
using LdJac = Eigen::Matrix<double, 2, Eigen::Dynamic, 0, 2, kLdMaxShapes>;
// n x n matrix and n-vector with storage on the stack.
using LdMat = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, kLdMaxShapes, kLdMaxShapes>;
using LdVec = Eigen::Matrix<double, Eigen::Dynamic, 1, 0, kLdMaxShapes, 1>;

// Fills the large-deflection fields of a tooth whose section (area, I, rho A, root, axes) is
// already derived: nodes, node masses, shape values, stiffness and damping.
void compileLargeDeflection(ToothModel* tooth);

// Shape functions phi_i(s) [-] and their slopes phi_i'(s) [1/m] (n_modes values each).
void ldShapes(const ToothModel& tooth, double s_m, double* phi, double* dphi);

// The rod at one configuration q: node angles and the centreline and its Jacobian at the
// interval ends (tooth frame, drum origin).
struct LdConfig {
  int n = 0;                      // shape functions [-]
  double theta[kLdNodes];         // section angle at the nodes [rad]
  double cos_t[kLdNodes];         // its cosine [-]
  double sin_t[kLdNodes];         // its sine [-]
  Vec2 r_end[kLdIntervals + 1];   // r at the interval ends [m]
  LdJac J_end[kLdIntervals + 1];  // dr/dq there [m/rad]
};

// Computes the configuration of `tooth` at q (n_modes values) [rad].
void ldConfigure(const ToothModel& tooth, const double* q, LdConfig* cfg);

// Centreline point r(s) in the tooth frame [m]; optionally its tangent dr/ds [-], curvature
// vector d2r/ds2 [1/m] and Jacobian dr/dq [m/rad] (any may be null).
Vec2 ldPoint(const ToothModel& tooth, const LdConfig& cfg, double s_m, Vec2* r_s, Vec2* r_ss,
             LdJac* jac);

// Velocity v = dr/dt and frozen-velocity acceleration a = (dJ/dt) q' of the centreline point at
// s relative to the tooth frame, for rates qd [rad/s] ([m/s], [m/s^2]); and dv/ds [1/s].
void ldPointMotion(const ToothModel& tooth, const LdConfig& cfg, const double* qd, double s_m,
                   Vec2* v, Vec2* a, Vec2* v_s);

// The rod's dynamics at (cfg, qd) on a drum turning at omega with acceleration alpha: mass
// matrix M [kg m^2], generalised force f = -K q - D qd - inertial terms [N m] (without contacts),
// kinetic energy in the inertial frame [J] and angular momentum about the drum axis
// [kg m^2/s]. Any output may be null.
void ldDynamics(const ToothModel& tooth, const LdConfig& cfg, const double* q, const double* qd,
                double omega_radps, double alpha_radps2, LdMat* M, LdVec* f, double* kinetic_J,
                double* momentum_kgm2ps);

// Elastic energy 1/2 q^T K q [J].
double ldElasticEnergy(const ToothModel& tooth, const double* q);

// Static equilibrium of the non-rotating rod under a tip force P fixed in direction (tooth
// frame) [N], by Newton's method on K q = J(L)^T P from q = 0 (with load stepping). Returns
// the tip displacement from the undeformed tip (tooth frame) [m]; fills q if given. Returns
// NaN if Newton does not converge.
Vec2 ldStaticTipLoad(const ToothModel& tooth, const Vec2& P_T_N, VecX* q = nullptr);

}  // namespace threshing_sim
