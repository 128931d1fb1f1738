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

// Compliant normal force (Hertz constant K with Hunt-Crossley damping), >= 0 [N]. For tooth
// contacts the residual flexibility r = g.residual_mpN is a spring in series: the Hertz law sees
// the indentation delta_e = delta - r F and its rate delta_e' = delta' / (1 + r dF_e/d delta_e)
// (the quasi-static split of the approach between the two springs, F_e = K delta_e^{3/2}):
//   F = K delta_e^{3/2} (1 + chi delta_e'),  solved for delta_e by a bracketed Newton iteration.
double compliantNormalForce(const ContactGeom& g, double K, double v_in_mps, double v_floor_mps);
// The same force before the no-adhesion clamp: negative where the damping would pull (the
// event function of a compliant contact's release) [N].
double compliantNormalForceSigned(const ContactGeom& g, double K, double v_in_mps,
                                  double v_floor_mps);
// Its time derivative [N/s] given the normal relative acceleration g_N'' [m/s^2] (implicit
// differentiation of the relation above).
double compliantNormalForceRate(const ContactGeom& g, double K, double v_in_mps, double v_floor_mps,
                                double acc_n_mps2);

}  // namespace internal
}  // namespace threshing_sim
