// Time stepping (docs/model.md §9): the velocity-level contact problem of a step: the free
// velocity (stage 3), the contact rows (stage 4), Newton's law targets (stage 5) and the
// impulses (stage 6).
#include <algorithm>
#include <cmath>
#include <vector>

#include "context.h"

namespace threshing_sim {
namespace internal {
namespace time_stepping {

// Stage 3: the free velocity: theta-method on the linear tooth equations, explicit kernel
// forces (the drum's acceleration over the step as the forcing).
void freeVelocity(TsStep* s) {
  const Model& m = s->m;
  const Data& d = *s->d;
  Workspace& ws = s->ws;
  const double h = s->h, th = m.integrator.theta;
  const int T = static_cast<int>(m.teeth.size());
  Drive forcing = s->mid;
  forcing.alpha_radps2 = (s->end.omega_radps - d.omega_radps) / h;
  smoothForces(m, d, ws.ts.z_mid, d.u, forcing, &ws.forces);
  for (int k = 0; k < T; ++k) {
    const ToothModel& tm = m.teeth[k];
    if (tm.n_modes == 0) continue;
    auto f = ws.forces.segment(tm.dof_offset, tm.n_modes);
    f.noalias() -=
        (h * (th - 0.5)) * (ws.ts.iteration_stiffness[k] * d.u.segment(tm.dof_offset, tm.n_modes));
  }
  ws.ts.u_free = d.u;
  for (int k = 0; k < T; ++k) {
    const ToothModel& tm = m.teeth[k];
    if (tm.n_modes == 0) continue;
    ws.ts.u_free.segment(tm.dof_offset, tm.n_modes).noalias() +=
        h * (ws.ts.iteration_inverse[k] * ws.forces.segment(tm.dof_offset, tm.n_modes));
  }
  for (const KernelModel& k : m.kernels) {
    ws.ts.u_free.segment<2>(k.dof_offset) += h / k.mass_kg * ws.forces.segment<2>(k.dof_offset);
    ws.ts.u_free[k.dof_offset + 2] += h / k.inertia_kgm2 * ws.forces[k.dof_offset + 2];
  }
}

namespace {

// The residual spring's share of a compliant tooth contact's impulse (docs/model.md §9b):
// h (F^2/2) w_r with F = pn / h, a known impulse, into the free velocity (through the same
// iteration inverse as the contact impulses).
void addResidualImpulse(TsStep* s, const ContactGeom& g, double pn_Ns) {
  const double scale = s->h * residualForceFactor(g, pn_Ns / s->h);  // [N s]
  if (scale == 0.0) return;
  for (const BodyJac& side : g.side)
    applyInverseMass(s->m, &s->ws.ts.iteration_inverse, side.body, side.w_r, scale,
                     &s->ws.ts.u_free);
}

}  // namespace

// Stage 4: the active contacts, closed at the midpoint, as rows of the contact problem. Rigid:
// an unknown normal impulse with Newton's law; compliant: the Hertz-Hunt-Crossley force over
// the step as a fixed normal impulse. A pressed rigid contact (sticking or slipping at the last
// step, past its impact step) stays active up to a slop of clearance (h zeno_velocity): the
// drift its depth keeping corrects must not open it. A contact that just bounced is not pressed.
void assembleContactRows(TsStep* s) {
  const Model& m = s->m;
  Workspace& ws = s->ws;
  ws.active.clear();
  ws.rows.clear();
  const double keep_m = s->h * m.integrator.zeno_velocity_mps;
  for (size_t c = 0; c < ws.geoms.size(); ++c) {
    const ContactGeom& g = ws.geoms[c];
    PairMemory& mem = s->memoryOf(c);
    const bool pressed = g.params->law == ContactLaw::kRigid &&
                         (mem.state == ContactState::kStick || mem.state == ContactState::kSlip);
    if (g.gap_m > (pressed ? keep_m : 0.0)) continue;
    ContactRow row;
    row.mu = g.params->friction;
    if (g.params->law == ContactLaw::kRigid) {
      row.normal_unknown = true;
    } else {
      const bool first = mem.state == ContactState::kSeparated;
      const double v_in = first ? -g.vn : mem.v_in_mps;
      const double K = first ? g.hertz_K : mem.hertz_K;
      row.normal_unknown = false;
      row.lambda_n_fixed = s->h * compliantNormalForce(g, K, v_in, m.hc_min_impact_speed_mps);
      addResidualImpulse(s, g, row.lambda_n_fixed);
    }
    ws.active.push_back(static_cast<int>(c));
    ws.rows.push_back(row);
  }
}

// Stage 5: the free contact velocities b = W^T u_free (+ the restitution target e dg_N- of
// Newton's law 0 <= P_N _|_ dg_N+ + e dg_N- >= 0; slow approaches are plastic: Zeno).
void contactTargets(TsStep* s) {
  const Model& m = s->m;
  Workspace& ws = s->ws;
  const int k = static_cast<int>(ws.active.size());
  growTo(&ws.b, 2 * k);
  growTo(&ws.b_offset, k);
  ws.b_offset.head(k).setZero();
  for (int i = 0; i < k; ++i) {
    const ContactGeom& g = ws.geoms[ws.active[i]];
    double bn = g.wtilde_n, bt = g.wtilde_t;
    for (const BodyJac& side : g.side) {
      if (side.body < 0 || side.w_n.size() == 0) continue;
      const auto uf = ws.ts.u_free.segment(bodyDofOffset(m, side.body), side.w_n.size());
      bn += side.w_n.dot(uf);
      bt += side.w_t.dot(uf);
    }
    if (ws.rows[i].normal_unknown && g.vn < -m.integrator.zeno_velocity_mps)
      ws.b_offset[i] = g.params->restitution * g.vn;
    ws.b[2 * i] = bn + ws.b_offset[i];
    ws.b[2 * i + 1] = bt;
  }
}

namespace {

// A compliant force held over a coarse step can throw the bodies apart faster than they met
// (energy from nothing). No contact may separate faster than its approach speed (e <= 1): such
// a contact becomes a rigid row with that bound as its target. Returns whether any did.
bool capSeparationSpeeds(TsStep* s) {
  const Model& m = s->m;
  Workspace& ws = s->ws;
  bool capped = false;
  for (int i = 0; i < static_cast<int>(ws.active.size()); ++i) {
    if (ws.rows[i].normal_unknown) continue;
    const PairMemory& mem = s->memoryOf(ws.active[i]);
    const double v_in =
        mem.state == ContactState::kSeparated ? -ws.geoms[ws.active[i]].vn : mem.v_in_mps;
    // 1 % above the approach speed is the discretisation noise of an elastic (e = 1) contact.
    const double v_max = 1.01 * std::max(v_in, m.integrator.zeno_velocity_mps);
    if (ws.y[2 * i] <= v_max) continue;
    ws.rows[i].normal_unknown = true;
    ws.b_offset[i] = -v_max;
    ws.b[2 * i] -= v_max;
    capped = true;
  }
  return capped;
}

// Newton's law with friction can create energy. The impulses' work relative to the free
// motion is P.dg+ - 1/2 P.G P = P.(y - offset) - 1/2 P.(y - b); if it is positive, the step's
// impacts lose their restitution targets (to be solved again plastically, which cannot gain
// energy). Returns whether they did.
bool dropRestitutionIfWorkGained(Workspace* ws) {
  const int k = static_cast<int>(ws->active.size());
  double work = 0.0, restitution = 0.0;
  for (int i = 0; i < 2 * k; ++i) {
    const double off = (i % 2 == 0) ? ws->b_offset[i / 2] : 0.0;
    work += ws->lambda[i] * (ws->y[i] - off) - 0.5 * ws->lambda[i] * (ws->y[i] - ws->b[i]);
    if (i % 2 == 0 && ws->rows[i / 2].normal_unknown) restitution += std::abs(off);
  }
  if (!(restitution > 0.0 && work > 1e-15)) return false;
  for (int i = 0; i < k; ++i) {
    if (!ws->rows[i].normal_unknown || ws->b_offset[i] >= 0.0) continue;
    ws->b[2 * i] -= ws->b_offset[i];
    ws->b_offset[i] = 0.0;
  }
  return true;
}

}  // namespace

// Stage 6: the contact impulses: the complementarity problem per island, again with capped
// separation speeds, and again plastically if Newton's law gained energy.
void solveImpulses(TsStep* s) {
  Workspace& ws = s->ws;
  s->solved = solveContactIslands(s->m, &ws.ts.iteration_inverse, &ws);
  if (capSeparationSpeeds(s))
    s->solved = solveContactIslands(s->m, &ws.ts.iteration_inverse, &ws) && s->solved;
  if (dropRestitutionIfWorkGained(&ws))
    s->solved = solveContactIslands(s->m, &ws.ts.iteration_inverse, &ws) && s->solved;
}

}  // namespace time_stepping
}  // namespace internal
}  // namespace threshing_sim
