// Moreau-Jean time stepping (docs/model.md §9): fixed step h, theta-method for the smooth
// linear part, contact detection at the midpoint, one velocity-level complementarity problem
// per island with Newton's impact law (rigid) or the Hertz force as a fixed normal (compliant).
#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <limits>

#include "internal.h"
#include "threshing_sim/core/beam.h"
#include "threshing_sim/core/simulator.h"

namespace threshing_sim {
namespace internal {
namespace {

// (I + h theta D + h^2 theta^2 K(Omega))^-1 per tooth, rebuilt only when Omega or h changes
// (a recovery crosses an interval with smaller steps).
void updateIterationMatrices(const Model& m, double omega, double h, Workspace* ws) {
  if (ws->ts.iteration_omega == omega && ws->ts.iteration_h == h &&
      ws->ts.iteration_inverse.size() == m.teeth.size())
    return;
  const double th = m.integrator.theta;
  const size_t T = m.teeth.size();
  ws->ts.iteration_inverse.resize(T);
  ws->ts.iteration_stiffness.resize(T);
  ws->ts.iteration_matrix.resize(T);
  ws->ts.iteration_lu.resize(T);
  for (size_t k = 0; k < T; ++k) {
    const ToothModel& tm = m.teeth[k];
    const int n = tm.n_modes;
    // K(Omega) = Lambda + Omega^2 (K_G - I), written into storage of a fixed size per tooth so
    // that a drum ramp (new Omega every step) allocates nothing.
    MatX& K = ws->ts.iteration_stiffness[k];
    K.resize(n, n);
    if (tm.beam_model == ToothBeamModel::kLargeDeflection) {
      // The rod's implicit part is its constant elastic stiffness; its mass depends on q, so
      // updateLdIterationMatrices builds the matrix at every step's midpoint.
      K = tm.ld_K;
      ws->ts.iteration_matrix[k].resize(n, n);
      ws->ts.iteration_inverse[k].resize(n, n);
      continue;
    }
    K = (omega * omega) * tm.K_G;
    K.diagonal().array() =
        (omega * omega) * (tm.K_G.diagonal().array() - 1.0) + tm.omega0_sq.array();
    MatX& W = ws->ts.iteration_matrix[k];
    W.resize(n, n);
    W = (h * h * th * th) * K;
    W.diagonal().array() += 1.0 + h * th * tm.damping_coeff.array();
    ws->ts.iteration_inverse[k].resize(n, n);
    if (n == 0) continue;
    ws->ts.iteration_lu[k].compute(W);
    ws->ts.iteration_inverse[k] = ws->ts.iteration_lu[k].inverse();
  }
  ws->ts.iteration_omega = omega;
  ws->ts.iteration_h = h;
}

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

// Closed rigid contacts keep their depth. Moreau-Jean constrains the normal velocity at the
// midpoint, not the gap, and the second-order terms it drops (a kernel rocking on its flank
// rolls over a curved profile) move a pressed contact's gap by O(h^2) per step, down and up
// in turn as it rocks, with a net sinking: 2 um/s at h = 1 us, 0.8 mm over the 750 s long
// run. After the position update, every rigid contact that carried an impulse this step is
// evaluated at the end state. Its impact step records its depth (at least a slop: one step at
// the Zeno speed). Afterwards it is moved back to that depth when it sinks a slop deeper, and
// onto the surface when it rises half a slop above it while pressed, by the smallest mass-weighted
// position change along its normal; velocities are unchanged. Together with the activation
// of a pressed contact up to a slop of clearance (timeSteppingStep), a resting contact neither
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

// ---------------------------------------------------------------------------------------------
// The step's stages (timeSteppingStep below calls them in order).

// What one time step carries from stage to stage.
struct TsStep {
  const Model& m;
  Data* d;
  Workspace& ws;
  double h;                         // step length [s]
  Drive mid{}, end{};               // the drum at the step's midpoint and end
  double energy_before = 0.0;       // mechanical energy at the start, when known [J]
  double H_before = 0.0;            // the teeth's angular momentum at the start [kg m^2/s]
  bool have_energy_before = false;  // energy_before is the start's (else computed on need)
  double drive_work_before_J = 0;   // drive work at the start [J]
  double energy_net_before = 0;     // energy minus drive work at the start, when needed [J]
  double H_after = 0.0;             // angular momentum at the end [kg m^2/s]
  double energy_after = 0.0;        // mechanical energy at the end, once computed [J]
  bool have_energy_after = false;   // energy_after is computed
  bool solved = true;               // every contact problem of the step was solved

  PairMemory& memoryOf(size_t c) const { return ws.memory.entry(ws.ts.candidate_memory[c]).second; }
  // Energy minus drive work at the step end, the energy computed on first use.
  double energyNetAfter() {
    if (!have_energy_after) energy_after = energyOf(m, *d, d->z, d->u, d->omega_radps);
    have_energy_after = true;
    return energy_after - d->stats.drive_work_J;
  }
};

// Stage 1: the drum over the step (midpoint for forces and contacts, end for the new state),
// the iteration matrices, and the energy and angular momentum at the start: those the previous
// step ended with if the state is still exactly that one (the energy is O(kernels) to compute
// and only needed when an episode begins or ends: computed later only then).
void beginStep(TsStep* s) {
  const Model& m = s->m;
  Data* d = s->d;
  s->mid = driveAt(m, *d, 0.5 * s->h);
  s->end = driveAt(m, *d, s->h);
  updateIterationMatrices(m, s->mid.omega_radps, s->h, &s->ws);
  s->have_energy_before = s->ws.ts.end_values.lookup(*d, &s->energy_before, &s->H_before);
  if (!s->have_energy_before) s->H_before = angularMomentumOf(m, d->z, d->u, d->omega_radps);
  s->drive_work_before_J = d->stats.drive_work_J;
}

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

// Stage 8: the drive's work, Omega (change of the teeth's angular momentum - the contacts'
// angular impulse); then time and the drum advance, time kept on the grid of the model's step
// (no round-off drift).
void advanceClock(TsStep* s) {
  const Model& m = s->m;
  Data* d = s->d;
  const Workspace& ws = s->ws;
  double contact_angular_impulse = 0.0;
  for (int i = 0; i < static_cast<int>(ws.active.size()); ++i) {
    const ContactGeom& g = ws.geoms[ws.active[i]];
    if (g.pair.kind != PairKind::kToothKernel) continue;
    const Vec2& p = g.p0;
    contact_angular_impulse += -ws.lambda[2 * i] * (p.x() * g.n.y() - p.y() * g.n.x()) -
                               ws.lambda[2 * i + 1] * (p.x() * g.t.y() - p.y() * g.t.x());
  }
  s->H_after = angularMomentumOf(m, d->z, d->u, s->end.omega_radps);
  d->stats.drive_work_J +=
      s->mid.omega_radps * (s->H_after - s->H_before - contact_angular_impulse);
  d->t_s = s->end.t_s;
  const double grid = m.integrator.dt_s;
  const double snapped = std::round(d->t_s / grid) * grid;
  if (std::abs(snapped - d->t_s) < 1e-6 * grid) d->t_s = snapped;
  d->theta_rad = s->end.theta_rad;
  d->omega_radps = s->end.omega_radps;
  d->alpha_radps2 = s->end.alpha_radps2;
  ++d->steps;
}

// The impact event of a rigid contact's first step: its impulse is the impact.
void logRigidImpact(TsStep* s, const ContactGeom& g, const PairMemory& mem, int row,
                    double vt_after) {
  Data* d = s->d;
  const Workspace& ws = s->ws;
  ContactEvent ev;
  ev.t_s = d->t_s;
  ev.pair = g.pair;
  ev.from = ContactState::kSeparated;
  ev.to = ContactState::kImpact;
  ev.is_impact = true;
  ev.vn_before_mps = g.vn;
  ev.vt_before_mps = g.vt;
  ev.vn_after_mps = ws.y[2 * row] - ws.b_offset[row];
  ev.vt_after_mps = vt_after;
  ev.impulse_normal_Ns = ws.lambda[2 * row];
  ev.impulse_tangential_Ns = ws.lambda[2 * row + 1];
  ev.energy_lost_J = s->energy_net_before - s->energyNetAfter();
  ev.macro_collision = mem.macro_index;
  ev.sub_collision = mem.sub_index;
  d->events.push_back(ev);
  ++d->stats.impacts;
  const int kb = g.pair.kind == PairKind::kKernelObstacle ? g.pair.a : g.pair.b;
  ++d->stats.kernel_impacts[kb];
  if (g.pair.kind == PairKind::kKernelKernel) ++d->stats.kernel_impacts[g.pair.a];
  d->stats.max_energy_gain_at_impact_J =
      std::max(d->stats.max_energy_gain_at_impact_J, -ev.energy_lost_J);
}

// A touching pair (row `row` of the contact problem, impulses pn, pt): a new episode starts
// with an impact, then sticks or slips; its forces and impulses go to the statistics.
void updateTouchingPair(TsStep* s, const ContactGeom& g, PairMemory* mem, int row,
                        double vt_after) {
  const Model& m = s->m;
  Data* d = s->d;
  const double h = s->h;
  const double pn = s->ws.lambda[2 * row], pt = s->ws.lambda[2 * row + 1];
  const ContactState before = mem->state;
  if (before == ContactState::kSeparated) {
    mem->v_in_mps = std::max(-g.vn, 0.0);
    mem->hertz_K = g.hertz_K;
    beginEpisode(m, d, mem, g, d->t_s - h, s->energy_net_before);
  }
  const double mu = g.params->friction;
  const bool sticking = mu > 0.0 && std::abs(pt) < mu * pn * (1.0 - 1e-9);
  mem->state = before == ContactState::kSeparated
                   ? ContactState::kImpact
                   : (sticking || mu == 0.0 ? ContactState::kStick : ContactState::kSlip);
  if (mu == 0.0 && std::abs(vt_after) > m.integrator.zeno_velocity_mps)
    mem->state = ContactState::kSlip;
  if (before != ContactState::kSeparated && before != mem->state)
    emitTransition(d, g.pair, before, mem->state, d->t_s, g);
  if (before == ContactState::kSeparated && g.params->law == ContactLaw::kRigid)
    logRigidImpact(s, g, *mem, row, vt_after);
  mem->normal_force_N = pn / h;
  mem->tangential_force_N = pt / h;
  mem->impulse_n_acc += pn;
  mem->impulse_t_acc += pt;
  mem->episode_impulse_n += pn;
  mem->episode_impulse_t += pt;
  mem->episode_peak_N = std::max(mem->episode_peak_N, pn / h);
  d->stats.total_normal_impulse_Ns += pn;
  recordForce(m, d, g, pn / h, pt / h, d->t_s);
}

// Stage 9: contact states, episodes, events and statistics of every candidate pair. Pairs in
// contact at the previous step end are kept by this integrator in ws.ts.in_contact (pair-table
// indices). Any other history of the workspace (a reset, event-driven steps) leaves it stale:
// then every pair's memory is scanned once, as a rebuild.
void updateContactStates(TsStep* s) {
  const Model& m = s->m;
  Data* d = s->d;
  Workspace& ws = s->ws;
  std::vector<int>& in_contact = ws.ts.in_contact;
  if (ws.ts.in_contact_step != d->steps - 1) {
    in_contact.clear();
    for (size_t e = 0; e < ws.memory.size(); ++e) {
      PairMemory& mem = ws.memory.entry(static_cast<int>(e)).second;
      mem.seen = false;
      if (mem.state != ContactState::kSeparated) in_contact.push_back(static_cast<int>(e));
    }
  }
  const int k = static_cast<int>(ws.active.size());
  int ia = 0;
  for (size_t c = 0; c < ws.geoms.size(); ++c) {
    const ContactGeom& g = ws.geoms[c];
    PairMemory& mem = s->memoryOf(c);
    mem.seen = true;
    const bool is_active = ia < k && ws.active[ia] == static_cast<int>(c);
    const int row = is_active ? ia++ : -1;
    const double vt_after = is_active ? ws.y[2 * row + 1] : g.vt;
    if (is_active && ws.lambda[2 * row] > 0.0) {
      updateTouchingPair(s, g, &mem, row, vt_after);
    } else if (mem.state != ContactState::kSeparated) {
      ContactGeom g_end = g;
      g_end.vn = is_active ? ws.y[2 * row] - ws.b_offset[row] : g.vn;
      endEpisode(m, d, &mem, g_end, d->t_s, s->energyNetAfter());
    }
  }
  // Pairs that left the broad phase while in contact have separated (in pair-table order, the
  // order of a scan of the whole table).
  std::sort(in_contact.begin(), in_contact.end());
  for (int e : in_contact) {
    auto& kv = ws.memory.entry(e);
    PairMemory& mem = kv.second;
    if (mem.seen || mem.state == ContactState::kSeparated) continue;
    ContactGeom g_far;
    g_far.pair = PairId{static_cast<PairKind>(kv.first >> 60),
                        static_cast<int>((kv.first >> 30) & 0x3fffffff),
                        static_cast<int>(kv.first & 0x3fffffff)};
    g_far.params = &m.contact[static_cast<int>(g_far.pair.kind)];
    endEpisode(m, d, &mem, g_far, d->t_s, s->energyNetAfter());
  }
  // The candidates in contact now, for the next step; seen flags back to false.
  in_contact.clear();
  for (size_t c = 0; c < ws.candidates.size(); ++c) {
    PairMemory& mem = s->memoryOf(c);
    mem.seen = false;
    if (mem.state != ContactState::kSeparated) in_contact.push_back(ws.ts.candidate_memory[c]);
  }
  ws.ts.in_contact_step = d->steps;
}

// Stage 10: pedicels that reached their detachment force break; the end values for the next
// step (it starts from the end energy with the pedicels as they were before this step's
// breaks: if one breaks, that energy is computed now, the pedicels put back meanwhile); the
// contacts published to the data.
void finishStep(TsStep* s) {
  Data* d = s->d;
  Workspace& ws = s->ws;
  if (!s->have_energy_after) ws.ts.attached_before = d->kernel_attached;
  updatePedicels(s->m, d);
  if (!s->have_energy_after && d->kernel_attached != ws.ts.attached_before) {
    std::swap(d->kernel_attached, ws.ts.attached_before);
    s->energyNetAfter();
    std::swap(d->kernel_attached, ws.ts.attached_before);
  }
  if (s->have_energy_after)
    ws.ts.end_values.store(*d, s->energy_after, s->H_after);
  else
    ws.ts.end_values.invalidate();
  publishContacts(d, &ws);
}

}  // namespace

// One Moreau-Jean time step of length h.
StepStatus timeSteppingStep(const Model& m, Data* d, double h) {
  TsStep s{m, d, *d->ws, h, Drive{}, Drive{}};
  beginStep(&s);
  detectContacts(&s);
  freeVelocity(&s);
  assembleContactRows(&s);
  contactTargets(&s);
  solveImpulses(&s);
  applyImpulses(&s);
  advanceClock(&s);
  updateContactStates(&s);
  finishStep(&s);
  return s.solved ? StepStatus::kOk : StepStatus::kRecovered;
}

}  // namespace internal
}  // namespace threshing_sim
