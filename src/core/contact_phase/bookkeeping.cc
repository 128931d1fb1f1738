// The contact phase's step end: the accepted state and the drive's work, the episodes opened and
// closed by sign with their times interpolated inside the step, stick and slip from the cone
// projection, the impulses (trapezoidal: the kicks' own), the force statistics with each force
// peak located on the parabola through three step ends, pedicels, the published contacts, and
// the end values the next step starts from.
#include <algorithm>
#include <cmath>

#include "contact_phase.h"

namespace threshing_sim {
namespace internal {
namespace contact_phase {

using event_driven::candidateMemory;
using event_driven::Ctx;
using event_driven::isActive;

namespace {

// The state, clock and drum at the step end, and the drive's work over the step (the change of
// the teeth's angular momentum less the contacts' angular impulse, at the mid-step speed).
void acceptState(const Ctx& c, const StepState& s) {
  const Model& m = c.m;
  Data* d = &c.d;
  Workspace& ws = c.ws;
  const Drive mid = driveAt(m, *d, 0.5 * s.h_s);
  const Drive end = driveAt(m, *d, s.h_s);
  double H0 = 0, unused_energy = 0;
  if (!ws.ed.end_values.lookup(*d, &unused_energy, &H0))
    H0 = angularMomentumOf(m, d->z, d->u, d->omega_radps);
  const double H1 = angularMomentumOf(m, ws.ed.z1, ws.cp.u_end, end.omega_radps);
  const double torque_impulse = 0.5 * s.h_s * (s.torque0_Nm + s.torque1_Nm);
  d->stats.drive_work_J += mid.omega_radps * (H1 - H0 - torque_impulse);
  std::swap(d->z, ws.ed.z1);
  std::swap(d->u, ws.cp.u_end);
  d->t_s = end.t_s;
  d->theta_rad = end.theta_rad;
  d->omega_radps = end.omega_radps;
  d->alpha_radps2 = end.alpha_radps2;
  ++d->steps;
  ++ws.cp.steps;
  ws.ed.end_values.store(*d, 0.0, H1);
  ws.ed.h = s.h_s;  // the adaptive step after the phase starts from the phase's step
}

// The vertex of the parabola through (t_a, f_a), (t_b, f_b), (t_c, f_c) where f_b is the largest
// of the three: its time *t_s [s] and value; f_b itself where the three are not a cap.
double parabolaPeak(double t_a, double f_a, double t_b, double f_b, double t_c, double f_c,
                    double* t_s) {
  *t_s = t_b;
  const double h1 = t_b - t_a, h2 = t_c - t_b;
  if (!(h1 > 0.0 && h2 > 0.0)) return f_b;
  const double a = ((f_c - f_b) / h2 + (f_a - f_b) / h1) / (h1 + h2);
  if (!(a < 0.0)) return f_b;
  const double b = (f_c - f_b) / h2 - a * h2;
  const double tau = std::clamp(-b / (2.0 * a), -h1, h2);
  *t_s = t_b + tau;
  return std::max(f_b, f_b + tau * (b + a * tau));
}

// The force statistics of a closed contact at the step end, and, where the step start was a
// local maximum of its normal or tangential force, that maximum located between the three step
// ends around it.
void recordForces(const Ctx& c, const StepState& s, size_t i, PairMemory* mem) {
  const Model& m = c.m;
  Data* d = &c.d;
  const ContactPhaseScratch& cp = c.ws.cp;
  const ContactGeom& g = c.ws.geoms[i];
  const double t1 = s.t0_s + s.h_s;
  recordForce(m, d, g, cp.fn1[i], cp.ft1[i], t1);
  mem->episode_peak_N = std::max(mem->episode_peak_N, cp.fn1[i]);
  if (mem->cp_t_before_s < 0.0 || mem->cp_t_before_s < mem->episode_start_s) return;
  const double fb = mem->cp_fn_before_N, f0 = cp.fn0[i], f1 = cp.fn1[i];
  double fn_peak = f0, t_n = s.t0_s;
  if (f0 >= fb && f0 >= f1 && f0 > 0.0) {
    fn_peak = parabolaPeak(mem->cp_t_before_s, fb, s.t0_s, f0, t1, f1, &t_n);
    recordForce(m, d, g, fn_peak, 0.0, t_n);
    mem->episode_peak_N = std::max(mem->episode_peak_N, fn_peak);
  }
  const double tb = std::abs(mem->cp_ft_before_N), t0v = std::abs(cp.ft0[i]),
               t1v = std::abs(cp.ft1[i]);
  if (t0v >= tb && t0v >= t1v && t0v > 0.0) {
    double t_t = s.t0_s;
    const double ft_peak = parabolaPeak(mem->cp_t_before_s, tb, s.t0_s, t0v, t1, t1v, &t_t);
    recordForce(m, d, g, std::max(fn_peak, f0), ft_peak, t_t);
  }
}

// The normal force at time t_s inside the step [N]: the parabola through the step end before
// the start (in the same episode), the start (fn0) and the end (fn1); else the line.
double normalForceAt(const PairMemory& mem, const StepState& s, double fn0, double fn1,
                     double t_s) {
  const double t0 = s.t0_s, t1 = s.t0_s + s.h_s, tb = mem.cp_t_before_s;
  const double line = fn0 + (t_s - t0) / s.h_s * (fn1 - fn0);
  if (tb < 0.0 || tb < mem.episode_start_s || !(tb < t0)) return line;
  const double fb = mem.cp_fn_before_N;
  const double lb = (t_s - t0) * (t_s - t1) / ((tb - t0) * (tb - t1));
  const double l0 = (t_s - tb) * (t_s - t1) / ((t0 - tb) * (t0 - t1));
  const double l1 = (t_s - tb) * (t_s - t0) / ((t1 - tb) * (t1 - t0));
  return std::max(0.0, fb * lb + fn0 * l0 + fn1 * l1);
}

// When inside the step the slip velocity of contact i, sliding under the friction force
// -ft_slip_N, reaches zero [s from the start]: the root of
// vt0 + at0 tau + (at1 - at0) tau^2 / (2 h), at1 the slip velocity's rate at the end had it
// kept sliding (the end's kick acceleration with the sliding force in place of the one found).
double slipEnd(const Ctx& c, const StepState& s, size_t i, double ft_slip_N) {
  const ContactPhaseScratch& cp = c.ws.cp;
  const ContactGeom& g = c.ws.geoms[i];
  const double vt0 = cp.vt0_mps[i], at0 = cp.at0_mps2[i];
  double at1 = 0.0, w = 0.0;
  for (const BodyJac& b : g.side) {
    if (b.body < 0 || b.w_t.size() == 0) continue;
    const int off = bodyDofOffset(c.m, b.body);
    for (int j = 0; j < b.w_t.size(); ++j) at1 += b.w_t[j] * cp.a1[off + j];
    w += weightedDot(c.m, nullptr, b.body, b.w_t, b.w_t);
  }
  at1 += w * (-ft_slip_N - cp.ft1[i]);
  const double k = (at1 - at0) / s.h_s;  // rate of the slip acceleration [m/s^3]
  const double linear = -vt0 / at0;
  double tau = linear;
  const double disc = at0 * at0 - 2.0 * k * vt0;
  if (k != 0.0 && disc >= 0.0) {  // the root nearest the linear one
    const double q = -0.5 * (at0 + std::copysign(std::sqrt(disc), at0));
    const double r1 = q / (0.5 * k), r2 = vt0 / q;
    tau = std::abs(r1 - linear) < std::abs(r2 - linear) ? r1 : r2;
  }
  return std::clamp(tau, 0.0, s.h_s);
}

// Stick or slip at the step end from the cone projection, the transition reported at its
// interpolated time (stick -> slip where |ft| - mu fn crosses zero; slip -> stick or a reversal
// where the slip velocity does), with the friction force mu fn there in the statistics.
void updateFrictionState(const Ctx& c, const StepState& s, size_t i, PairMemory* mem) {
  const Model& m = c.m;
  const ContactPhaseScratch& cp = c.ws.cp;
  const ContactGeom& g = c.ws.geoms[i];
  const double mu = g.params->friction, fn = cp.fn1[i], ft = cp.ft1[i];
  const ContactState before = mem->state;
  const int sign_before = mem->slip_sign;
  if (mu == 0.0) {
    mem->slip_sign = 0;
    mem->state = std::abs(g.vt) > m.integrator.zeno_velocity_mps ? ContactState::kSlip
                                                                 : ContactState::kStick;
  } else if (std::abs(ft) < mu * fn * (1.0 - 1e-9)) {
    mem->slip_sign = 0;
    mem->state = ContactState::kStick;
  } else {
    mem->slip_sign = ft > 0 ? -1 : 1;
    mem->state = ContactState::kSlip;
  }
  mem->slip_from_stick = false;
  if (before == ContactState::kImpact) return;
  if (before == mem->state && sign_before == mem->slip_sign) return;
  double t = s.t0_s + s.h_s;
  const double vt0 = cp.vt0_mps[i], at0 = cp.at0_mps2[i];
  if (before == ContactState::kStick) {
    const double r0 = std::abs(cp.ft0[i]) - mu * cp.fn0[i];
    const double r1 = std::abs(cp.ft_trial[i]) - mu * fn;  // the stick force the cone cut
    t = r0 < 0.0 && r1 >= 0.0 ? s.t0_s + s.h_s * r0 / (r0 - r1) : t;
  } else if (vt0 * at0 < 0.0) {  // the slip velocity's zero under the slip force
    t = s.t0_s + slipEnd(c, s, i, sign_before * mu * fn);
  }
  emitTransition(&c.d, g.pair, before, mem->state, t, g);
  // At a transition between stick and slip the friction is at the cone's edge: mu fn there.
  if (mu > 0.0 && (before == ContactState::kStick) != (mem->state == ContactState::kStick)) {
    const double fn_t = normalForceAt(*mem, s, cp.fn0[i], fn, t);
    recordForce(m, &c.d, g, fn_t, mu * fn_t, t);
  }
}

// One candidate's bookkeeping at the step end; e_net: energy less drive work, made on demand.
template <typename EnergyNet>
void finishPair(const Ctx& c, const StepState& s, size_t i, EnergyNet&& e_net) {
  Data* d = &c.d;
  const ContactPhaseScratch& cp = c.ws.cp;
  const ContactGeom& g = c.ws.geoms[i];
  PairMemory& mem = candidateMemory(c.ws, i);
  if (cp.opened[i]) {
    mem.v_in_mps = cp.v_in_mps[i];
    mem.hertz_K = g.hertz_K;
    beginEpisode(c.m, d, &mem, g, cp.t_open_s[i], e_net());
    mem.state = ContactState::kImpact;
    mem.slip_sign = 0;
    emitTransition(d, g.pair, ContactState::kSeparated, ContactState::kImpact, cp.t_open_s[i], g);
  }
  if (!isActive(mem)) return;
  const double imp_n = 0.5 * s.h_s * (cp.fn0[i] + cp.fn1[i]);
  const double imp_t = 0.5 * s.h_s * (cp.ft0[i] + cp.ft1[i]);
  mem.episode_impulse_n += imp_n;
  mem.episode_impulse_t += imp_t;
  mem.impulse_n_acc += imp_n;
  mem.impulse_t_acc += imp_t;
  d->stats.total_normal_impulse_Ns += imp_n;
  if (cp.released[i]) {
    endEpisode(c.m, d, &mem, g, cp.t_open_s[i], e_net());
    mem.cp_t_before_s = -1.0;
    return;
  }
  updateFrictionState(c, s, i, &mem);
  mem.normal_force_N = cp.fn1[i];
  mem.tangential_force_N = cp.ft1[i];
  recordForces(c, s, i, &mem);
  mem.cp_drift_mps2 = cp.opened[i] || g.far ? 0.0 : cp.drift_rate_mps2[i];
  mem.cp_fn_before_N = cp.fn0[i];
  mem.cp_ft_before_N = cp.ft0[i];
  mem.cp_t_before_s = s.t0_s;
}

// The stem's generalised force on kernel i at (z, u) and time t_s [s]: force [N] and moment
// about the centre [N m].
Eigen::Vector3d stemForce(const Model& m, const VecX& z, const VecX& u, int i, double t_s) {
  Vec2 p_WP;
  const Vec2 F = pedicelForce(m, z, u, i, t_s, &p_WP);
  const Vec2 r = p_WP - z.segment<2>(m.kernels[i].dof_offset);
  return Eigen::Vector3d(F.x(), F.y(), r.x() * F.y() - r.y() * F.x());
}

// Pedicels whose force passed the detachment threshold over the step break at the instant it
// crossed it (interpolated between the step's ends), not at the step end: the kicks gave the
// kernel the stem's force all through the step, the share after the break is taken back (the
// trapezoid's). The step's start state is in ws.ed.z1 and ws.cp.u_end (acceptState swapped it
// out). Returns whether any broke.
bool breakPedicels(const Ctx& c, const StepState& s) {
  const Model& m = c.m;
  Data* d = &c.d;
  const VecX& z0 = c.ws.ed.z1;
  const VecX& u0 = c.ws.cp.u_end;
  bool broke = false;
  for (int i = 0; i < static_cast<int>(m.kernels.size()); ++i) {
    const KernelModel& k = m.kernels[i];
    if (!k.pedicel.present || !d->kernel_attached[i] || !d->kernel_active[i]) continue;
    const double limit = k.pedicel.detachment_force_N;
    const Eigen::Vector3d q1 = stemForce(m, d->z, d->u, i, d->t_s);
    const double f1 = q1.head<2>().norm();
    if (!(f1 > limit)) continue;
    const Eigen::Vector3d q0 = stemForce(m, z0, u0, i, s.t0_s);
    const double f0 = q0.head<2>().norm();
    const double frac = f0 < limit ? (limit - f0) / (f1 - f0) : 0.0;
    const Eigen::Vector3d q_break = q0 + frac * (q1 - q0);
    const Eigen::Vector3d excess = 0.5 * s.h_s * ((q0 + q1) - frac * (q0 + q_break));
    d->u[k.dof_offset] -= excess[0] / k.mass_kg;
    d->u[k.dof_offset + 1] -= excess[1] / k.mass_kg;
    d->u[k.dof_offset + 2] -= excess[2] / k.inertia_kgm2;
    d->kernel_attached[i] = 0;
    d->stats.kernel_detach_time_s[i] = s.t0_s + frac * s.h_s;
    broke = true;
  }
  return broke;
}

// The end values the next step starts from, while nothing else moves the state.
void keepEndValues(const Ctx& c, bool pedicels_changed) {
  ContactPhaseScratch& cp = c.ws.cp;
  cp.end_valid = !pedicels_changed;
  cp.end_t_s = c.d.t_s;
  cp.end_omega_radps = c.d.omega_radps;
  cp.end_z = c.d.z;
  cp.end_u = c.d.u;
  cp.end_candidates = c.ws.candidates;
}

}  // namespace

void acceptStep(const Ctx& c, const StepState& s) {
  const Model& m = c.m;
  Data* d = &c.d;
  acceptState(c, s);
  bool have_energy = false;
  double energy_net = 0.0;
  auto e_net = [&]() {
    if (!have_energy) energy_net = mechanicalEnergy(m, *d) - d->stats.drive_work_J;
    have_energy = true;
    return energy_net;
  };
  for (size_t i = 0; i < c.ws.candidates.size(); ++i) finishPair(c, s, i, e_net);
  const bool broke = breakPedicels(c, s);
  publishContacts(d, &c.ws);
  keepEndValues(c, broke);
}

}  // namespace contact_phase
}  // namespace internal
}  // namespace threshing_sim
