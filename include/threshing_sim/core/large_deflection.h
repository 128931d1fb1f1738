// threshing_sim core: a geometrically exact planar tooth (inextensible Kirchhoff rod) for
// large deflections, selected per tooth by `teeth.*.model: large_deflection`.
//
// The section angle along the rod is a Ritz sum theta(s) = sum_i q_i phi_i(s) with
// phi_i(s) = (1/L) int_0^s P_{i-1}(2 sigma / L - 1) d sigma (P: Legendre polynomials), so the
// clamp theta(0) = 0 holds for any q, the curvatures phi_i' are orthogonal and the elastic
// stiffness EI int phi_i' phi_j' ds is constant and diagonal. Positions are exact geometry,
// r(s) = b + int_0^s (cos theta, sin theta) d sigma in the tooth frame T (axes e1 along the
// undeformed tooth, e2 = J e1, origin on the drum axis, root at b), integrated by collocation:
// 8 intervals of 8 Gauss-Legendre nodes (16 intervals past kLdFineShapes shape functions), with
// the integral inside an interval taken from the Lagrange interpolant of (cos, sin)(theta) on its
// nodes (spectral integration matrix). The rod's mass sits on the same 64 (128) nodes (node
// weight rho A w_a), so the discrete system is a
// set of particles whose positions are exact functions of q: its mass matrix M(q), velocity
// terms, centrifugal, Coriolis and Euler loads follow from D'Alembert's principle without
// approximation, and the energy of the free rod is conserved exactly by its equations
//   M(q) q'' = -K q - D q' - sum_a m_a J_a^T [a_a + 2 Omega J v_a + dOmega/dt J r_a - Omega^2 r_a]
// (J_a = dr_a/dq, v_a = J_a q', a_a = dJ_a/dt q', all in the rotating tooth frame).
#pragma once

#include <Eigen/Core>

#include "threshing_sim/core/model.h"

namespace threshing_sim {

constexpr int kLdGauss = 8;          // Gauss nodes per collocation interval [-]
constexpr int kLdMaxIntervals = 16;  // most collocation intervals along the rod [-]
constexpr int kLdMaxNodes = kLdMaxIntervals * kLdGauss;  // most mass and collocation nodes [-]
// Most Ritz shape functions (teeth.*.modes). The Legendre angle fields' highest Ritz frequencies
// are spurious, and they climb fast once the mass nodes stop resolving the kinetic energy: with
// 64 nodes the polyurethane tooth's highest frequency is 36 times the cantilever's at 28
// functions, 205 times at 32; with 128 nodes 30 times at 28, 62 times at 40
// (docs/large_deflection.md). Hence 8 intervals up to kLdFineShapes functions, 16 beyond.
constexpr int kLdMaxShapes = 40;
constexpr int kLdFineShapes = 24;
// Collocation intervals of a rod with n shape functions [-].
constexpr int ldIntervalsFor(int n) { return n <= kLdFineShapes ? 8 : kLdMaxIntervals; }
// teeth.*.modes: auto on a rod takes the modal tooth's count (chooseModeCount: the modes the
// contact time and tolerance need), at least kLdAutoMinShapes and at most kLdAutoMaxShapes, so
// that two finer levels (+4, +8) stay available to check convergence. The polyurethane knead's
// forces and exit speed move by less than 1 % from 24 to 28 and 32 functions; at 20 the exit
// speed is 1.3 % off (docs/large_deflection.md).
constexpr int kLdAutoMinShapes = 6;
constexpr int kLdAutoMaxShapes = 24;

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
  int n = 0;                         // shape functions [-]
  double theta[kLdMaxNodes];         // section angle at the nodes [rad]
  double cos_t[kLdMaxNodes];         // its cosine [-]
  double sin_t[kLdMaxNodes];         // its sine [-]
  Vec2 r_end[kLdMaxIntervals + 1];   // r at the interval ends [m]
  LdJac J_end[kLdMaxIntervals + 1];  // dr/dq there [m/rad]
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
