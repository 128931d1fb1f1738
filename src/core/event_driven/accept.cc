// The event-driven integrator's step end: the accepted step (stage 8), the force statistics
// (stage 9), the projection onto the constraints and the contacts published (stage 11).
#include <algorithm>
#include <vector>

#include "context.h"

namespace threshing_sim {
namespace internal {
namespace event_driven {

// Stage 8: accept the step: the drive's work, then the state and the drum move to its end.
void acceptStep(const Ctx& c, const StepPlan& plan) {
  const Model& m = c.m;
  Data* d = &c.d;
  Workspace& ws = c.ws;
  const Drive mid = driveAt(m, *d, 0.5 * plan.h_take_s);
  const Drive end = driveAt(m, *d, plan.h_take_s);
  // (The start's momentum is the last step's end value unless something moved the state.)
  double H0 = 0, unused_energy = 0;
  if (!ws.ed.end_values.lookup(*d, &unused_energy, &H0))
    H0 = angularMomentumOf(m, d->z, d->u, d->omega_radps);
  const double H1 = angularMomentumOf(m, ws.ed.z1, ws.ed.u1, end.omega_radps);
  d->stats.drive_work_J += mid.omega_radps * (H1 - H0 - ws.ed.torque_impulse);
  const int n_geoms = static_cast<int>(ws.candidates.size());
  growTo(&ws.ed.imp_n_step, n_geoms);
  growTo(&ws.ed.imp_t_step, n_geoms);
  ws.ed.imp_n_step.head(n_geoms) = ws.ed.imp_n.head(n_geoms);
  ws.ed.imp_t_step.head(n_geoms) = ws.ed.imp_t.head(n_geoms);
  d->z = ws.ed.z1;
  d->u = ws.ed.u1;
  d->t_s = end.t_s;
  d->theta_rad = end.theta_rad;
  d->omega_radps = end.omega_radps;
  d->alpha_radps2 = end.alpha_radps2;
  ++d->steps;
  ws.ed.end_values.store(*d, 0.0, H1);
  if (!plan.event)
    ws.ed.h = plan.truncated && !plan.rejected && plan.h_next_s < plan.h_wanted_s ? plan.h_wanted_s
                                                                                  : plan.h_next_s;
}

// Stage 9: statistics of the forces over the accepted step (its end point), and the step's
// impulses added to the episodes; an impact under the compliant law becomes stick or slip.
void recordStepForces(const Ctx& c) {
  const Model& m = c.m;
  Data* d = &c.d;
  Workspace& ws = c.ws;
  const double t = d->t_s;
  double torque1 = 0;
  // (Unless an event moved the end, the end's event functions evaluated it: kStepEnd serves.)
  rhs(c, t, d->z, d->u, &ws.ed.udot_end, &torque1, true);
  const VecX& imp_n = ws.ed.imp_n_step;
  const VecX& imp_t = ws.ed.imp_t_step;
  for (size_t i = 0; i < ws.geoms.size(); ++i) {
    const ContactGeom& g = ws.geoms[i];
    PairMemory& mem = candidateMemory(ws, i);
    if (!isActive(mem)) continue;
    recordForce(m, d, g, mem.normal_force_N, mem.tangential_force_N, t);
    mem.episode_peak_N = std::max(mem.episode_peak_N, mem.normal_force_N);
    mem.episode_impulse_n += imp_n[i];
    mem.episode_impulse_t += imp_t[i];
    mem.impulse_n_acc += imp_n[i];
    mem.impulse_t_acc += imp_t[i];
    d->stats.total_normal_impulse_Ns += imp_n[i];
    if (mem.state == ContactState::kImpact && g.params->law == ContactLaw::kCompliant)
      mem.state = mem.slip_sign == 0 ? ContactState::kStick : ContactState::kSlip;
    // A slip begun from stick whose slip velocity passed the velocity error scale reverses at
    // zero from here (slipReversalScale).
    if (mem.slip_from_stick && mem.slip_sign * g.vt > slipReversalScale(m.integrator))
      mem.slip_from_stick = false;
  }
}

namespace {

// Projects the state back onto closed rigid contacts (g = 0, dg/dt = 0) and sticking tangents
// (dg_T/dt = 0) after a step, so that constraint drift never accumulates. Gauss-Seidel: each
// contact is re-evaluated after the previous one's correction. Returns whether any correction
// was applied (the state is otherwise untouched).
bool projectConstraints(const Ctx& c, double t) {
  bool corrected = false;
  const Model& m = c.m;
  Workspace& ws = c.ws;
  Data& d = c.d;
  const Drive dr = driveAtTime(c, t);
  for (int pass = 0; pass < 3; ++pass) {
    for (size_t i = 0; i < ws.candidates.size(); ++i) {
      const PairMemory& mem = candidateMemory(ws, i);
      if (!isActive(mem)) continue;
      const ContactParams& cp = m.contact[static_cast<int>(ws.candidates[i].kind)];
      const bool normal = cp.law == ContactLaw::kRigid && mem.closed;
      const bool tangent =
          mem.slip_sign == 0 && cp.friction > 0 && mem.state == ContactState::kStick;
      if (!normal && !tangent) continue;
      // This contact at the current (already corrected) state.
      ws.ed.memo.valid = false;  // the stations move
      ContactGeom g;
      const PairId& pair = ws.candidates[i];
      if (pair.kind == PairKind::kToothKernel)
        updateToothStations(m, d.z, dr.theta_rad, pair.a, &ws);
      evaluateContact(m, d.z, d.u, dr, pair, &ws, &g);
      // Minimal mass-weighted correction of this contact alone.
      const std::vector<MatX>* minv = toothInverseMass(m, d.z, &ws);
      double gnn = 0, gtt = 0;
      for (const BodyJac& s : g.side) {
        if (s.body < 0 || s.w_n.size() == 0) continue;
        gnn += weightedDot(m, minv, s.body, s.w_n, s.w_n);
        gtt += weightedDot(m, minv, s.body, s.w_t, s.w_t);
      }
      if (normal && gnn > 0) {
        corrected = true;
        for (const BodyJac& s : g.side) {
          applyInverseMass(m, minv, s.body, s.w_n, -g.gap_m / gnn, &d.z);
          applyInverseMass(m, minv, s.body, s.w_n, -g.vn / gnn, &d.u);
        }
      }
      if (tangent && gtt > 0) {
        corrected = true;
        for (const BodyJac& s : g.side) applyInverseMass(m, minv, s.body, s.w_t, -g.vt / gtt, &d.u);
      }
    }
  }
  return corrected;
}

}  // namespace

// Stage 11: the forces and geometry of the end state (the statistics' evaluation holds them
// unless an event, a broken pedicel or a projection changed the state or the index sets), and
// the contacts published to the data.
void finishStep(const Ctx& c, const StepPlan& plan, long attached_before) {
  Data* d = &c.d;
  Workspace& ws = c.ws;
  const bool projected = projectConstraints(c, d->t_s);
  double torque1 = 0;
  if (plan.event || projected || attached_before != attachedCount(*d))
    rhs(c, d->t_s, d->z, d->u, &ws.ed.udot_end, &torque1, true, SeparatedPairs::kStepEnd,
        stepEndHorizon(ws, 0.0));
  publishContacts(d, &ws);
}

}  // namespace event_driven
}  // namespace internal
}  // namespace threshing_sim
