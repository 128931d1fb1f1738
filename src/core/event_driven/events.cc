// The event-driven integrator's events: the event functions, their arming over a step (stage
// 4), detection of sign changes and grazes (stage 6) and location of the first (stage 7).
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

#include "context.h"

namespace threshing_sim {
namespace internal {
namespace event_driven {

// Event functions: positive while the current index sets stay valid. Fills vals in the
// order of ws.geoms (4 per pair) followed by one per kernel (pedicel). Uses the forces the
// last rhs() call stored for (z, u) at time t. If rates is given it receives the time
// derivative of each function where it is known cheaply (the gap functions: +-dg_N/dt of a
// pair whose geometry was evaluated in full) and NaN elsewhere [unit of the function / s].
// horizon_s is the length of the step these values bound [s]: every separated pair that could
// close within it gets its exact gap and rate (evaluateAll). separated: kSign, or kStepEnd at a
// step's end (the same values for every pair kSign evaluates exactly).
void eventValues(const Ctx& c, double t, const VecX& z, const VecX& u, std::vector<double>* vals,
                 std::vector<double>* rates, double horizon_s, SeparatedPairs separated) {
  const Model& m = c.m;
  Workspace& ws = c.ws;
  double torque;
  rhs(c, t, z, u, &ws.ed.udot_ev, &torque, true, separated, horizon_s);
  vals->assign(4 * ws.geoms.size() + m.kernels.size(), 1.0);
  if (rates) rates->assign(vals->size(), std::numeric_limits<double>::quiet_NaN());
  for (size_t i = 0; i < ws.geoms.size(); ++i) {
    const ContactGeom& g = ws.geoms[i];
    const PairMemory& mem = candidateMemory(ws, i);
    double* v = &(*vals)[4 * i];
    if (!isActive(mem)) {
      // Separated: the gap closes (a rigid contact released at the step start: below the
      // position error scale; see releasedAt).
      v[0] =
          releasedAt(mem, *g.params, c.d.t_s) ? g.gap_m + m.integrator.tolerance * 1e-2 : g.gap_m;
      if (rates && !g.far) (*rates)[4 * i] = g.vn;
      continue;
    }
    const double mu = g.params->friction;
    const double fn = mem.normal_force_N, ft = mem.tangential_force_N;
    if (g.params->law == ContactLaw::kCompliant) {
      // Compliant: the bodies part, or the damped force would pull.
      v[0] = -g.gap_m;
      if (rates) (*rates)[4 * i] = -g.vn;
      const double delta = std::max(-g.gap_m, 0.0);
      v[1] = g.residual_mpN > 0.0
                 ? compliantNormalForceSigned(g, mem.hertz_K, mem.v_in_mps,
                                              m.hc_min_impact_speed_mps) /
                       std::max(1.0, mem.hertz_K * 1e-9)
                 : mem.hertz_K * delta * std::sqrt(delta) *
                       (1.0 - g.params->hc_damping_factor /
                                  std::max(mem.v_in_mps, m.hc_min_impact_speed_mps) * g.vn) /
                       std::max(1.0, mem.hertz_K * 1e-9);
    } else {
      // Rigid: the normal multiplier falls to zero.
      v[0] = fn;
    }
    if (mu > 0) {
      // Stick: the friction limit is reached. Slip: the sliding velocity reverses (a slip begun
      // from stick: past the velocity error scale, see slipReversalScale).
      v[2] = mem.slip_sign == 0 ? mu * fn - std::abs(ft)
                                : mem.slip_sign * g.vt +
                                      (mem.slip_from_stick ? slipReversalScale(m.integrator) : 0.0);
    }
  }
  for (size_t i = 0; i < m.kernels.size(); ++i) {
    const KernelModel& k = m.kernels[i];
    if (!k.pedicel.present || !c.d.kernel_attached[i]) continue;
    Vec2 p;
    (*vals)[4 * ws.geoms.size() + i] =
        k.pedicel.detachment_force_N - pedicelForce(m, z, u, static_cast<int>(i), t, &p).norm();
  }
}

// Interior minimum of the cubic Hermite interpolant of a function over a step of length h [s],
// from its values g0, g1 and rates r0 < 0 < r1 at the ends: returns the value and sets s_min,
// the position in (0, 1) as a fraction of h.
double hermiteMinimum(double g0, double r0, double g1, double r1, double h, double* s_min) {
  // p(s) = c0 + c1 s + c2 s^2 + c3 s^3 on s in [0, 1].
  const double c1 = h * r0;
  const double c2 = 3.0 * (g1 - g0) - 2.0 * h * r0 - h * r1;
  const double c3 = 2.0 * (g0 - g1) + h * r0 + h * r1;
  // p'(0) < 0 < p'(1): bisection on p' (60 halvings, exact to round-off, deterministic).
  double lo = 0.0, hi = 1.0;
  for (int it = 0; it < 60; ++it) {
    const double s = 0.5 * (lo + hi);
    (c1 + s * (2.0 * c2 + 3.0 * c3 * s) < 0 ? lo : hi) = s;
  }
  *s_min = 0.5 * (lo + hi);
  return g0 + *s_min * (c1 + *s_min * (c2 + *s_min * c3));
}

namespace {

// Whether any armed function fired at values b (ws.ed.arm, start values ws.ed.ev0); function
// `deep` (if given) only counts when it went below -depth.
bool anyFired(const Workspace& ws, const std::vector<double>& b, size_t deep = SIZE_MAX,
              double depth = 0) {
  if (b.size() != ws.ed.ev0.size()) return false;
  for (size_t i = 0; i < b.size(); ++i)
    if (armFires(static_cast<Arm>(ws.ed.arm[i]), i == deep ? b[i] + depth : b[i], ws.ed.ev0[i]))
      return true;
  return false;
}

// Earliest crossing in (lo, hi) of the armed functions that fired at hi, by linear
// interpolation of their values (v_lo, v_hi) weighted by (w_lo, w_hi); *sel receives the
// function. The midpoint (and *sel = -1) where a fired function has no positive value at lo
// (armed below its start, at the start itself) or no crossing inside.
double earliestCrossing(const Workspace& ws, double lo, double hi, const std::vector<double>& v_lo,
                        const std::vector<double>& v_hi, double w_lo, double w_hi, int* sel) {
  const std::vector<double>& ev0 = ws.ed.ev0;
  double x = hi;
  *sel = -1;
  for (size_t i = 0; i < v_hi.size(); ++i) {
    const Arm a = static_cast<Arm>(ws.ed.arm[i]);
    if (a == Arm::kOff || !armFires(a, v_hi[i], ev0[i])) continue;
    const double f_lo = w_lo * armValue(a, v_lo[i], ev0[i]);
    const double f_hi = w_hi * armValue(a, v_hi[i], ev0[i]);
    if (!(f_lo > 0) || !(f_lo - f_hi > 0)) {
      *sel = -1;
      return 0.5 * (lo + hi);
    }
    const double xi = lo + (hi - lo) * (f_lo / (f_lo - f_hi));
    if (xi < x) {
      x = xi;
      *sel = static_cast<int>(i);
    }
  }
  if (!(x > lo)) {
    *sel = -1;
    return 0.5 * (lo + hi);
  }
  return x;
}

// Locates the first event of a step from the data's time: some armed function (ws.ed.arm,
// values ws.ed.ev0 at the start) has fired at step length hi_s (values ev_hi; its state, impulses
// and torque impulse in ws.ed.z_hi, ...) and none at 0. Narrows the bracket [lo, hi] until
// hi - lo <= t_tol by re-stepping from the start: Illinois regula falsi on the function
// that fired earliest by linear interpolation, bisection when a fired function has no positive
// value at lo (an armed-below-start function at the start) or the bracket stopped halving;
// trial points keep t_tol / 2 from the ends so that the bracket closes from both sides. Sets
// *h_take to hi, with its state in ws.ed.z_hi, ws.ed.u_hi, ws.ed.imp_n_hi, ws.ed.imp_t_hi,
// ws.ed.torque_impulse_hi and its values in ws.ed.ev_hi; returns whether the last evaluation
// (ws.geoms, forces) was at hi.
bool locateEvent(const Ctx& c, double hi_s, const std::vector<double>& ev_hi, double t_tol,
                 double* h_take) {
  Workspace& ws = c.ws;
  const std::vector<double>& ev0 = ws.ed.ev0;
  const std::vector<std::uint8_t>& arm = ws.ed.arm;
  std::vector<double>& v_lo = ws.ed.ev_lo;
  std::vector<double>& v_hi = ws.ed.ev_hi;
  std::vector<double>& v_mid = ws.ed.evm;
  v_lo = ev0;
  v_hi = ev_hi;
  double lo = 0, hi = hi_s;
  double w_lo = 1, w_hi = 1;  // Anderson-Bjorck weights of the end values
  int kept = 0;               // +1: lo kept by the last step, -1: hi kept, 0: neither yet
  double width_before[3] = {kInf, kInf, kInf};  // bracket widths one to three steps back
  bool at_hi = true;
  double err, tq;
  for (int it = 0; it < 80 && hi - lo > t_tol; ++it) {
    // Trial point: the earliest linear-interpolated crossing of the fired functions.
    int sel = -1;  // the function that gave it
    double x = hi - lo > 0.5 * width_before[2]
                   ? 0.5 * (lo + hi)
                   : earliestCrossing(ws, lo, hi, v_lo, v_hi, w_lo, w_hi, &sel);
    x = std::clamp(x, lo + 0.5 * t_tol, hi - 0.5 * t_tol);
    width_before[2] = width_before[1];
    width_before[1] = width_before[0];
    width_before[0] = hi - lo;
    dopriStep(c, c.d.t_s, x, c.d.z, c.d.u, &ws.ed.zt, &ws.ed.ut, &err, &tq);
    eventValues(c, c.d.t_s + x, ws.ed.zt, ws.ed.ut, &v_mid);
    bool fired = false;
    for (size_t i = 0; i < v_mid.size() && v_mid.size() == ev0.size() && !fired; ++i)
      fired = armFires(static_cast<Arm>(arm[i]), v_mid[i], ev0[i]);
    // Anderson-Bjorck: an end kept twice in a row has its value scaled by 1 - f_new / f_old
    // (of the replaced end; 1/2 where that is not positive or no function was selected).
    auto scale = [&](const std::vector<double>& v_old) {
      if (sel < 0 || v_mid.size() != ev0.size()) return 0.5;
      const Arm a = static_cast<Arm>(arm[sel]);
      const double ratio = armValue(a, v_mid[sel], ev0[sel]) / armValue(a, v_old[sel], ev0[sel]);
      const double m = 1.0 - ratio;
      return m > 0 && m < 1 ? m : 0.5;
    };
    if (fired) {
      if (kept == 1) w_lo *= scale(v_hi);
      hi = x;
      v_hi = v_mid;
      ws.ed.z_hi = ws.ed.zt;
      ws.ed.u_hi = ws.ed.ut;
      ws.ed.imp_n_hi = ws.ed.imp_n;
      ws.ed.imp_t_hi = ws.ed.imp_t;
      ws.ed.torque_impulse_hi = ws.ed.torque_impulse;
      w_hi = 1;
      kept = 1;
    } else {
      if (kept == -1) w_hi *= scale(v_lo);
      lo = x;
      v_lo = v_mid;
      w_lo = 1;
      kept = -1;
    }
    at_hi = fired;
  }
  *h_take = hi;
  return at_hi;
}

// Whether event function k is the slip-velocity function s vt of a sliding contact (slip sign
// s != 0, friction on): at or below zero at a step start only when its slip began at the
// friction limit with vt at round-off.
bool startsSliding(const Workspace& ws, size_t k) {
  const size_t i = k / 4;
  if (k % 4 != 2 || i >= ws.geoms.size()) return false;
  const ContactGeom& g = ws.geoms[i];
  const PairMemory* mem = ws.memory.find(pairKey(g.pair));
  return mem && isActive(*mem) && g.params->friction > 0 && mem->slip_sign != 0;
}

}  // namespace

// Stage 4: event values at the start of the step, and which of them are armed over it. A
// function positive at the start fires when it reaches zero. A gap function at or below zero
// whose rate points to positive (a pair that just bounced apart, a compliant contact that just
// closed) is armed as well: it fires when it falls below its start value again, so that a
// flight shorter than the step is not seen one step late, inside the plate. So is the
// slip-velocity function s vt of a sliding contact at or below zero: a slip that began at the
// friction limit (from stick, or from a slip velocity that reached zero) starts with vt at
// round-off, possibly on the wrong side of its slip sign s; its next reversal must still fire.
void armEvents(const Ctx& c, StepPlan* plan) {
  Workspace& ws = c.ws;
  const Data& d = c.d;
  eventValues(c, d.t_s, d.z, d.u, &ws.ed.ev0, &ws.ed.rate0, plan->h_s);
  // Compliant normal forces and their rates at the start, for the located peaks.
  plan->peaks_on = compliantForceSnapshot(c, d.t_s, d.z, d.u, ws.ed.udot_ev, &ws.ed.pk_f0,
                                          &ws.ed.pk_r0, &ws.ed.pk_on);
  const std::vector<double>& ev0 = ws.ed.ev0;
  ws.ed.arm.assign(ev0.size(), static_cast<std::uint8_t>(Arm::kOff));
  for (size_t i = 0; i < ev0.size(); ++i) {
    if (ev0[i] > 0) {
      ws.ed.arm[i] = static_cast<std::uint8_t>(Arm::kAtZero);
    } else if (ws.ed.rate0[i] > 0 || startsSliding(ws, i)) {  // NaN (rate unknown) stays off
      ws.ed.arm[i] = static_cast<std::uint8_t>(Arm::kBelowStart);
    }
  }
}

// Stage 6a: grazes. A separated pair whose gap falls and rises again within the step shows no
// sign change at the ends. The cubic Hermite interpolant of the gap (values and rates at both
// ends) predicts the interior minimum; where it comes near zero the state there is computed (a
// step from the start) and the gap checked. A dip counts once it is deeper than the position
// error scale of the integrator (tolerance x 1e-2 m): shallower ones are below what the step
// resolves, and a path that exactly touches gives no contact.
void detectGrazes(const Ctx& c, StepPlan* plan) {
  Workspace& ws = c.ws;
  const Data& d = c.d;
  const std::vector<double>& ev0 = ws.ed.ev0;
  const std::vector<double>& ev1 = ws.ed.ev1;
  const double h = plan->h_s;
  const double depth_m = c.m.integrator.tolerance * 1e-2;
  double et, tq;
  for (size_t i = 0; i < ws.geoms.size() && !plan->event; ++i) {
    const size_t j = 4 * i;
    if (static_cast<Arm>(ws.ed.arm[j]) != Arm::kAtZero || isActive(candidateMemory(ws, i)))
      continue;
    if (!(ws.ed.rate0[j] < 0 && ws.ed.rate1[j] > 0)) continue;  // no interior minimum
    double s_min = 0;
    const double g_min = hermiteMinimum(ev0[j], ws.ed.rate0[j], ev1[j], ws.ed.rate1[j], h, &s_min);
    if (!(g_min < std::max(depth_m, 1e-3 * (ev0[j] + ev1[j])))) continue;
    // The probe step overwrites the step's contact impulses and drum torque impulse; they are
    // restored unless the event is confirmed (then the located step recomputes them).
    ws.ed.imp_n_saved = ws.ed.imp_n;
    ws.ed.imp_t_saved = ws.ed.imp_t;
    const double torque_impulse_saved = ws.ed.torque_impulse;
    plan->end_evaluated = false;
    dopriStep(c, d.t_s, s_min * h, d.z, d.u, &ws.ed.zt, &ws.ed.ut, &et, &tq);
    eventValues(c, d.t_s + s_min * h, ws.ed.zt, ws.ed.ut, &ws.ed.evm);
    if (anyFired(ws, ws.ed.evm, j, depth_m)) {
      plan->event = true;
      plan->h_fired_s = s_min * h;
    } else {
      ws.ed.imp_n = ws.ed.imp_n_saved;
      ws.ed.imp_t = ws.ed.imp_t_saved;
      ws.ed.torque_impulse = torque_impulse_saved;
    }
  }
}

// Stage 6: did any event function fire over the step (a sign change at the end, or a graze
// inside)? The end is evaluated as a step end (kStepEnd) over the longest next step, so that,
// when no event moves it, the statistics, the published contacts and the next step's event
// functions at its start reuse this evaluation.
void detectEvents(const Ctx& c, StepPlan* plan) {
  Workspace& ws = c.ws;
  const int n = c.m.n_dof;
  const double horizon_s = stepEndHorizon(ws, std::max(plan->h_s, plan->h_next_s));
  eventValues(c, c.d.t_s + plan->h_s, ws.ed.z1, ws.ed.u1, &ws.ed.ev1, &ws.ed.rate1, horizon_s,
              SeparatedPairs::kStepEnd);
  plan->h_take_s = plan->h_s;
  plan->h_fired_s = plan->h_s;
  plan->event = anyFired(ws, ws.ed.ev1);
  ws.ed.zt.resize(n);
  ws.ed.ut.resize(n);
  plan->end_evaluated = true;
  if (!plan->event && ws.ed.ev1.size() == ws.ed.ev0.size()) detectGrazes(c, plan);
}

// Stage 7: the first crossing (re-stepping from the start each time) to the tolerance, from
// the values at the fired end (ws.ed.ev1, or the graze probe's); the step's end state, impulses
// and end values become the located ones.
void locateFirstEvent(const Ctx& c, StepPlan* plan) {
  Workspace& ws = c.ws;
  const double t_tol = std::max(1e-15, 1e-3 * c.m.integrator.tolerance * 1e-3);
  const bool at_end = plan->h_fired_s == plan->h_s;
  ws.ed.z_hi = at_end ? ws.ed.z1 : ws.ed.zt;
  ws.ed.u_hi = at_end ? ws.ed.u1 : ws.ed.ut;
  ws.ed.imp_n_hi = ws.ed.imp_n;  // the step's, or the confirmed graze probe's
  ws.ed.imp_t_hi = ws.ed.imp_t;
  ws.ed.torque_impulse_hi = ws.ed.torque_impulse;
  const bool at_hi =
      locateEvent(c, plan->h_fired_s, at_end ? ws.ed.ev1 : ws.ed.evm, t_tol, &plan->h_take_s);
  // The state at the located end, and its values (geometry and forces) unless the last
  // evaluation was there.
  ws.ed.z1 = ws.ed.z_hi;
  ws.ed.u1 = ws.ed.u_hi;
  ws.ed.imp_n = ws.ed.imp_n_hi;
  ws.ed.imp_t = ws.ed.imp_t_hi;
  ws.ed.torque_impulse = ws.ed.torque_impulse_hi;
  if (at_hi) {
    ws.ed.ev1 = ws.ed.ev_hi;
  } else {
    eventValues(c, c.d.t_s + plan->h_take_s, ws.ed.z1, ws.ed.u1, &ws.ed.ev1);
  }
  plan->end_evaluated = true;
}

}  // namespace event_driven
}  // namespace internal
}  // namespace threshing_sim
