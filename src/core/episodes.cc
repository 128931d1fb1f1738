// Episodes and events, the bookkeeping both integrators share: force statistics (peaks per
// kernel), contact episodes opened and closed with their ContactEvents, the published contact
// list, pedicel breaks and the tooth deflection check.
#include "episodes.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>

#include "internal.h"
#include "threshing_sim/core/beam.h"

namespace threshing_sim {
namespace internal {

namespace {
int kernelOf(const PairId& p) { return p.kind == PairKind::kKernelObstacle ? p.a : p.b; }
}  // namespace

namespace {
// Magnitude of the tangential force a statistic records [N]: |ft| projected on the friction cone
// |ft| <= mu fn. At a located stick -> slip event the stick force evaluated just past the
// crossing can lie far outside the cone (a wedged kernel's stick solution may run through a
// pole instead of reaching the cone); the force at that transition is the sliding one, mu fn.
double coneTangential(const ContactGeom& g, double fn, double ft) {
  return std::min(std::abs(ft), g.params->friction * std::max(fn, 0.0));
}

// Per-kernel force peaks of one closed contact's forces fn, |ft| [N] at time t [s]: the largest
// normal force of any contact on each kernel of the pair, and the tooth force peaks with their
// times (the first time a peak value is reached is kept).
void recordKernelPeaks(RunStats* st, const PairId& pair, double fn, double ft_abs, double t) {
  const int kb = kernelOf(pair);
  st->kernel_peak_normal_force_N[kb] = std::max(st->kernel_peak_normal_force_N[kb], fn);
  if (pair.kind == PairKind::kKernelKernel)
    st->kernel_peak_normal_force_N[pair.a] = std::max(st->kernel_peak_normal_force_N[pair.a], fn);
  if (pair.kind != PairKind::kToothKernel) return;
  KernelToothPeaks& peaks = st->kernel_tooth_peaks[kb];
  if (fn > peaks.normal_force_N) {
    peaks.normal_force_N = fn;
    peaks.time_of_normal_s = t;
  }
  if (ft_abs > peaks.tangential_force_N) {
    peaks.tangential_force_N = ft_abs;
    peaks.time_of_tangential_s = t;
  }
}
}  // namespace

void recordForce(const Model& m, Data* d, const ContactGeom& g, double fn, double ft, double t) {
  (void)m;
  RunStats& st = d->stats;
  const double ft_abs = coneTangential(g, fn, ft);
  if (fn > st.peak_normal_force_N) {
    st.peak_normal_force_N = fn;
    st.time_of_peak_normal_s = t;
  }
  if (ft_abs > st.peak_tangential_force_N) {
    st.peak_tangential_force_N = ft_abs;
    st.time_of_peak_tangential_s = t;
  }
  recordKernelPeaks(&st, g.pair, fn, ft_abs, t);
  st.max_penetration_m = std::max(st.max_penetration_m, -g.gap_m);
}

void emitTransition(Data* d, const PairId& pair, ContactState from, ContactState to, double t,
                    const ContactGeom& g) {
  ContactEvent ev;
  ev.t_s = t;
  ev.pair = pair;
  ev.from = from;
  ev.to = to;
  ev.vn_before_mps = ev.vn_after_mps = g.vn;
  ev.vt_before_mps = ev.vt_after_mps = g.vt;
  d->events.push_back(ev);
}

void beginEpisode(const Model& m, Data* d, PairMemory* mem, const ContactGeom& g, double t,
                  double energy_net) {
  // A new sub-collision; a new macro-collision if the pair was apart for long enough.
  if (mem->last_contact_end_s < 0 || t - mem->last_contact_end_s > m.macro_collision_gap_s) {
    ++mem->macro_index;
    mem->sub_index = 0;
  } else {
    ++mem->sub_index;
  }
  mem->episode_start_s = t;
  mem->episode_peak_N = 0;
  mem->episode_impulse_n = mem->episode_impulse_t = 0;
  mem->vn_before = g.vn;
  mem->vt_before = g.vt;
  mem->energy_before_J = energy_net;
  ++d->stats.contact_episodes;
}

void endEpisode(const Model& m, Data* d, PairMemory* mem, const ContactGeom& g, double t,
                double energy_net) {
  (void)m;
  mem->last_contact_end_s = t;
  // Under the compliant law the whole episode is the impact: report it now.
  if (g.params->law == ContactLaw::kCompliant) {
    ContactEvent ev;
    ev.t_s = t;
    ev.pair = g.pair;
    ev.from = mem->state;
    ev.to = ContactState::kSeparated;
    ev.is_impact = true;
    ev.vn_before_mps = mem->vn_before;
    ev.vt_before_mps = mem->vt_before;
    ev.vn_after_mps = g.vn;
    ev.vt_after_mps = g.vt;
    ev.impulse_normal_Ns = mem->episode_impulse_n;
    ev.impulse_tangential_Ns = mem->episode_impulse_t;
    ev.energy_lost_J = mem->energy_before_J - energy_net;
    ev.peak_normal_force_N = mem->episode_peak_N;
    ev.macro_collision = mem->macro_index;
    ev.sub_collision = mem->sub_index;
    d->events.push_back(ev);
    ++d->stats.impacts;
    ++d->stats.kernel_impacts[kernelOf(g.pair)];
    if (g.pair.kind == PairKind::kKernelKernel) ++d->stats.kernel_impacts[g.pair.a];
    d->stats.max_energy_gain_at_impact_J =
        std::max(d->stats.max_energy_gain_at_impact_J, -ev.energy_lost_J);
  } else {
    emitTransition(d, g.pair, mem->state, ContactState::kSeparated, t, g);
  }
  mem->state = ContactState::kSeparated;
  mem->closed = false;
  mem->slip_sign = 0;
  mem->slip_from_stick = false;
  mem->normal_force_N = mem->tangential_force_N = 0;
}

void publishContacts(Data* d, Workspace* ws) {
  // Pairs near enough to have exact geometry (not "far" bounds).
  size_t n = 0;
  for (const ContactGeom& g : ws->geoms) n += g.far ? 0 : 1;
  d->contacts.resize(n);
  size_t i_out = 0;
  for (const ContactGeom& g : ws->geoms) {
    if (g.far) continue;
    const PairMemory& mem = ws->memory[pairKey(g.pair)];
    ContactInfo& c = d->contacts[i_out++];
    c.pair = g.pair;
    c.state = mem.state;
    c.gap_m = g.gap_m;
    c.p_W = 0.5 * (g.p0 + g.p1);
    c.n_W = g.n;
    c.tooth_x_m = g.tooth_x_m;
    c.normal_velocity_mps = g.vn;
    c.slip_velocity_mps = g.vt;
    c.normal_force_N = mem.normal_force_N;
    c.tangential_force_N = mem.tangential_force_N;
    c.impulse_normal_Ns = mem.impulse_n_acc;
    c.impulse_tangential_Ns = mem.impulse_t_acc;
    // The published forces count for the per-kernel peaks too: after a located event they are
    // those of the switched contact modes, which recordForce (called before the switch) missed.
    if (mem.state != ContactState::kSeparated) {
      recordKernelPeaks(&d->stats, g.pair, mem.normal_force_N,
                        coneTangential(g, mem.normal_force_N, mem.tangential_force_N), d->t_s);
    }
  }
}

void updatePedicels(const Model& m, Data* d) {
  for (size_t i = 0; i < m.kernels.size(); ++i) {
    const KernelModel& k = m.kernels[i];
    if (!k.pedicel.present || !d->kernel_attached[i]) continue;
    Vec2 p_WP;
    const double f = pedicelForce(m, d->z, d->u, static_cast<int>(i), d->t_s, &p_WP).norm();
    // The stem breaks for good once its force passes the detachment threshold.
    if (f > k.pedicel.detachment_force_N) {
      d->kernel_attached[i] = 0;
      d->stats.kernel_detach_time_s[i] = d->t_s;
    }
  }
}

}  // namespace internal

namespace internal {

// Model validity after a step: the beam model is linear in the deflection (small-deflection
// Euler-Bernoulli with first-order foreshortening, docs/model.md §2), so a tooth whose tip
// deflection |w(L)| exceeds model.deflection_validity_fraction x L has left the range the model
// is valid in. Tracks the largest |w(L)| / L and warns once per run (no allocation otherwise).
void checkToothDeflection(const Model& m, Data* d) {
  RunStats& st = d->stats;
  for (size_t k = 0; k < m.teeth.size(); ++k) {
    const ToothModel& tm = m.teeth[k];
    if (tm.n_modes == 0) continue;
    // The last station is the tip, x = L. A large-deflection rod is valid at any deflection:
    // only tracked.
    const bool rod = tm.beam_model == ToothBeamModel::kLargeDeflection;
    const double w_tip_m = rod ? toothDeflection(m, *d, static_cast<int>(k), tm.length_m)
                               : tm.phi_s.row(tm.n_stations - 1)
                                     .transpose()
                                     .dot(d->z.segment(tm.dof_offset, tm.n_modes));
    const double ratio = std::abs(w_tip_m) / tm.length_m;
    st.max_tip_deflection_ratio = std::max(st.max_tip_deflection_ratio, ratio);
    if (!rod && ratio > m.deflection_validity_fraction && st.deflection_warning_time_s < 0) {
      st.deflection_warning_time_s = d->t_s;
      char text[320];
      std::snprintf(text, sizeof(text),
                    "tooth %zu: tip deflection %.3g L (|w(L)| = %.3g m) at t = %.6g s is outside "
                    "the small-deflection range of the beam model (|w(L)| <= %.3g L); use "
                    "teeth.%zu.model: large_deflection",
                    k, ratio, std::abs(w_tip_m), d->t_s, m.deflection_validity_fraction, k);
      st.warnings.push_back(text);
    }
  }
}

}  // namespace internal

}  // namespace threshing_sim
