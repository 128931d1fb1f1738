// Time stepping (docs/model.md §9): the impulses applied to the velocities and the positions
// advanced, with the depths of closed rigid contacts kept (stage 7).
#include <algorithm>
#include <vector>

#include "context.h"

namespace threshing_sim {
namespace internal {
namespace time_stepping {

namespace {

// Closed rigid contacts keep their depth. Moreau-Jean constrains the normal velocity at the
// midpoint, not the gap, and the second-order terms it drops (a kernel rocking on its flank
// rolls over a curved profile) move a pressed contact's gap by O(h^2) per step, down and up
// in turn as it rocks, with a net sinking: 2 um/s at h = 1 us, 0.8 mm over the 750 s long
// run. After the position update, every rigid contact that carried an impulse this step is
// evaluated at the end state. Its impact step records its depth (at least a slop: one step at
// the Zeno speed). Afterwards it is moved back to that depth when it sinks a slop deeper, and
// onto the surface when it rises half a slop above it while pressed, by the smallest mass-weighted
// position change along its normal; velocities are unchanged. Together with the activation
// of a pressed contact up to a slop of clearance (assembleContactRows), a resting contact neither
// sinks nor opens by drift: opening made resting kernels chatter, an impact every few steps.
// The potential energy restored is at most what the sinking took. Gauss-Seidel (a kernel on a
// kernel on the floor): each contact is evaluated after the previous one's correction, for up
// to three passes while any correction is made.
template <class MemoryOf>
void keepClosedContactDepths(const Model& m, const Drive& end, double h, MemoryOf memoryOf, Data* d,
                             Workspace* ws) {
  const int k = static_cast<int>(ws->active.size());
  const double slop_m = h * m.integrator.zeno_velocity_mps;
  ContactGeom g;
  for (int pass = 0; pass < 3; ++pass) {
    bool corrected = false;
    for (int i = 0; i < k; ++i) {
      if (!ws->rows[i].normal_unknown || ws->lambda[2 * i] <= 0.0) continue;
      const size_t c = static_cast<size_t>(ws->active[i]);
      if (ws->geoms[c].params->law != ContactLaw::kRigid) continue;
      PairMemory& mem = memoryOf(c);
      const bool impact_step = mem.state == ContactState::kSeparated;
      if (impact_step && pass > 0) continue;
      // This contact at the end state (tooth stations at the end angle).
      const PairId& pair = ws->candidates[c];
      if (pair.kind == PairKind::kToothKernel)
        updateToothStations(m, d->z, end.theta_rad, pair.a, ws);
      evaluateContact(m, d->z, d->u, end, pair, ws, &g);
      // The depth it is kept at: the impact step's, at least a slop.
      const double pen_m = -g.gap_m;
      if (impact_step) {
        mem.ts_depth_m = std::max(slop_m, pen_m);
        continue;
      }
      // Sunk a slop below that depth: back to it. Risen half a slop above the surface while
      // pressed: back onto it, so that the pressed contact, kept active up to a slop of
      // clearance, does not open by drift. Each correction leaves half a slop of room before
      // the next (while a kernel rocks, one every few hundred steps; the evaluation after a
      // correction finds nothing more to do), and rounding-level clearances of a sliding
      // kernel are left alone.
      double target_m;
      if (pen_m > mem.ts_depth_m + slop_m) {
        target_m = mem.ts_depth_m;
      } else if (pen_m < -0.5 * slop_m) {
        target_m = 0.0;
      } else {
        continue;
      }
      const double excess_m = pen_m - target_m;
      const std::vector<MatX>* minv = toothInverseMass(m, d->z, ws);
      double gnn = 0.0;
      for (const BodyJac& s : g.side) {
        if (s.body < 0 || s.w_n.size() == 0) continue;
        gnn += weightedDot(m, minv, s.body, s.w_n, s.w_n);
      }
      if (gnn <= 0.0) continue;
      for (const BodyJac& s : g.side) {
        if (s.body < 0 || s.w_n.size() == 0) continue;
        applyInverseMass(m, minv, s.body, s.w_n, excess_m / gnn, &d->z);
      }
      ++d->stats.depth_corrections;
      corrected = true;
    }
    if (!corrected) break;
  }
}

}  // namespace

// Stage 7: the energy at the step start (still the state in d), when an episode begins; then
// the new velocities u+ = u_free + Minv W P, and positions by the theta rule with the depths of
// closed rigid contacts kept.
void applyImpulses(TsStep* s) {
  const Model& m = s->m;
  Data* d = s->d;
  Workspace& ws = s->ws;
  const int k = static_cast<int>(ws.active.size());
  bool episode_begins = false;
  for (int i = 0; i < k && !episode_begins; ++i)
    episode_begins =
        ws.lambda[2 * i] > 0.0 && s->memoryOf(ws.active[i]).state == ContactState::kSeparated;
  if (episode_begins && !s->have_energy_before)
    s->energy_before = energyOf(m, *d, d->z, d->u, d->omega_radps);
  s->energy_net_before = s->energy_before - s->drive_work_before_J;
  ws.u_old = d->u;
  d->u = ws.ts.u_free;
  for (int i = 0; i < k; ++i) {
    const ContactGeom& g = ws.geoms[ws.active[i]];
    const double pn = ws.lambda[2 * i], pt = ws.lambda[2 * i + 1];
    for (const BodyJac& side : g.side) {
      applyInverseMass(m, &ws.ts.iteration_inverse, side.body, side.w_n, pn, &d->u);
      applyInverseMass(m, &ws.ts.iteration_inverse, side.body, side.w_t, pt, &d->u);
    }
  }
  const double th = m.integrator.theta;
  d->z += s->h * (th * d->u + (1.0 - th) * ws.u_old);
  keepClosedContactDepths(
      m, s->end, s->h, [s](size_t c) -> PairMemory& { return s->memoryOf(c); }, d, &ws);
}

}  // namespace time_stepping
}  // namespace internal
}  // namespace threshing_sim
