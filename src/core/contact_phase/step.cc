// The contact phase: the step as its list of stages (step) and when it applies (applies). The
// method is summarised in contact_phase.h.
#include <algorithm>

#include "contact_phase.h"

namespace threshing_sim {
namespace internal {
namespace contact_phase {

using event_driven::Ctx;

bool applies(const Ctx& c) {
  const Model& m = c.m;
  Workspace& ws = c.ws;
  if (m.integrator.contact_steps <= 0 || m.has_large_deflection) return false;
  if (c.d.omega_radps != c.d.omega_target_radps) return false;  // a drum ramp
  bool compliant = false;
  for (size_t i = 0; i < ws.candidates.size(); ++i) {
    const PairMemory& mem = event_driven::candidateMemory(ws, i);
    if (!event_driven::isActive(mem)) continue;
    if (m.contact[static_cast<int>(ws.candidates[i].kind)].law == ContactLaw::kRigid) return false;
    compliant = true;
  }
  if (!compliant) return false;
  const int T = static_cast<int>(m.teeth.size());
  if (ws.ed.prop.size() != static_cast<size_t>(T)) ws.ed.prop.resize(T);
  for (int k = 0; k < T; ++k) {
    if (m.teeth[k].n_modes == 0) continue;
    if (!buildToothPropagator(m, k, c.d.omega_radps, &ws.ed.prop[k])) return false;
  }
  return true;
}

bool keepCandidates(const Ctx& c, event_driven::StepPlan* plan) {
  const double margin_m = std::max(c.m.broadphase_margin_m, 1e-6);
  ContactPhaseScratch& cp = c.ws.cp;
  if (c.m.integrator.contact_steps > 0 && cp.list_motion_m <= 0.5 * margin_m && endValuesHold(c)) {
    plan->margin_m = margin_m;
    return true;
  }
  cp.list_motion_m = 0.0;
  return false;
}

bool step(const Ctx& c, double t_end_s, double v_bound_mps, double margin_m) {
  StepState s;
  s.t0_s = c.d.t_s;
  startForces(c, &s);
  bool cut = false;
  s.h_s = stepLength(c, t_end_s, v_bound_mps, margin_m, &cut);
  s.cached_h = !cut;
  startFriction(c, &s);
  kickDrift(c, &s);
  if (!endForces(c, &s)) return false;
  acceptStep(c, s);
  c.ws.cp.list_motion_m += v_bound_mps * s.h_s;
  return true;
}

}  // namespace contact_phase
}  // namespace internal
}  // namespace threshing_sim
