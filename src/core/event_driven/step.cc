// Event-driven integration (docs/model.md §7-9, the paper's method).
//
// Between events the index sets are fixed: each pair is separated, in compliant contact, or
// closed under the rigid law, and each contact sticks or slips one way. The smooth phase is
// integrated by Dormand-Prince 5(4) to the tolerance; the multipliers of closed normals and
// sticking tangents come from g'' = 0 at every right-hand side. After each accepted step the
// event functions are checked (gap, normal force, friction limit, slip velocity, pedicel
// force); a gap that dips below zero and back inside the step is found from the cubic Hermite
// interpolant of its values and rates at the step ends (checked at the predicted minimum), and
// a just-bounced gap (at or below zero, opening) is armed to fire when it closes again. A
// sign change is located by re-stepping from the step start (bisection on the step length), the
// state is advanced to just past it, and the index sets are switched: impacts are solved as a
// velocity-level complementarity problem, stick/slip/separation as an acceleration-level one.
// Impacts slower than zeno_velocity are plastic (Zeno rule).
//
// This file: the step as its list of stages (eventDrivenStep) and the candidate pairs (stage
// 1). The stages live in the files of this folder; context.h lists them.
#include <algorithm>

#include "../contact_phase/contact_phase.h"
#include "context.h"

namespace threshing_sim {
namespace internal {
namespace event_driven {

// Stage 1: the candidate pairs for this step, by the broad phase with a margin the step cannot
// outrun; contacts that left the candidate set are separated (their episodes end).
void prepareCandidates(const Ctx& c, StepPlan* plan) {
  const Model& m = c.m;
  Data* d = &c.d;
  Workspace& ws = c.ws;
  // A time step since the last event-driven one rewrote the geometry and forces.
  if (ws.ts.in_contact_step != -2) ws.ed.memo.valid = false;
  ws.ts.in_contact_step = -2;  // time stepping's list of pairs in contact is stale from here
  plan->margin_m = std::max(m.broadphase_margin_m, 1e-6);
  // (Stations only of the teeth that a kernel can reach: evaluateAll computes what it needs.)
  layoutStations(m, &ws);
  broadPhase(m, d->z, 2.0 * plan->margin_m, &ws, &d->theta_rad);
  ws.ed.cand_entry.resize(ws.candidates.size());
  for (size_t i = 0; i < ws.candidates.size(); ++i)
    ws.ed.cand_entry[i] = ws.memory.indexOf(pairKey(ws.candidates[i]));
  for (auto& kv : ws.memory) kv.second.seen = false;
  for (size_t i = 0; i < ws.candidates.size(); ++i) candidateMemory(ws, i).seen = true;
  for (auto& kv : ws.memory) {
    PairMemory& mem = kv.second;
    if (mem.seen || !isActive(mem)) continue;
    ContactGeom g;
    g.pair = PairId{static_cast<PairKind>(kv.first >> 60),
                    static_cast<int>((kv.first >> 30) & 0x3fffffff),
                    static_cast<int>(kv.first & 0x3fffffff)};
    g.params = &m.contact[static_cast<int>(g.pair.kind)];
    endEpisode(m, d, &mem, g, d->t_s, mechanicalEnergy(m, *d) - d->stats.drive_work_J);
  }
}

}  // namespace event_driven

// One event-driven step: from the data's time to the next event, the step-size law's step, or
// t_end_s, whichever comes first.
StepStatus eventDrivenStep(const Model& m, Data* d, double t_end_s) {
  event_driven::Ctx c{m, *d, *d->ws};
  event_driven::StepPlan plan;
  plan.t_end_s = t_end_s;
  const double v_bound_mps = event_driven::motionBound(c);
  // (The contact phase keeps its last step's candidates while they cannot have gone stale.)
  const bool kept = contact_phase::keepCandidates(c, &plan);
  if (!kept) event_driven::prepareCandidates(c, &plan);
  // While a compliant contact is closed: the contact phase's fixed step (contact_phase/).
  if (contact_phase::applies(c) && contact_phase::step(c, t_end_s, v_bound_mps, plan.margin_m))
    return StepStatus::kOk;
  if (kept) event_driven::prepareCandidates(c, &plan);  // the adaptive step's own margin
  event_driven::openTouchingContacts(c);
  event_driven::planStep(c, v_bound_mps, &plan);
  event_driven::armEvents(c, &plan);
  if (!event_driven::integrateAdaptive(c, &plan)) return StepStatus::kFailed;
  event_driven::detectEvents(c, &plan);
  if (plan.event) event_driven::locateFirstEvent(c, &plan);
  // Located maxima of the compliant forces over the step, under the step's index sets.
  if (plan.peaks_on)
    event_driven::locateForcePeaks(c, d->t_s, plan.h_take_s, d->z, d->u, c.ws.ed.z1, c.ws.ed.u1,
                                   plan.end_evaluated);
  event_driven::acceptStep(c, plan);
  event_driven::recordStepForces(c);
  const long attached_before = event_driven::attachedCount(*d);
  event_driven::switchModes(c, plan);
  event_driven::finishStep(c, plan, attached_before);
  return StepStatus::kOk;
}

}  // namespace internal
}  // namespace threshing_sim
