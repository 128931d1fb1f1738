// Time stepping (docs/model.md §9): contact detection at the step's midpoint (stage 2).
#include <algorithm>
#include <cmath>
#include <limits>

#include "context.h"

namespace threshing_sim {
namespace internal {
namespace time_stepping {

namespace {

// Largest speed of any material point, to widen the broad phase over one step [m/s].
double speedBound(const Model& m, const Data& d) {
  double v = 0.0;
  for (const ToothModel& tm : m.teeth) {
    v = std::max(v, std::abs(d.omega_radps) * (m.drum.radius_m + tm.length_m));
  }
  for (int i = 0; i < static_cast<int>(m.kernels.size()); ++i)
    v = std::max(v, kernelSpeedBound(m, d.u, i));
  return v;
}

}  // namespace

// Stage 2: contact detection at the midpoint configuration z_M = z + h/2 u: the broad phase,
// each candidate's pair memory (inserted on first sight), and the narrow phase. Separated pairs
// surely farther than a quarter margin get only a gap bound: inactive (kernel and obstacle
// pairs by the supporting-line bound, so that kernels side by side on the grate, within each
// other's bounding circles but not in reach, get no exact distance).
void detectContacts(TsStep* s) {
  const Model& m = s->m;
  const Data& d = *s->d;
  Workspace& ws = s->ws;
  ws.ts.z_mid = d.z + 0.5 * s->h * d.u;
  updateLdIterationMatrices(m, ws.ts.z_mid, s->h, &ws);
  // Tooth stations only for the teeth that can meet a kernel (computed by the broad phase).
  layoutStations(m, &ws);
  broadPhase(m, ws.ts.z_mid, m.broadphase_margin_m + 2.0 * s->h * speedBound(m, d), &ws,
             &s->mid.theta_rad);
  ws.geoms.resize(ws.candidates.size());
  ws.ts.candidate_memory.resize(ws.candidates.size());
  for (size_t c = 0; c < ws.candidates.size(); ++c)
    ws.ts.candidate_memory[c] = ws.memory.indexOf(pairKey(ws.candidates[c]));
  for (size_t c = 0; c < ws.candidates.size(); ++c) {
    const bool separated = s->memoryOf(c).state == ContactState::kSeparated;
    evaluateContact(
        m, ws.ts.z_mid, d.u, s->mid, ws.candidates[c], &ws, &ws.geoms[c],
        separated ? 0.25 * m.broadphase_margin_m : std::numeric_limits<double>::infinity(),
        separated);
  }
}

}  // namespace time_stepping
}  // namespace internal
}  // namespace threshing_sim
