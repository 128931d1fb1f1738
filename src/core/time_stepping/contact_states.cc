// Time stepping (docs/model.md §9): contact states, episodes, impact events and statistics
// after a step (stage 9).
#include <algorithm>
#include <cmath>
#include <vector>

#include "context.h"

namespace threshing_sim {
namespace internal {
namespace time_stepping {

namespace {

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

// The slip of a compliant contact that ends inside the step (docs/model.md §9): the contact
// slipped at the step's start (tangential rate vt0 = g.vt) and sticks at its end. Over the
// step the states are interpolated (gap rate linear from g.vn to the end's vn_end, gap its
// integral, the Hertz-Hunt-Crossley force N(t) of that state), the normal impulse P_N(t)
// accumulates as the integral of the quadratic through N(0), N(h/2) = pn / h and N(h) (scaled to
// pn), and the tangential rate, had the contact slipped all step, runs as
//   vt(t) = vt0 + (t/h) (bt_free - vt0) + (P_N(t) / pn) (vt_slip - bt_free),
// vt_slip = y_T + G_TT (pt_slip - pt) the end rate under the sliding impulse pt_slip = -s mu pn.
// The slip ends where vt(t) = 0 (bisection): the friction force there, mu N(t_stick), is the
// largest of the step (the step's mean pt / h averages it with the smaller sticking force).
struct SlipEnd {
  double t_s = 0;   // time of the stick [s]
  double fn_N = 0;  // normal force there [N]
  double ft_N = 0;  // tangential force there, -s mu fn [N]
};

bool locateSlipEnd(const TsStep& s, const ContactGeom& g, const PairMemory& mem, int row,
                   SlipEnd* out) {
  const Model& m = s.m;
  const Workspace& ws = s.ws;
  const double h = s.h, mu = g.params->friction;
  const double pn = ws.lambda[2 * row], pt = ws.lambda[2 * row + 1];
  const double vt0 = g.vt;
  if (vt0 == 0.0 || pn <= 0.0) return false;
  const double sgn = vt0 > 0.0 ? 1.0 : -1.0;
  double G_tt = 0.0, vn_end = ws.y[2 * row] - ws.b_offset[row];
  for (const BodyJac& side : g.side)
    if (side.body >= 0 && side.w_t.size() > 0)
      G_tt += weightedDot(m, &ws.ts.iteration_inverse, side.body, side.w_t, side.w_t);
  const double bt_free = ws.b[2 * row + 1];
  const double vt_slip = ws.y[2 * row + 1] + G_tt * (-sgn * mu * pn - pt);
  if (!(sgn * vt_slip < 0.0)) return false;
  const double K = mem.hertz_K, v_in = mem.v_in_mps;  // this episode's (set at its first step)
  const double v_floor = m.hc_min_impact_speed_mps;
  const double gap0 = g.gap_m - 0.5 * h * g.vn, dvn = vn_end - g.vn;
  auto forceAt = [&](double t) {
    const double vn = g.vn + dvn * t / h;
    const double gap = gap0 + g.vn * t + 0.5 * dvn * t * t / h;
    return compliantNormalForceAt(g, gap, vn, K, v_in, v_floor);
  };
  // N(t) = a + b t + c t^2 through (0, N0), (h/2, Nm), (h, N1); P(t) its integral.
  const double N0 = forceAt(0.0), Nm = pn / h, N1 = forceAt(h);
  const double a = N0, b = (4.0 * Nm - 3.0 * N0 - N1) / h, c = 2.0 * (N0 + N1 - 2.0 * Nm) / (h * h);
  auto P = [&](double t) { return t * (a + t * (0.5 * b + t * c / 3.0)); };
  const double Ph = P(h);
  if (!(Ph > 0.0)) return false;
  auto vt = [&](double t) {
    return vt0 + (t / h) * (bt_free - vt0) + P(t) / Ph * (vt_slip - bt_free);
  };
  double lo = 0.0, hi = h;
  for (int it = 0; it < 50 && hi - lo > 1e-6 * h; ++it) {
    const double mid = 0.5 * (lo + hi);
    (sgn * vt(mid) > 0.0 ? lo : hi) = mid;
  }
  out->t_s = s.d->t_s - h + 0.5 * (lo + hi);
  out->fn_N = forceAt(0.5 * (lo + hi));
  out->ft_N = -sgn * mu * out->fn_N;
  return true;
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
  // Slipping at the step's start: a new contact, or one that slid over the last step.
  const bool slipped_before = before == ContactState::kSeparated || before == ContactState::kSlip ||
                              (before == ContactState::kImpact &&
                               std::abs(mem->tangential_force_N) >=
                                   g.params->friction * mem->normal_force_N * (1.0 - 1e-9));
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
  SlipEnd slip_end;
  if (sticking && slipped_before && g.params->law == ContactLaw::kCompliant &&
      locateSlipEnd(*s, g, *mem, row, &slip_end))
    recordForce(m, d, g, slip_end.fn_N, slip_end.ft_N, slip_end.t_s);
}

}  // namespace

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

}  // namespace time_stepping
}  // namespace internal
}  // namespace threshing_sim
