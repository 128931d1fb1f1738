// The event-driven integrator's located force peaks: the maxima of the compliant normal forces
// inside a step, and the force snapshots at its ends.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

#include "context.h"

namespace threshing_sim {
namespace internal {
namespace event_driven {

namespace {

// Rate of a compliant contact's normal force F = K delta^{3/2} (1 + chi d(delta)/dt) [N/s] at
// the state (z, u) at time t [s], for the geometry g and accelerations udot of a rhs() call at
// that state: dF/dt = K [3/2 delta^{1/2} delta' (1 + chi delta') + delta^{3/2} chi delta''],
// delta'' = -(w_N . udot + velocity drift). Zero where the force is zero (apart, or clamped:
// no adhesion).
double compliantForceRate(const Ctx& c, const ContactGeom& g, const PairMemory& mem, const VecX& z,
                          const VecX& u, const VecX& udot, double t) {
  const double delta_m = -g.gap_m;
  const double rate_mps = -g.vn;
  const double chi_spm =
      g.params->hc_damping_factor / std::max(mem.v_in_mps, c.m.hc_min_impact_speed_mps);
  if (delta_m <= 0.0 || (g.residual_mpN <= 0.0 && 1.0 + chi_spm * rate_mps <= 0.0)) return 0.0;
  // Normal relative acceleration: the Jacobians times the accelerations, plus the drift.
  double acc_mps2 = contactVelocityDrift(c.m, z, u, driveAtTime(c, t), g, &c.ws)[0];
  for (const BodyJac& s : g.side) {
    if (s.body < 0 || s.w_n.size() == 0) continue;
    acc_mps2 += s.w_n.dot(udot.segment(bodyDofOffset(c.m, s.body), s.w_n.size()));
  }
  if (g.residual_mpN > 0.0) {  // the residual spring in series (static correction)
    const Drive drive = driveAtTime(c, t);
    double r_rate_mpNps = drive.omega_radps * g.residual_dtheta_mpNprad;  // R' [m/(N s)]
    for (const BodyJac& s : g.side) {
      if (s.body < 0 || s.w_r.size() == 0) continue;
      r_rate_mpNps += s.w_r.dot(u.segment(bodyDofOffset(c.m, s.body), s.w_r.size()));
    }
    return compliantNormalForceRate(g, mem.hertz_K, mem.v_in_mps, c.m.hc_min_impact_speed_mps,
                                    acc_mps2, r_rate_mpNps);
  }
  const double sq = std::sqrt(delta_m);
  return mem.hertz_K *
         (1.5 * sq * rate_mps * (1.0 + chi_spm * rate_mps) - delta_m * sq * chi_spm * acc_mps2);
}

// The probes evaluate the pairs at states inside the step, and each evaluation moves a tooth
// pair's narrow-phase warm start (its last closest points and their times, PairMemory::warm_*)
// there. Kept before the probes and restored after them, so that the steps that follow start
// their closest-point searches where they would have without the probes: the located peaks are
// a measurement and do not change the trajectory (before, how the probes went -- their
// number, where the force rate sent them -- moved later closest points within the narrow
// phase's tolerance and with them the step sequence).
void saveWarmStarts(Workspace* ws) {
  std::vector<double>& w = ws->ed.pk_warm;
  w.resize(5 * ws->candidates.size());
  for (size_t i = 0; i < ws->candidates.size(); ++i) {
    const PairMemory& mem = ws->memory[pairKey(ws->candidates[i])];
    w[5 * i] = mem.warm_x_m;
    w[5 * i + 1] = mem.warm_t_s;
    w[5 * i + 2] = mem.warm_x_prev_m;
    w[5 * i + 3] = mem.warm_t_prev_s;
    w[5 * i + 4] = mem.warm_theta_rad;
  }
}

void restoreWarmStarts(Workspace* ws) {
  const std::vector<double>& w = ws->ed.pk_warm;
  for (size_t i = 0; i < ws->candidates.size() && 5 * i + 4 < w.size(); ++i) {
    PairMemory& mem = ws->memory[pairKey(ws->candidates[i])];
    mem.warm_x_m = w[5 * i];
    mem.warm_t_s = w[5 * i + 1];
    mem.warm_x_prev_m = w[5 * i + 2];
    mem.warm_t_prev_s = w[5 * i + 3];
    mem.warm_theta_rad = w[5 * i + 4];
  }
  ws->ed.memo.valid = false;  // ws.geoms hold the last probe
}

// Whether a pair is in compliant contact.
bool inCompliantContact(const ContactGeom& g, const PairMemory& mem) {
  return isActive(mem) && g.params->law == ContactLaw::kCompliant;
}

}  // namespace

// Normal force [N] and its rate [N/s] of every pair in compliant contact, from the last rhs()
// call, made at the state (z, u) at time t [s] with accelerations udot (ws.geoms, ws.ed.fn), into
// f and r (per geom, zero for other pairs); `on` flags those pairs. Returns whether there is any.
bool compliantForceSnapshot(const Ctx& c, double t, const VecX& z, const VecX& u, const VecX& udot,
                            std::vector<double>* f, std::vector<double>* r,
                            std::vector<std::uint8_t>* on) {
  Workspace& ws = c.ws;
  const size_t n_geoms = ws.geoms.size();
  f->assign(n_geoms, 0.0);
  r->assign(n_geoms, 0.0);
  on->assign(n_geoms, 0);
  bool any = false;
  for (size_t i = 0; i < n_geoms; ++i) {
    const ContactGeom& g = ws.geoms[i];
    const PairMemory& mem = candidateMemory(ws, i);
    if (!inCompliantContact(g, mem)) continue;
    any = true;
    (*on)[i] = 1;
    (*f)[i] = ws.ed.fn[i];
    (*r)[i] = compliantForceRate(c, g, mem, z, u, udot, t);
  }
  return any;
}

// Located maxima of the compliant normal forces over an accepted step of length h [s] from
// (t0, z0, u0) to (z1, u1), before the index sets are switched. A force that rises at the start
// and falls at the end of the step (values and rates from ws.ed.pk_* at both ends) has an
// interior maximum: the cubic Hermite interpolant predicts its time, one Dormand-Prince step from
// the start gives the state there, and the force and its rate at that state narrow the bracket,
// until the prediction matches the probed force to 1e-2 x tolerance (at most 4 probes). Every
// probed state's forces count for the peak statistics: in slip |F_T| = mu F_N peaks with F_N.
// (A sticking |F_T| is a multiplier without a closed-form rate: its peak stays sampled at step
// ends and at located events.) A maximum at a step boundary (a kink from an impact elsewhere)
// is an end value, recorded with the step.
// end_evaluated: the last rhs() call was at (z1, u1), so ws.geoms and ws.ed.udot_ev hold the end.
void locateForcePeaks(const Ctx& c, double t0, double h, const VecX& z0, const VecX& u0,
                      const VecX& z1, const VecX& u1, bool end_evaluated) {
  Workspace& ws = c.ws;
  double torque_unused = 0, err_unused = 0;
  // Values and rates at the step end.
  if (!end_evaluated &&
      !rhs(c, t0 + h, z1, u1, &ws.ed.udot_ev, &torque_unused, false, SeparatedPairs::kNone))
    return;
  std::vector<std::uint8_t>& on_end = ws.ed.pk_on_end;
  compliantForceSnapshot(c, t0 + h, z1, u1, ws.ed.udot_ev, &ws.ed.pk_f1, &ws.ed.pk_r1, &on_end);
  const size_t n_geoms = std::min(ws.ed.pk_on.size(), on_end.size());
  // The probe steps overwrite the step's contact impulses and drum torque impulse: kept here.
  bool saved = false;
  double torque_impulse_saved = 0;
  const double rel_tol = 1e-2 * c.m.integrator.tolerance;
  for (size_t i = 0; i < n_geoms; ++i) {
    if (!ws.ed.pk_on[i] || !on_end[i]) continue;
    // Bracket [a, b] of the step (from its start) with a rising and a falling end. A force at
    // zero at an end (the episode opens or closes there, where F ~ delta^{3/2} has a zero rate)
    // counts as rising from the start or falling to the end.
    double a = 0, b = h;
    double fa = ws.ed.pk_f0[i], ra = ws.ed.pk_r0[i], fb = ws.ed.pk_f1[i], rb = ws.ed.pk_r1[i];
    const bool rising = ra > 0 || (fa <= 0 && fb > 0);
    const bool falling = rb < 0 || (fb <= 0 && fa > 0);
    if (!(rising && falling)) continue;
    if (!saved) {
      saveWarmStarts(&ws);
      ws.ed.imp_n_saved = ws.ed.imp_n;
      ws.ed.imp_t_saved = ws.ed.imp_t;
      torque_impulse_saved = ws.ed.torque_impulse;
      saved = true;
    }
    for (int probe = 0; probe < 4; ++probe) {
      // Predicted maximum of the Hermite cubic (the minimum of its negative).
      double s_max = 0;
      const double f_pred = -hermiteMinimum(-fa, -ra, -fb, -rb, b - a, &s_max);
      const double tp = a + s_max * (b - a);
      // The state there, one step from the start, and its forces.
      if (!dopriStep(c, t0, tp, z0, u0, &ws.ed.zt, &ws.ed.ut, &err_unused, &torque_unused) ||
          !rhs(c, t0 + tp, ws.ed.zt, ws.ed.ut, &ws.ed.pk_udot, &torque_unused, false,
               SeparatedPairs::kNone))
        break;
      const ContactGeom& g = ws.geoms[i];
      PairMemory& mem = ws.memory[pairKey(g.pair)];
      const double fp = ws.ed.fn[i];
      recordForce(c.m, &c.d, g, fp, ws.ed.ft[i], t0 + tp);
      mem.episode_peak_N = std::max(mem.episode_peak_N, fp);
      if (std::abs(f_pred - fp) <= rel_tol * fp) break;
      // Its rate; the bracket shrinks to the side where the force still rises.
      const double rp = compliantForceRate(c, g, mem, ws.ed.zt, ws.ed.ut, ws.ed.pk_udot, t0 + tp);
      if (rp > 0) {
        a = tp;
        fa = fp;
        ra = rp;
      } else if (rp < 0) {
        b = tp;
        fb = fp;
        rb = rp;
      } else {
        break;
      }
    }
  }
  if (saved) {
    restoreWarmStarts(&ws);
    ws.ed.imp_n = ws.ed.imp_n_saved;
    ws.ed.imp_t = ws.ed.imp_t_saved;
    ws.ed.torque_impulse = torque_impulse_saved;
  }
}

}  // namespace event_driven
}  // namespace internal
}  // namespace threshing_sim
