// The contact phase's forces: the kick acceleration at the step's two ends (smooth forces less
// the modal teeth's linear part, which their propagator carries, plus the contact forces), the
// compliant normals by the sign of the gap, and the normal transitions found at the end.
#include <algorithm>
#include <cmath>
#include <cstring>

#include "contact_phase.h"

namespace threshing_sim {
namespace internal {
namespace contact_phase {

using event_driven::candidateMemory;
using event_driven::Ctx;
using event_driven::isActive;

namespace {

// The smooth forces' kick acceleration at (z, u) into *a: the kernels' gravity and pedicels;
// the modal teeth's linear forces belong to their propagator (zero here).
void smoothKick(const Ctx& c, const VecX& z, const VecX& u, const Drive& dr, VecX* a) {
  const Model& m = c.m;
  smoothForces(m, c.d, z, u, dr, &c.ws.forces);
  for (const ToothModel& tm : m.teeth) c.ws.forces.segment(tm.dof_offset, tm.n_modes).setZero();
  freeAcceleration(m, nullptr, c.ws.forces, a);
}

// A closed pair's forces at the start of the phase (no end values): the compliant law's normal,
// the friction its memory holds (the event-driven step's stick force, or mu fn sliding), within
// the cone.
Vec2 entryForces(const Model& m, const ContactGeom& g, const PairMemory& mem) {
  const double fn = compliantNormalForce(g, mem.hertz_K, mem.v_in_mps, m.hc_min_impact_speed_mps);
  const double mu = g.params->friction;
  double ft = mem.slip_sign != 0 ? -mem.slip_sign * mu * fn : mem.tangential_force_N;
  ft = std::clamp(ft, -mu * fn, mu * fn);
  return Vec2(fn, ft);
}

// Linear interpolation of the instant where v0 -> v1 crosses zero over [t0, t0 + h] [s].
double crossing(double t0_s, double h_s, double v0, double v1) {
  const double s = v0 != v1 ? v0 / (v0 - v1) : 1.0;
  return t0_s + h_s * std::clamp(s, 0.0, 1.0);
}

// Gauss-Seidel sweeps of the normal forces at the step end, and the iterations of one pair's
// solve [-].
constexpr int kNormalSweeps = 4;
constexpr int kNormalIterations = 30;

// Contact i's normal force at the step end, implicit in its own damping: the root F of
// F = max(0, f(gap, vn + h/2 W (F - F_now))), f the compliant law and W its normal compliance:
// the Hunt-Crossley damper reads the end's normal velocity, which the end's half kick of F
// itself changes (explicit, the damper would bound the step by m*/c; a pressed contact whose
// first touch was slow has a stiff damper). The residual r(F) = F - f rises at least as fast as
// F (f falls as vn rises with F), so from the present force F_now the root lies between F_now
// and F_now - r(F_now): a bracket as wide as the present residual, closed by secant steps kept
// inside it (bisection when one falls outside).
double implicitNormal(const Ctx& c, int r, double half_h_s, double K, double v_in_mps) {
  const Model& m = c.m;
  const ContactPhaseScratch& cp = c.ws.cp;
  const size_t i = static_cast<size_t>(cp.cs.cand[r]);
  const ContactGeom& g = c.ws.geoms[i];
  const double f_now = cp.fn1[i];
  const double vn_now = cp.cs.vn[r];
  const double w = cp.cs.W(2 * r, 3 * r);
  auto residual = [&](double F) {
    const double vn = vn_now + half_h_s * w * (F - f_now);
    return F - std::max(0.0, compliantNormalForceAt(g, g.gap_m, vn, K, v_in_mps,
                                                    m.hc_min_impact_speed_mps));
  };
  const double r_now = residual(f_now);
  if (r_now == 0.0) return f_now;
  double lo = f_now, r_lo = r_now, hi = f_now, r_hi = r_now;
  if (r_now < 0.0) {
    hi = f_now - r_now;
    r_hi = residual(hi);
  } else {
    lo = std::max(0.0, f_now - r_now);
    r_lo = residual(lo);
    if (r_lo > 0.0) return 0.0;  // (lo = 0: the contact carries no force at the end)
    if (r_lo == 0.0) return lo;
  }
  for (int it = 0; it < kNormalIterations && r_hi != 0.0 && hi - lo > 1e-13 * hi; ++it) {
    double F = lo - r_lo * (hi - lo) / (r_hi - r_lo);  // secant, kept inside the bracket
    if (!(F > lo && F < hi)) F = 0.5 * (lo + hi);
    const double r = residual(F);
    if (r < 0.0) {
      lo = F;
      r_lo = r;
    } else {
      hi = F;
      r_hi = r;
    }
  }
  return r_hi == 0.0 ? hi : lo - r_lo * (hi - lo) / (r_hi - r_lo);
}

// The normal forces at the step end, each implicit in its own damping (implicitNormal), the
// contacts that share a body by Gauss-Seidel sweeps; each change applied to the kick
// acceleration and the end velocity.
void solveNormals(const Ctx& c, const StepState& s) {
  Workspace& ws = c.ws;
  ContactPhaseScratch& cp = ws.cp;
  ContactPhaseScratch::ContactSpace& cs = cp.cs;
  const double half_h = 0.5 * s.h_s;
  const int k = static_cast<int>(cs.cand.size());
  int closed = 0;
  for (int r = 0; r < k; ++r) closed += cp.fn1[cs.cand[r]] > 0.0 ? 1 : 0;
  const int sweeps = closed <= 1 ? 1 : kNormalSweeps;  // one contact: solved by its first
  for (int sweep = 0; sweep < sweeps; ++sweep) {
    double largest = 0.0;
    for (int r = 0; r < k; ++r) {
      const size_t i = static_cast<size_t>(cs.cand[r]);
      if (cp.fn1[i] <= 0.0) continue;
      const ContactGeom& g = ws.geoms[i];
      const PairMemory& mem = candidateMemory(ws, i);
      const bool active = isActive(mem);
      const double f = implicitNormal(c, r, half_h, active ? mem.hertz_K : g.hertz_K,
                                      active ? mem.v_in_mps : cp.v_in_mps[i]);
      if (f == cp.fn1[i]) continue;
      largest = std::max(largest, std::abs(f - cp.fn1[i]) / cp.fn1[i]);
      const double dfr = residualForceFactor(g, f) - residualForceFactor(g, cp.fn1[i]);
      addForceChange(&cs, r, f - cp.fn1[i], 0.0, dfr, half_h);
      cp.fn1[i] = f;
    }
    if (largest <= 1e-12) break;
  }
}

}  // namespace

bool endValuesHold(const Ctx& c) {
  const ContactPhaseScratch& cp = c.ws.cp;
  const Data& d = c.d;
  if (!cp.end_valid || cp.end_t_s != d.t_s || cp.end_omega_radps != d.omega_radps) return false;
  if (cp.end_z.size() != d.z.size() || cp.end_u.size() != d.u.size()) return false;
  if (c.ws.geoms.size() != c.ws.candidates.size() || cp.end_candidates != c.ws.candidates)
    return false;
  const size_t bytes = sizeof(double) * static_cast<size_t>(d.z.size());
  return bytes == 0 || (std::memcmp(cp.end_z.data(), d.z.data(), bytes) == 0 &&
                        std::memcmp(cp.end_u.data(), d.u.data(), bytes) == 0);
}

double normalVelocity(const Model& m, const ContactGeom& g, const VecX& u, const VecX& u_eval) {
  double vn = g.vn;
  for (const BodyJac& b : g.side) {
    if (b.body < 0 || b.w_n.size() == 0) continue;
    const int off = bodyDofOffset(m, b.body);
    for (int j = 0; j < b.w_n.size(); ++j) vn += b.w_n[j] * (u[off + j] - u_eval[off + j]);
  }
  return vn;
}

void addContactAcceleration(const Model& m, const ContactGeom& g, double fn, double ft,
                            double scale, VecX* a) {
  const double fr = residualForceFactor(g, fn);
  for (const BodyJac& s : g.side) {
    applyInverseMass(m, nullptr, s.body, s.w_n, scale * fn, a);
    if (ft != 0.0) applyInverseMass(m, nullptr, s.body, s.w_t, scale * ft, a);
    if (fr != 0.0) applyInverseMass(m, nullptr, s.body, s.w_r, scale * fr, a);
  }
}

double drumTorque(const ContactGeom& g, double fn, double ft) {
  if (g.pair.kind != PairKind::kToothKernel) return 0.0;
  const Vec2& p = g.p0;
  return -fn * (p.x() * g.n.y() - p.y() * g.n.x()) - ft * (p.x() * g.t.y() - p.y() * g.t.x()) +
         residualForceFactor(g, fn) * g.residual_dtheta_mpNprad;
}

void startForces(const Ctx& c, StepState* s) {
  const Model& m = c.m;
  Workspace& ws = c.ws;
  ContactPhaseScratch& cp = ws.cp;
  const size_t n = ws.candidates.size();
  growTo(&cp.fn0, n);
  growTo(&cp.ft0, n);
  cp.gap0_m.resize(n);
  cp.vt0_mps.resize(n);
  (void)s;
  if (endValuesHold(c)) {  // (ws.geoms and cp.u_pred, where they were evaluated, hold too)
    std::swap(cp.a0, cp.a1);
    cp.fn0.head(n) = cp.fn1.head(n);
    cp.ft0.head(n) = cp.ft1.head(n);
  } else {
    const Drive dr = event_driven::driveAtTime(c, c.d.t_s);
    event_driven::evaluateAll(c, c.d.z, c.d.u, dr);
    cp.u_pred = c.d.u;
    smoothKick(c, c.d.z, c.d.u, dr, &cp.a0);
    for (size_t i = 0; i < n; ++i) {
      const ContactGeom& g = ws.geoms[i];
      const PairMemory& mem = candidateMemory(ws, i);
      const Vec2 f = isActive(mem) ? entryForces(m, g, mem) : Vec2::Zero();
      cp.fn0[i] = f[0];
      cp.ft0[i] = f[1];
      if (f[0] == 0.0 && f[1] == 0.0) continue;
      addContactAcceleration(m, g, f[0], f[1], 1.0, &cp.a0);
    }
  }
  cp.vn0_mps.resize(n);
  for (size_t i = 0; i < n; ++i) {
    const ContactGeom& g = ws.geoms[i];
    cp.gap0_m[i] = g.far ? std::numeric_limits<double>::infinity() : g.gap_m;
    cp.vn0_mps[i] = g.far ? 0.0 : normalVelocity(m, g, c.d.u, cp.u_pred);
  }
}

void startFriction(const Ctx& c, StepState* s) {
  Workspace& ws = c.ws;
  ContactPhaseScratch& cp = ws.cp;
  const double half_h = 0.5 * s->h_s;
  // The slip velocity at the start and its rate under the start's forces (before the projection
  // below), from which a slip's end inside the step is timed.
  const size_t n = ws.candidates.size();
  cp.at0_mps2.resize(n);
  for (size_t i = 0; i < n; ++i) {
    const ContactGeom& g = ws.geoms[i];
    double vt = g.vt, at = 0.0;
    for (const BodyJac& b : g.side) {
      if (b.body < 0 || b.w_t.size() == 0) continue;
      const int off = bodyDofOffset(c.m, b.body);
      for (int j = 0; j < b.w_t.size(); ++j) {
        vt += b.w_t[j] * (c.d.u[off + j] - cp.u_pred[off + j]);
        at += b.w_t[j] * cp.a0[off + j];
      }
    }
    cp.vt0_mps[i] = vt;
    cp.at0_mps2[i] = at;
  }
  // The drift changes a sticking contact's slip velocity at the rate measured over the last step
  // (the contact points' motion over the surfaces and with the drum, the tooth's free modes):
  // the first half kick aims at minus half the drift's change, so that the slip velocity after
  // the drift is plus half of it and each half kick's stick force holds half the drift, as the
  // constraint force does all through the step (aiming at zero leaves the whole drift to the
  // end's force: the stick force then alternates about the constraint's, or with the target
  // at the whole change, lags it by the drift's share).
  cp.vt_target.resize(n);
  for (size_t i = 0; i < n; ++i) {
    const PairMemory& mem = candidateMemory(ws, i);
    cp.vt_target[i] = isActive(mem) ? -0.5 * s->h_s * mem.cp_drift_mps2 : 0.0;
  }
  cp.u_drift = c.d.u + half_h * cp.a0;
  buildContactSpace(c, cp.fn0, cp.u_drift, cp.u_pred);
  projectFriction(c, half_h, cp.fn0, &cp.vt_target, &cp.ft0);
  applyContactSpace(c, half_h, &cp.a0, &cp.u_drift);
  cp.vt_half_mps.resize(n);
  for (size_t i = 0; i < n; ++i)
    cp.vt_half_mps[i] = slipVelocity(c.m, ws.geoms[i], cp.u_drift, cp.u_pred);
  s->torque0_Nm = 0.0;
  for (size_t i = 0; i < ws.candidates.size(); ++i)
    if (cp.fn0[i] != 0.0 || cp.ft0[i] != 0.0)
      s->torque0_Nm += drumTorque(ws.geoms[i], cp.fn0[i], cp.ft0[i]);
}

bool endForces(const Ctx& c, StepState* s) {
  const Model& m = c.m;
  Workspace& ws = c.ws;
  ContactPhaseScratch& cp = ws.cp;
  const double t1 = s->t0_s + s->h_s;
  const Drive dr = event_driven::driveAtTime(c, t1);
  // Separated pairs only as far as their sign over the next step needs: exact within what their
  // bodies can cover in two steps, else a bound of the gap.
  event_driven::evaluateAll(c, ws.ed.z1, cp.u_pred, dr, event_driven::SeparatedPairs::kReach,
                            2.0 * s->h_s);
  const size_t n = ws.candidates.size();
  // A rigid-law pair that closed: the adaptive step locates its impact.
  for (size_t i = 0; i < n; ++i) {
    const ContactGeom& g = ws.geoms[i];
    if (g.params->law == ContactLaw::kRigid && !g.far && g.gap_m < 0.0) return false;
  }
  smoothKick(c, ws.ed.z1, cp.u_pred, dr, &cp.a1);
  // The drift's change of each slip velocity, per second (startFriction's next target).
  cp.drift_rate_mps2.resize(n);
  for (size_t i = 0; i < n; ++i)
    cp.drift_rate_mps2[i] =
        (slipVelocity(m, ws.geoms[i], cp.u_drift, cp.u_pred) - cp.vt_half_mps[i]) / s->h_s;
  growTo(&cp.fn1, n);
  growTo(&cp.ft1, n);
  cp.opened.assign(n, 0);
  cp.released.assign(n, 0);
  cp.t_open_s.assign(n, t1);
  cp.v_in_mps.assign(n, 0.0);
  const double v_floor = m.hc_min_impact_speed_mps;
  for (size_t i = 0; i < n; ++i) {
    const ContactGeom& g = ws.geoms[i];
    const PairMemory& mem = candidateMemory(ws, i);
    cp.fn1[i] = cp.ft1[i] = 0.0;
    const bool active = isActive(mem);
    // A separated pair closes where its gap crosses zero over the step, approaching (as the
    // adaptive step's gap event fires); one that overlaps at both ends was released by its
    // damped force and stays open, without force, until its gap has opened (else it would close
    // again at once: a new impact at every other step, more the smaller the step).
    if (!active && (g.far || g.gap_m >= 0.0 || g.vn > 0.0 || cp.gap0_m[i] < 0.0)) continue;
    if (!active) {  // closed over the step: the approach speed at the crossing fixes the damping
      cp.opened[i] = 1;
      cp.t_open_s[i] = crossing(s->t0_s, s->h_s, cp.gap0_m[i], g.gap_m);
      const double frac = (cp.t_open_s[i] - s->t0_s) / s->h_s;
      cp.v_in_mps[i] =
          std::isfinite(cp.gap0_m[i]) ? -(cp.vn0_mps[i] + frac * (g.vn - cp.vn0_mps[i])) : -g.vn;
    }
    const double K = active ? mem.hertz_K : g.hertz_K;
    const double v_in = active ? mem.v_in_mps : cp.v_in_mps[i];
    const double f = compliantNormalForceSigned(g, K, v_in, v_floor);
    // A contact opens where its gap does; while the bodies overlap, a damped force that would
    // pull is no force (the law's clamp) and the contact stays closed (opened at the clamp at a
    // step end and closed again as soon as the bodies approach, a resting or pressed contact
    // would count an impact at every other step, more the smaller the step).
    if (active && (g.far || g.gap_m > 0.0)) {  // opened over the step
      cp.released[i] = 1;
      cp.t_open_s[i] = crossing(s->t0_s, s->h_s, cp.gap0_m[i], g.gap_m);
      continue;
    }
    cp.fn1[i] = std::max(f, 0.0);
    addContactAcceleration(m, g, cp.fn1[i], 0.0, 1.0, &cp.a1);
  }
  cp.u_end = cp.u_drift + (0.5 * s->h_s) * cp.a1;
  // Normal and friction forces are coupled through the end velocity (a kernel's turn, the
  // contact frame): the normals again after the friction, then the friction after them; all in
  // contact space, applied to the end's acceleration and velocity once.
  buildContactSpace(c, cp.fn1, cp.u_end, cp.u_pred);
  solveNormals(c, *s);
  solveFriction(c, *s);
  solveNormals(c, *s);
  projectFriction(c, 0.5 * s->h_s, cp.fn1, nullptr, &cp.ft1);
  applyContactSpace(c, 0.5 * s->h_s, &cp.a1, &cp.u_end);
  s->torque1_Nm = 0.0;
  for (size_t i = 0; i < n; ++i)
    if (cp.fn1[i] != 0.0 || cp.ft1[i] != 0.0)
      s->torque1_Nm += drumTorque(ws.geoms[i], cp.fn1[i], cp.ft1[i]);
  return true;
}

}  // namespace contact_phase
}  // namespace internal
}  // namespace threshing_sim
