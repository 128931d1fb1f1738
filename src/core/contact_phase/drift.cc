// The contact phase's first half kick and drift: kernels move on a straight line at the kicked
// velocity (the symplectic Euler drift of velocity Verlet); a modal tooth's (q, qd) moves by the
// exact propagator of its free modal equations at the drum's constant speed, a real 2n x 2n
// matrix over the fixed step, built once per step length and speed (a few kept per tooth).
#include <algorithm>

#include "contact_phase.h"

namespace threshing_sim {
namespace internal {
namespace contact_phase {

using event_driven::Ctx;

namespace {

// The propagator of tooth k over h as a real matrix (column j: the flow of the unit state e_j),
// from the event-driven integrator's eigendecomposition: the cached one for (h, speed), else
// built into the least recently built of the tooth's kStepMatrices slots.
const MatX& stepMatrix(const Model& m, int k, double h_s, double omega_radps, Workspace* ws) {
  ContactPhaseScratch& cp = ws->cp;
  std::vector<ContactPhaseScratch::StepMatrix>& slots = cp.phi[k];
  if (slots.size() != ContactPhaseScratch::kStepMatrices)
    slots.resize(ContactPhaseScratch::kStepMatrices);
  for (ContactPhaseScratch::StepMatrix& e : slots)
    if (e.h_s == h_s && e.omega_radps == omega_radps) return e.phi;
  ContactPhaseScratch::StepMatrix& e = *std::min_element(
      slots.begin(), slots.end(), [](const auto& a, const auto& b) { return a.built < b.built; });
  const int n = m.teeth[k].n_modes;
  e.phi.resize(2 * n, 2 * n);
  growTo(&cp.y_unit, 2 * n);
  for (int j = 0; j < 2 * n; ++j) {
    cp.y_unit.head(2 * n).setZero();
    cp.y_unit[j] = 1.0;
    propagateTooth(&ws->ed.prop[k], h_s, cp.y_unit.head(n), cp.y_unit.segment(n, n),
                   e.phi.col(j).head(n), e.phi.col(j).tail(n));
  }
  e.h_s = h_s;
  e.omega_radps = omega_radps;
  e.built = ++cp.matrices_built;
  return e.phi;
}

// Tooth k's (q, qd) from (z0, u) over h into (z1, u) (u holds the kicked qd on entry): by the
// step's matrix, or (a step cut to land on the end time) by the propagator itself.
void driftTooth(const Ctx& c, int k, const StepState& s, const VecX& z0, VecX* z1, VecX* u) {
  const Model& m = c.m;
  Workspace& ws = c.ws;
  ContactPhaseScratch& cp = ws.cp;
  const ToothModel& tm = m.teeth[k];
  const int n = tm.n_modes, off = tm.dof_offset;
  growTo(&cp.y0, 2 * n);
  growTo(&cp.y1, 2 * n);
  cp.y0.head(n) = z0.segment(off, n);
  cp.y0.segment(n, n) = u->segment(off, n);
  if (s.cached_h) {
    cp.y1.head(2 * n).noalias() = stepMatrix(m, k, s.h_s, c.d.omega_radps, &ws) * cp.y0.head(2 * n);
  } else {
    propagateTooth(&ws.ed.prop[k], s.h_s, cp.y0.head(n), cp.y0.segment(n, n), cp.y1.head(n),
                   cp.y1.segment(n, n));
  }
  z1->segment(off, n) = cp.y1.head(n);
  u->segment(off, n) = cp.y1.segment(n, n);
}

}  // namespace

void kickDrift(const Ctx& c, StepState* s) {
  const Model& m = c.m;
  Workspace& ws = c.ws;
  ContactPhaseScratch& cp = ws.cp;
  const Data& d = c.d;
  const double h = s->h_s;
  const int T = static_cast<int>(m.teeth.size());
  if (cp.phi.size() != static_cast<size_t>(T)) cp.phi.resize(T);
  ws.ed.z1 = d.z + h * cp.u_drift;
  for (int k = 0; k < T; ++k)
    if (m.teeth[k].n_modes > 0) driftTooth(c, k, *s, d.z, &ws.ed.z1, &cp.u_drift);
  cp.u_pred = cp.u_drift + (0.5 * h) * cp.a0;
}

}  // namespace contact_phase
}  // namespace internal
}  // namespace threshing_sim
