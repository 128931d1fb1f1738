// threshing_sim core, private: the narrow phase, everything known about one contact pair at one
// configuration: gap, normal, contact points, Jacobians, relative velocities and the Hertz
// constant, by one function per pair kind (src/core/contact/narrow_phase.cc).
#pragma once

#include <limits>
#include <vector>

#include "../drive.h"
#include "../small_vec.h"
#include "threshing_sim/core/beam.h"
#include "threshing_sim/core/data.h"
#include "threshing_sim/core/model.h"

namespace threshing_sim {
namespace internal {

// One body's share of a contact's Jacobians: dg/dt = w_n . u_body (+ the other body + rheonomic).
struct BodyJac {
  int body = -1;  // body index, -1 = fixed
  SmallVec w_n;   // d(dg_N/dt)/d(u_body)
  SmallVec w_t;   // d(dg_T/dt)/d(u_body)
  SmallVec w_r;   // tooth contacts: d(residual_mpN)/dt per unit of u_body, the residual
                  // flexibility's configuration gradient [m/N per unit coordinate]; else empty
};

// Everything known about one contact pair at one configuration.
struct ContactGeom {
  PairId pair;
  double gap_m = 0;        // signed gap [m]
  Vec2 n = Vec2::UnitY();  // unit normal towards the kernel (body 1) [-]
  Vec2 t = Vec2::UnitX();  // unit tangent J n [-]
  Vec2 p0 = Vec2::Zero();  // contact point on body 0's surface [m]
  Vec2 p1 = Vec2::Zero();  // contact point on body 1's (the kernel's) surface [m]
  double tooth_x_m = 0;    // tooth contacts: material coordinate [m]
  BodyJac side[2];         // side 0: tooth / kernel a / fixed; side 1: the kernel b
  double wtilde_n = 0;     // rheonomic part of dg_N/dt [m/s]
  double wtilde_t = 0;     // rheonomic part of dg_T/dt [m/s]
  double vn = 0;           // dg_N/dt [m/s]
  double vt = 0;           // dg_T/dt [m/s]
  double hertz_K = 0;      // Hertz constant K in F = K delta^{3/2} [N/m^{3/2}]
  // Radii of curvature of the two surfaces at p0 and p1 (inf: flat; a tooth pair's rho0 is
  // unused, its drift follows the deformed centreline) [m].
  double rho0_m = std::numeric_limits<double>::infinity();
  double rho1_m = std::numeric_limits<double>::infinity();
  double residual_mpN = 0;  // tooth contacts: residual flexibility of the truncated modes along
                            // n at the contact point, in series with the Hertz law [m/N]
  double residual_dtheta_mpNprad = 0;  // its derivative in the drum angle at fixed coordinates
                                       // (the rheonomic part of its rate / Omega) [m/(N rad)]
  const ContactParams* params = nullptr;
  bool far = false;  // only a lower bound of the gap was computed (no Jacobians)
};

// The narrow phase's memory across calls (Workspace::narrow): none since the residual
// flexibility is tabulated over the drum speed at compile time (ToothModel::residual_panels).
struct NarrowPhaseScratch {};

// Narrow phase for one pair: gap, normal, Jacobians, relative velocities, Hertz constant.
// Requires updateStations for z first. If a cheap lower bound of the gap exceeds far_m, only
// that bound is stored (g->far = true): enough for the sign of a separated pair's gap. The
// bound is that of the bounding circles (which pairs count as near, and are reported in
// Data::contacts, follows from it), or with tight_bound, for pairs of exact shapes (kernels,
// obstacles), the supporting-line gap along the line of centres, a far better bound for
// elongated kernels; tooth pairs always use the bounding circles (the polyline of stations only
// approximates the deformed tooth, and the margin covers the difference). Both integrators
// pass tight_bound for separated pairs, so kernel-kernel and kernel-obstacle pairs count as
// near (and are reported) when their supporting-line gap is within a quarter margin.
// warm_x_m (tooth pairs, optional): where >= 0 and far_m is infinite, the closest point's
// material coordinate of an earlier evaluation, from which the refinement on the deformed
// centreline starts instead of the polyline search (that search remains the fallback should
// the refinement not converge); receives the closest point found (left alone when far).
// warm_theta_rad (kernel-kernel pairs, or nullptr): the separating direction of the pair's last
// query, the warm start of ellipseEllipse, which receives this one's (left alone when far).
void evaluateContact(const Model& m, const VecX& z, const VecX& u, const Drive& drive,
                     const PairId& pair, Workspace* ws, ContactGeom* g,
                     double far_m = std::numeric_limits<double>::infinity(),
                     bool tight_bound = false, double* warm_x_m = nullptr,
                     double* warm_theta_rad = nullptr);

// What the warm tooth-kernel pairs of one tooth share at one evaluation (evaluateWarmToothKernel):
// the tooth's axes turned by the drum, computed once per tooth and evaluation.
struct ToothFrame {
  int tooth = -1;              // the tooth it was computed for (-1: none) [-]
  double theta_rad = 0;        // the drum angle it was computed at [rad]
  Vec2 e1_W = Vec2::UnitX();   // tooth axis in world [-]
  Vec2 e2_W = Vec2::UnitY();   // transverse axis J e1 in world [-]
  Vec2 root_W = Vec2::Zero();  // the tooth's root in world [m]
  // Recomputes the frame unless it holds for (tooth, theta_rad) already.
  void update(const Model& m, int tooth_index, double drum_angle_rad);
};

// The contact phase's narrow phase of a tooth-kernel pair in contact that was evaluated at its
// last step (a warm pair; a modal tooth with modes): the closest point by Newton steps on the
// closest-point condition n . rt_x = 0 from warm_x_m [m], the deflection w, w', w'' from the
// mode table contracted with q once per table interval (beam.h interpolateDeflection), the
// condition's exact derivative through the ellipse's curvature, the stations bracketing the
// point computed directly: no polyline search, no station update, no transcendental function
// but the kernel angle's sincos. Then the Jacobians, velocities, residual flexibility and
// Hertz constant as evaluateContact gives them (w'' from the table, to ~1e-12 of the exact
// one). frame: ToothFrame::update for the pair's tooth and the drive's angle. Returns false
// when its guard doubts the warm answer (no strict minimum of the distance, no convergence in
// a few steps, a move of more than a quarter station interval, or a point that says the bodies
// are apart): then call evaluateContact, whose full path decides. apart_ok: a point that says
// they are apart is answered too where the distance has a single minimum over the tooth (the
// centreline's curvature bound against the kernel's, narrow_phase.cc singleMinimum); the
// geometry is then the exact one of a separated pair, never marked far.
bool evaluateWarmToothKernel(const Model& m, const VecX& z, const VecX& u, const Drive& drive,
                             const PairId& pair, const ToothFrame& frame, double warm_x_m,
                             ContactGeom* g, bool apart_ok = false);

}  // namespace internal
}  // namespace threshing_sim
