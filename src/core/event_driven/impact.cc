// The event-driven integrator's impacts: a velocity-level complementarity problem over the
// closed rigid contacts (Newton's law, Coulomb friction on the impulses, the Zeno rule).
#include <algorithm>
#include <cmath>
#include <vector>

#include "context.h"

namespace threshing_sim {
namespace internal {
namespace event_driven {

namespace {

// The rows of an impact: every rigid contact closed or touching (gap within 10 x tolerance x
// 1e-3 m), into ws.active / ws.rows; their free velocities, with Newton's restitution target
// e dg_N- folded in unless the impact is plastic or slower than zeno_velocity, into ws.b and
// ws.b_offset.
void assembleImpactRows(const Ctx& c, bool plastic) {
  const Model& m = c.m;
  Workspace& ws = c.ws;
  ws.active.clear();
  ws.rows.clear();
  for (size_t i = 0; i < ws.geoms.size(); ++i) {
    const ContactGeom& g = ws.geoms[i];
    const PairMemory& mem = ws.memory[pairKey(g.pair)];
    if (g.params->law != ContactLaw::kRigid) continue;
    if (!(mem.closed || g.gap_m <= 10 * m.integrator.tolerance * 1e-3)) continue;
    ContactRow row;
    row.mu = g.params->friction;
    ws.active.push_back(static_cast<int>(i));
    ws.rows.push_back(row);
  }
  const int k = static_cast<int>(ws.active.size());
  growTo(&ws.b, 2 * k);
  growTo(&ws.b_offset, k);
  for (int i = 0; i < k; ++i) {
    const ContactGeom& g = ws.geoms[ws.active[i]];
    const bool slow = g.vn > -m.integrator.zeno_velocity_mps;
    ws.b_offset[i] = plastic || slow ? 0.0 : g.params->restitution * std::min(g.vn, 0.0);
    ws.b[2 * i] = g.vn + ws.b_offset[i];
    ws.b[2 * i + 1] = g.vt;
  }
}

// The impulses ws.lambda applied to the velocities d.u; returns their angular impulse on the
// drum through the tooth contacts [N m s].
double applyImpactImpulses(const Ctx& c, const std::vector<MatX>* minv) {
  const Model& m = c.m;
  Workspace& ws = c.ws;
  Data& d = c.d;
  const int k = static_cast<int>(ws.active.size());
  double ang = 0.0;
  for (int i = 0; i < k; ++i) {
    const ContactGeom& g = ws.geoms[ws.active[i]];
    for (const BodyJac& s : g.side) {
      applyInverseMass(m, minv, s.body, s.w_n, ws.lambda[2 * i], &d.u);
      applyInverseMass(m, minv, s.body, s.w_t, ws.lambda[2 * i + 1], &d.u);
    }
    if (g.pair.kind == PairKind::kToothKernel) {
      const Vec2& p = g.p0;
      ang += -ws.lambda[2 * i] * (p.x() * g.n.y() - p.y() * g.n.x()) -
             ws.lambda[2 * i + 1] * (p.x() * g.t.y() - p.y() * g.t.x());
    }
  }
  return ang;
}

// Reports active contact i of a solved impact at time t if it took an impulse: its episode
// (begun if it was open), its impact event and statistics, and its state after the impact.
// e_before: the energy before the impact [J]; work: the drive's work over it [J]; gain: the
// energy it created [J].
void reportImpact(const Ctx& c, int i, double t, double e_before, double work, double gain) {
  const Model& m = c.m;
  Workspace& ws = c.ws;
  Data& d = c.d;
  const ContactGeom& g = ws.geoms[ws.active[i]];
  PairMemory& mem = ws.memory[pairKey(g.pair)];
  const double pn = ws.lambda[2 * i], pt = ws.lambda[2 * i + 1];
  if (pn <= 0.0) return;
  const bool was_open = !mem.closed;
  if (was_open) beginEpisode(m, &d, &mem, g, t, e_before - (d.stats.drive_work_J - work));
  ContactEvent ev;
  ev.t_s = t;
  ev.pair = g.pair;
  ev.from = was_open ? ContactState::kSeparated : mem.state;
  ev.to = ContactState::kImpact;
  ev.is_impact = true;
  ev.vn_before_mps = g.vn;
  ev.vt_before_mps = g.vt;
  // y_N is dg_N+ + e dg_N-: take the offset back out for the post-impact velocity.
  const double vn_after = ws.y[2 * i] - ws.b_offset[i];
  ev.vn_after_mps = vn_after;
  ev.vt_after_mps = ws.y[2 * i + 1];
  ev.impulse_normal_Ns = pn;
  ev.impulse_tangential_Ns = pt;
  ev.energy_lost_J = -gain;
  ev.macro_collision = mem.macro_index;
  ev.sub_collision = mem.sub_index;
  d.events.push_back(ev);
  ++d.stats.impacts;
  const int kb = g.pair.kind == PairKind::kKernelObstacle ? g.pair.a : g.pair.b;
  ++d.stats.kernel_impacts[kb];
  if (g.pair.kind == PairKind::kKernelKernel) ++d.stats.kernel_impacts[g.pair.a];
  d.stats.max_energy_gain_at_impact_J = std::max(d.stats.max_energy_gain_at_impact_J, gain);
  d.stats.total_normal_impulse_Ns += pn;
  mem.impulse_n_acc += pn;
  mem.impulse_t_acc += pt;
  mem.episode_impulse_n += pn;
  mem.episode_impulse_t += pt;
  // Closed if the contact does not leave after the impact; otherwise it bounced.
  const bool stays = vn_after <= m.integrator.zeno_velocity_mps;
  mem.closed = stays;
  mem.state = ContactState::kImpact;
  mem.slip_sign = 0;
  if (!stays) {
    // It bounced: the episode was the instant of the impact.
    mem.last_contact_end_s = t;
    mem.state = ContactState::kSeparated;
    mem.closed = false;
  }
}

}  // namespace

// Velocity-level impact over the closed rigid contacts: Newton restitution, Coulomb friction on
// the impulses. Falls back to a plastic impact if the Newton law would raise the energy.
void solveImpact(const Ctx& c, double t, bool force_plastic) {
  const Model& m = c.m;
  Workspace& ws = c.ws;
  Data& d = c.d;
  const Drive dr = driveAtTime(c, t);
  evaluateAll(c, d.z, d.u, dr);
  for (int attempt = 0; attempt < 2; ++attempt) {
    const bool plastic = force_plastic || attempt == 1;
    assembleImpactRows(c, plastic);
    const int k = static_cast<int>(ws.active.size());
    const double e_before = energyOf(m, d, d.z, d.u, dr.omega_radps);
    const double H_before = angularMomentumOf(m, d.z, d.u, dr.omega_radps);
    const std::vector<MatX>* minv = toothInverseMass(m, d.z, &ws);
    solveContactIslands(m, minv, &ws);
    ws.u_old = d.u;
    const double ang = applyImpactImpulses(c, minv);
    const double H_after = angularMomentumOf(m, d.z, d.u, dr.omega_radps);
    const double work = dr.omega_radps * (H_after - H_before - ang);
    const double gain = energyOf(m, d, d.z, d.u, dr.omega_radps) - e_before - work;
    // Newton's law with friction can create energy: redo the impact plastically.
    if (gain > 1e-12 * std::max(1.0, std::abs(e_before)) && !plastic) {
      d.u = ws.u_old;
      continue;
    }
    d.stats.drive_work_J += work;
    // Report each contact that took an impulse.
    for (int i = 0; i < k; ++i) reportImpact(c, i, t, e_before, work, gain);
    return;
  }
}

}  // namespace event_driven
}  // namespace internal
}  // namespace threshing_sim
