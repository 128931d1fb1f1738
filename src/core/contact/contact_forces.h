// threshing_sim core, private: the forces of one contact: the compliant normal law (Hertz with
// Hunt-Crossley damping and the residual flexibility in series), the contact's generalised
// forces, and the velocity drift of its rows (src/core/contact/contact_forces.cc).
#pragma once

#include "../drive.h"
#include "narrow_phase.h"
#include "threshing_sim/core/data.h"
#include "threshing_sim/core/model.h"

namespace threshing_sim {
namespace internal {

// Velocity drift of a contact's rows, analytically: the time derivative of (dg_N/dt, dg_T/dt)
// along the motion z' = u with u frozen and the drum at its speed and acceleration, i.e.
// (d/dt W)^T u + d(wtilde)/dt for the normal (0) and tangential (1) rows, including the
// motion of the contact points over the surfaces. g must come from evaluateContact at
// (z, u, drive) (not far).
Vec2 contactVelocityDrift(const Model& m, const VecX& z, const VecX& u, const Drive& drive,
                          const ContactGeom& g, Workspace* ws);

// Adds w * scale to the generalised vector f for each side of the contact.
void addGeneralised(const Model& m, const ContactGeom& g, double fn, double ft, VecX* f);

// The residual flexibility table (kResidualPoints equally spaced values on [0, length_m], see
// residualFlexibility) interpolated C^1 in x_m: a monotone cubic Hermite interpolant
// (Fritsch-Butland slopes: a node between secants of opposite sign, or next to a flat one, has
// slope 0, so the interpolant keeps the table's sign and monotone stretches) [m/N], with its
// derivative in x_m into *d_dx [1/N]. The series potential's force along the residual's
// gradient needs R'(x*) continuous (docs/model.md §9b).
double residualSmoothAt(const VecX& table, double length_m, double x_m, double* d_dx);

// The same for tooth's ww table at drum speed omega_radps, read as the step reads it
// (residualWwAtSpeed: the compiled table at the scene's speed, else the interpolation in
// Omega^2): C^1 in x_m at any fixed speed. Allocation-free.
double residualSmoothAtSpeed(const ToothModel& tooth, double omega_radps, double x_m, double* d_dx);

// The residual spring's share of a compliant tooth contact's generalised force (docs/model.md
// §9b, "Energy of the series spring"): the series potential V(delta, R) changes by -F^2/2 per
// unit of R at a fixed approach, so the full gradient of V(q) adds (F^2/2) w_r to the contact's
// F w_n. Returns that factor F^2/2 [N] for a normal force fn_N [N] (zero for pairs without a
// residual gradient and under the rigid law, which has no series spring).
inline double residualForceFactor(const ContactGeom& g, double fn_N) {
  const bool has_gradient = g.side[0].w_r.size() > 0 || g.side[1].w_r.size() > 0;
  return has_gradient && g.params->law == ContactLaw::kCompliant ? 0.5 * fn_N * fn_N : 0.0;
}

// Compliant normal force (Hertz constant K with Hunt-Crossley damping), >= 0 [N]. For tooth
// contacts the residual flexibility r = g.residual_mpN is a spring in series: the Hertz law sees
// the indentation delta_e = delta - r F and its rate delta_e' = delta' / (1 + r dF_e/d delta_e)
// (the quasi-static split of the approach between the two springs, F_e = K delta_e^{3/2}):
//   F = K delta_e^{3/2} (1 + chi delta_e'),  solved for delta_e by a bracketed Newton iteration.
double compliantNormalForce(const ContactGeom& g, double K, double v_in_mps, double v_floor_mps);
// The same law at another gap gap_m [m] and normal gap rate vn_mps [m/s] of the pair g (its
// residual flexibility and parameters): the force at an instant inside a time step [N].
double compliantNormalForceAt(const ContactGeom& g, double gap_m, double vn_mps, double K,
                              double v_in_mps, double v_floor_mps);
// The same force before the no-adhesion clamp: negative where the damping would pull (the
// event function of a compliant contact's release) [N].
double compliantNormalForceSigned(const ContactGeom& g, double K, double v_in_mps,
                                  double v_floor_mps);
// Its time derivative [N/s] given the normal relative acceleration g_N'' [m/s^2] and the rate of
// the residual flexibility r' [m/(N s)] (the contact point sliding, the normal turning: w_r . u
// + Omega dR/dtheta) (implicit differentiation of the relation above).
double compliantNormalForceRate(const ContactGeom& g, double K, double v_in_mps, double v_floor_mps,
                                double acc_n_mps2, double r_rate_mpNps = 0.0);

}  // namespace internal
}  // namespace threshing_sim
