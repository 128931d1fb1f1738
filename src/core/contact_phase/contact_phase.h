// The contact phase (integrator.contact_steps; docs/contact_phase.md): while
// a compliant contact is closed, the system (an island's sub-system under the island scheme)
// advances by fixed steps set by the Hertz contact time, as a DEM code does, and returns to the
// adaptive event-driven step (the reference) when its last contact opens.
//
// One step of length h is a Strang splitting, second order in h, with one force evaluation:
//   kick   u+ = u + h/2 a(z, u)             (contact, pedicel and gravity forces; not the teeth's
//                                            linear modal forces)
//   drift  kernels z1 = z + h u+;  modal teeth (q, qd) by their exact propagator over h
//   force  a1 = a(z1, u_pred), u_pred = u_drift + h/2 a: the Hertz (Hunt-Crossley) normals by
//          sign of the gap, friction as a velocity-level cone projection at the step end (stick:
//          zero slip velocity at the end; slip: mu fn against it), pairs coupled through a body
//          by projected Gauss-Seidel
//   kick   u1 = u_drift + h/2 a1
// Contacts open and close, stick and slip, by sign at step ends; each transition's time is
// interpolated inside its step. Rigid-law contacts stay impulsive events of the adaptive step.
//
// Folder-private; the event-driven step (event_driven/step.cc) calls these two functions.
#pragma once

#include "../event_driven/context.h"

namespace threshing_sim {
namespace internal {
namespace contact_phase {

// Whether the step from the data's time is a contact-phase step: the option is on, the drum
// turns at its target speed, every tooth with modes is modal with a valid propagator, some
// candidate pair is in compliant contact and none is closed under the rigid law. Call after
// prepareCandidates.
bool applies(const event_driven::Ctx& c);

// Whether the step from the data's time keeps the candidate pairs of the last contact-phase
// step instead of listing them again (a Verlet list, as DEM codes keep theirs): the last step
// was a contact-phase step that ended at this state, and no body can have moved half the
// broad-phase margin since the list was built (each step moves at most another half: the
// list, built with twice the margin, misses no pair). Sets plan->margin_m when it keeps them;
// else the caller lists them (prepareCandidates) and the motion since is counted from zero.
bool keepCandidates(const event_driven::Ctx& c, event_driven::StepPlan* plan);

// One contact-phase step from the data's time, at most to t_end_s (v_bound_mps: the motion
// bound of the step start, so the step cannot outrun the broad phase's margin margin_m).
// Returns false, with the data unchanged, if a rigid-law pair would close over the step: the
// adaptive step must take it (and locate the impact).
bool step(const event_driven::Ctx& c, double t_end_s, double v_bound_mps, double margin_m);

// forces.cc: whether the last step's end values (ws.cp.end_*) hold for the data's state and
// candidates.
bool endValuesHold(const event_driven::Ctx& c);

// --- the stages (one file each) ---------------------------------------------------------------

// What one contact-phase step carries from stage to stage.
struct StepState {
  double t0_s = 0;                        // step start [s]
  double h_s = 0;                         // step length [s]
  double torque0_Nm = 0, torque1_Nm = 0;  // contact torque on the drum at the ends [N m]
  bool cached_h = false;                  // h is the cached propagator's step (no truncation) [-]
};

// step_size.cc: the step length from the Hertz contact time of the closed contacts (the
// geometry at the start must be in ws.geoms: after startForces); *cut: shortened to land on
// t_end_s.
double stepLength(const event_driven::Ctx& c, double t_end_s, double v_bound_mps, double margin_m,
                  bool* cut);

// forces.cc: the kick acceleration and contact forces at the step start (those of the last
// step's end when the state and the candidates are still those), into ws.cp.a0, fn0, ft0, and
// the velocity the geometry in ws.geoms was evaluated at into ws.cp.u_pred.
void startForces(const event_driven::Ctx& c, StepState* s);
// forces.cc: the first half kick into ws.cp.u_drift, with the friction at the start projected
// so that a sticking contact's slip velocity after it is zero (as at the end: the stick force
// then follows the constraint at both ends instead of alternating about it step by step), and
// the contact torque on the drum at the start.
void startFriction(const event_driven::Ctx& c, StepState* s);
// drift.cc: the drift of ws.cp.u_drift's state into ws.ed.z1 (the teeth's velocities in
// ws.cp.u_drift by their propagator), and the predicted end velocity ws.cp.u_pred.
void kickDrift(const event_driven::Ctx& c, StepState* s);
// forces.cc: the geometry at the end; false if a rigid-law pair closed. Then the normal
// transitions' onsets (pairs that closed get their approach speed and Hertz constant), the
// normal forces, the friction (friction.cc) and the kick acceleration a1, the end velocity.
bool endForces(const event_driven::Ctx& c, StepState* s);
// friction.cc: the tangential forces at the step end (cone projection, Gauss-Seidel), applied
// to ws.cp.a1 and ws.cp.u_end.
void solveFriction(const event_driven::Ctx& c, const StepState& s);
// friction.cc: projects the tangential forces *ft of the contact space's rows (closed contacts,
// buildContactSpace) with normal force fn > 0 on their cones |ft| <= mu fn so that each one's
// slip velocity is its target (zero, or (*target)[i]) where its cone allows (stick) and opposed
// at the cone's edge otherwise (slip), the velocity being one that the forces kick over
// half_h_s; each change goes into the contact space (addForceChange). Gauss-Seidel over the
// contacts (they share bodies), a bounded number of sweeps.
void projectFriction(const event_driven::Ctx& c, double half_h_s, const VecX& fn,
                     const std::vector<double>* target, VecX* ft);

// contact_space.cc: the contact space of the candidates with fn[i] > 0 (the rows), their normal
// and slip velocities at the velocity u (the geometry in ws.geoms evaluated at u_eval) and their
// couplings W; no changes pending.
void buildContactSpace(const event_driven::Ctx& c, const VecX& fn, const VecX& u,
                       const VecX& u_eval);
// contact_space.cc: a change of row r's normal force dfn_N, tangential force dft_N and residual
// factor dfr (residualForceFactor's change) kicked over half_h_s: every row's velocities follow,
// the change is kept for applyContactSpace.
void addForceChange(ContactPhaseScratch::ContactSpace* cs, int r, double dfn_N, double dft_N,
                    double dfr, double half_h_s);
// contact_space.cc: the pending changes applied to the acceleration *a and to the velocity *u it
// kicks over half_h_s (and cleared).
void applyContactSpace(const event_driven::Ctx& c, double half_h_s, VecX* a, VecX* u);
// forces.cc: the normal velocity of contact g at the velocity u, from its value g.vn at the
// velocity u_eval its geometry was evaluated at [m/s].
double normalVelocity(const Model& m, const ContactGeom& g, const VecX& u, const VecX& u_eval);
// friction.cc: the slip velocity of contact g at the velocity u, from its value g.vt at the
// velocity u_eval its geometry was evaluated at [m/s].
double slipVelocity(const Model& m, const ContactGeom& g, const VecX& u, const VecX& u_eval);
// bookkeeping.cc: the accepted step into the data (drive work, clock), the episodes and their
// transitions, impulses, force statistics and peaks, pedicels, the published contacts, and the
// end values kept for the next step.
void acceptStep(const event_driven::Ctx& c, const StepState& s);

// The generalised force of one contact (normal fn, tangential ft and the residual spring's
// share) times scale, added to the accelerations *a (inverse mass applied) [N -> m/s^2 ...].
void addContactAcceleration(const Model& m, const ContactGeom& g, double fn, double ft,
                            double scale, VecX* a);
// The contact torque on the drum of a tooth contact's forces [N m] (0 for other pairs).
double drumTorque(const ContactGeom& g, double fn, double ft);

}  // namespace contact_phase
}  // namespace internal
}  // namespace threshing_sim
