// The event-driven integrator's contact modes: the contacts opened at a step start (stage 2),
// the index sets switched by the events that fired (stage 10), and the consistent modes from an
// acceleration-level complementarity problem (updateModes).
#include <algorithm>
#include <cmath>
#include <vector>

#include "context.h"

namespace threshing_sim {
namespace internal {
namespace event_driven {

namespace {

// The rows of the mode problem, into ws.active / ws.rows: contacts in compliant contact (a
// known normal) and closed rigid ones; a sliding contact keeps its direction, a slow one may
// stick, one in forced_slip slides as its memory says.
void assembleModeRows(const Ctx& c, const std::vector<int>& forced_slip) {
  const Model& m = c.m;
  Workspace& ws = c.ws;
  const double v_eps = m.integrator.zeno_velocity_mps;
  ws.active.clear();
  ws.rows.clear();
  for (size_t i = 0; i < ws.geoms.size(); ++i) {
    const ContactGeom& g = ws.geoms[i];
    PairMemory& mem = ws.memory[pairKey(g.pair)];
    if (!isActive(mem)) continue;
    ContactRow row;
    row.mu = g.params->friction;
    if (g.params->law == ContactLaw::kCompliant) {
      row.normal_unknown = false;
      row.lambda_n_fixed =
          compliantNormalForce(g, mem.hertz_K, mem.v_in_mps, m.hc_min_impact_speed_mps);
    } else if (!mem.closed) {
      continue;
    }
    // Sliding contacts keep their direction; slow ones may stick.
    const bool forced =
        std::find(forced_slip.begin(), forced_slip.end(), static_cast<int>(i)) != forced_slip.end();
    if (forced) {
      row.slip_sign = mem.slip_sign;
    } else {
      row.slip_sign = std::abs(g.vt) > v_eps ? (g.vt > 0 ? 1 : -1) : 0;
      mem.slip_from_stick = false;  // the mode problem decides afresh
    }
    if (row.mu == 0) row.slip_sign = 0;
    ws.active.push_back(static_cast<int>(i));
    ws.rows.push_back(row);
  }
}

// The free relative accelerations of the rows (Jacobians times ws.du plus the velocity drift)
// into ws.b.
void modeTargets(const Ctx& c, const Drive& dr) {
  const Model& m = c.m;
  Workspace& ws = c.ws;
  const Data& d = c.d;
  const int k = static_cast<int>(ws.active.size());
  growTo(&ws.b, 2 * k);
  for (int i = 0; i < k; ++i) {
    const ContactGeom& g = ws.geoms[ws.active[i]];
    const Vec2 drift = contactVelocityDrift(m, d.z, d.u, dr, g, &ws);
    double an = drift[0], at = drift[1];
    for (const BodyJac& s : g.side) {
      if (s.body < 0 || s.w_n.size() == 0) continue;
      const auto ab = ws.du.segment(bodyDofOffset(m, s.body), s.w_n.size());
      an += s.w_n.dot(ab);
      at += s.w_t.dot(ab);
    }
    ws.b[2 * i] = an;
    ws.b[2 * i + 1] = at;
  }
}

// The modes of the solved rows at time t: a rigid normal whose multiplier vanished with a
// separating acceleration opens; the others stick or slip (transitions reported).
void assignModes(const Ctx& c, double t, const Drive& dr) {
  const Model& m = c.m;
  Workspace& ws = c.ws;
  Data& d = c.d;
  const double v_eps = m.integrator.zeno_velocity_mps;
  const int k = static_cast<int>(ws.active.size());
  for (int i = 0; i < k; ++i) {
    const ContactGeom& g = ws.geoms[ws.active[i]];
    const ContactRow& row = ws.rows[i];
    PairMemory& mem = ws.memory[pairKey(g.pair)];
    const double fn = ws.lambda[2 * i], ft = ws.lambda[2 * i + 1];
    const ContactState before = mem.state;
    if (row.normal_unknown && fn <= 0.0 && ws.y[2 * i] > 0.0) {
      // The normal multiplier vanished with a separating acceleration: the contact opens.
      endEpisode(m, &d, &mem, g, t,
                 energyOf(m, d, d.z, d.u, dr.omega_radps) - d.stats.drive_work_J);
      continue;
    }
    if (row.mu == 0.0) {
      mem.slip_sign = 0;
      mem.state = std::abs(g.vt) > v_eps ? ContactState::kSlip : ContactState::kStick;
    } else if (row.slip_sign != 0) {
      mem.slip_sign = row.slip_sign;
      mem.state = ContactState::kSlip;
    } else if (std::abs(ft) < row.mu * fn * (1.0 - 1e-9)) {
      mem.slip_sign = 0;
      mem.state = ContactState::kStick;
    } else {
      // At the friction limit the contact slides the way the tangential acceleration points.
      mem.slip_sign = ft > 0 ? -1 : 1;
      mem.state = ContactState::kSlip;
    }
    if (before != mem.state && before != ContactState::kImpact)
      emitTransition(&d, g.pair, before, mem.state, t, g);
  }
}

}  // namespace

// Chooses stick / slip / separation for every active contact from an acceleration-level
// complementarity problem over the closed rigid normals and the stick-capable tangents.
// Returns false if that problem has no solution found (Painleve); the caller then applies a
// tangential impact.
bool updateModes(const Ctx& c, double t, const std::vector<int>& forced_slip) {
  const Model& m = c.m;
  Workspace& ws = c.ws;
  Data& d = c.d;
  const Drive dr = driveAtTime(c, t);
  smoothForces(m, d, d.z, d.u, dr, &ws.forces);
  evaluateAll(c, d.z, d.u, dr);
  const std::vector<MatX>* minv = toothInverseMass(m, d.z, &ws);
  // The free accelerations Minv f of the smooth forces (as rhs() computes them).
  freeAcceleration(m, minv, ws.forces, &ws.du);
  assembleModeRows(c, forced_slip);
  modeTargets(c, dr);
  if (!solveContactIslands(m, minv, &ws)) return false;
  assignModes(c, t, dr);
  return true;
}

// Stage 2: pairs touching at the start of the step without being in contact (a scene that
// starts at rest on a plate, a reset, a contact closed by the previous event) begin a contact
// now, unless they are separating.
void openTouchingContacts(const Ctx& c) {
  const Model& m = c.m;
  Data* d = &c.d;
  Workspace& ws = c.ws;
  const Drive dr0 = driveAtTime(c, d->t_s);
  // (The last step's end, evaluated by its statistics, is this state.)
  if (!rhsMemoHit(c, dr0, d->z, d->u, SeparatedPairs::kNear, 0.0)) evaluateAll(c, d->z, d->u, dr0);
  bool rigid_touch = false, any_touch = false;
  double e_net = kInf;  // energy minus drive work, computed when a contact begins
  for (size_t i = 0; i < ws.geoms.size(); ++i) {
    const ContactGeom& g = ws.geoms[i];
    PairMemory& mem = ws.memory[pairKey(g.pair)];
    if (isActive(mem) || g.far || g.gap_m > 0.0 || g.vn > 0.0) continue;
    if (releasedAt(mem, *g.params, d->t_s)) continue;  // no approach (see releasedAt)
    any_touch = true;
    if (g.params->law == ContactLaw::kRigid) {
      rigid_touch = true;
    } else {
      if (e_net == kInf) e_net = mechanicalEnergy(m, *d) - d->stats.drive_work_J;
      mem.v_in_mps = -g.vn;
      mem.hertz_K = g.hertz_K;
      beginEpisode(m, d, &mem, g, d->t_s, e_net);
      mem.state = ContactState::kImpact;
      mem.slip_sign = 0;
      emitTransition(d, g.pair, ContactState::kSeparated, ContactState::kImpact, d->t_s, g);
    }
  }
  if (rigid_touch) solveImpact(c, d->t_s, false);
  if (any_touch && !updateModes(c, d->t_s, {})) {
    solveImpact(c, d->t_s, true);
    if (!updateModes(c, d->t_s, {})) ++d->stats.numerical_recoveries;
  }
}

namespace {

// Stage 10 for one pair: the transition of its index sets for the event functions that fired
// (gap j, normal force j + 1, friction limit or slip velocity j + 2). Sets *rigid_impact for a
// rigid pair that closed; adds a pair that starts to slip to forced_slip.
void switchPair(const Ctx& c, size_t i, double e_net, bool* rigid_impact,
                std::vector<int>* forced_slip) {
  const Model& m = c.m;
  Data* d = &c.d;
  Workspace& ws = c.ws;
  const double t = d->t_s;
  const size_t j = 4 * i;
  auto fired = [&](size_t k) {
    return armFires(static_cast<Arm>(ws.ed.arm[k]), ws.ed.ev1[k], ws.ed.ev0[k]);
  };
  const ContactGeom& g = ws.geoms[i];
  PairMemory& mem = ws.memory[pairKey(g.pair)];
  const bool fired0 = fired(j), fired1 = fired(j + 1), fired2 = fired(j + 2);
  if (!isActive(mem)) {
    if (!fired0 || g.vn >= 0) return;
    if (g.params->law == ContactLaw::kRigid) {
      *rigid_impact = true;
    } else {
      // Compliant: the contact opens with its approach speed fixing the damping.
      mem.v_in_mps = -g.vn;
      mem.hertz_K = g.hertz_K;
      beginEpisode(m, d, &mem, g, t, e_net);
      mem.state = ContactState::kImpact;
      mem.slip_sign = 0;
      emitTransition(d, g.pair, ContactState::kSeparated, ContactState::kImpact, t, g);
    }
  } else if (g.params->law == ContactLaw::kCompliant && (fired0 || fired1)) {
    endEpisode(m, d, &mem, g, t, e_net);
  } else if (g.params->law == ContactLaw::kRigid && fired0) {
    endEpisode(m, d, &mem, g, t, e_net);
  } else if (fired2) {
    if (mem.slip_sign == 0) {
      // Stick -> slip against the friction force.
      mem.slip_sign = mem.tangential_force_N > 0 ? -1 : 1;
      mem.slip_from_stick = true;
      forced_slip->push_back(static_cast<int>(i));
      emitTransition(d, g.pair, mem.state, ContactState::kSlip, t, g);
      mem.state = ContactState::kSlip;
    } else {
      // Slip velocity reached zero: stick or reverse, decided below.
      mem.slip_sign = 0;
    }
  }
}

}  // namespace

// Stage 10: switch the index sets for every event function at or past zero; solve the rigid
// impacts; break the pedicels that reached their detachment force; new consistent modes.
void switchModes(const Ctx& c, const StepPlan& plan) {
  Data* d = &c.d;
  Workspace& ws = c.ws;
  if (!plan.event) {
    updatePedicels(c.m, d);
    return;
  }
  const double t = d->t_s;
  const double e_net = mechanicalEnergy(c.m, *d) - d->stats.drive_work_J;
  bool rigid_impact = false;
  std::vector<int>& forced_slip = ws.ed.forced_slip;
  forced_slip.clear();
  for (size_t i = 0; i < ws.geoms.size(); ++i) {
    const size_t j = 4 * i;
    if (static_cast<Arm>(ws.ed.arm[j]) == Arm::kOff &&
        static_cast<Arm>(ws.ed.arm[j + 1]) == Arm::kOff &&
        static_cast<Arm>(ws.ed.arm[j + 2]) == Arm::kOff)
      continue;
    switchPair(c, i, e_net, &rigid_impact, &forced_slip);
  }
  if (rigid_impact) solveImpact(c, t, false);
  updatePedicels(c.m, d);
  if (!updateModes(c, t, forced_slip)) {
    // Painleve: no consistent accelerations; a tangential (plastic) impact resolves it.
    solveImpact(c, t, true);
    if (!updateModes(c, t, forced_slip)) ++d->stats.numerical_recoveries;
  }
}

}  // namespace event_driven
}  // namespace internal
}  // namespace threshing_sim
