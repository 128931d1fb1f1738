// The contact phase's step length: the Hertz contact time of each closed contact, from its
// closing speed at first touch (frozen for the episode), over integrator.contact_steps; bounded
// by the contacts' present stiffness and damping (a contact pressed harder than its impact, a
// damper stiffer than its spring), by the broad phase's margin, max_step and the end time.
#include <algorithm>
#include <cmath>

#include "contact_phase.h"

namespace threshing_sim {
namespace internal {
namespace contact_phase {

using event_driven::Ctx;

namespace {

// Halvings of an episode's step for the present stiffness and damping [-] (2^-20 of the Hertz
// step: beyond, the bound is not a contact's).
constexpr int kMaxHalvings = 20;

// Effective mass of a contact along its normal, 1 / (w_n^T M^-1 w_n) over both sides [kg].
double normalMass(const Model& m, const ContactGeom& g) {
  double inv_mass = 0.0;
  for (const BodyJac& s : g.side)
    if (s.body >= 0 && s.w_n.size() > 0) inv_mass += weightedDot(m, nullptr, s.body, s.w_n, s.w_n);
  return inv_mass > 0.0 ? 1.0 / inv_mass : std::numeric_limits<double>::infinity();
}

// Hertz contact time of an impact at closing speed v_mps of effective mass m_eff_kg with the
// Hertz constant K = 4/3 E* sqrt(R*): t_H = 2.87 (m*^2 / (R* E*^2 v))^(1/5), R* E*^2 = (3 K / 4)^2
// (Johnson, Contact Mechanics, section 11.4) [s].
double hertzContactTime(double m_eff_kg, double K, double v_mps) {
  const double rk = 0.75 * K;
  return 2.87 * std::pow(m_eff_kg * m_eff_kg / (rk * rk * v_mps), 0.2);
}

// The step one closed contact allows now [s]: its episode's Hertz time over the count, and at
// most 1 / count of a period of its linearised spring at the present overlap (an impact's
// Hertz time is about half its peak's period, so this binds only on a contact pressed well
// beyond its impact, a knead). (The damper needs no bound: the end's normal force is implicit
// in it, forces.cc.)
double contactStep(const Ctx& c, const ContactGeom& g, PairMemory* mem) {
  const Model& m = c.m;
  const int n = m.integrator.contact_steps;
  const double m_eff = normalMass(m, g);
  if (!std::isfinite(m_eff)) return std::numeric_limits<double>::infinity();
  const double v_floor = m.hc_min_impact_speed_mps;
  if (mem->cp_step_for_s != mem->episode_start_s) {
    mem->cp_step_s = hertzContactTime(m_eff, mem->hertz_K, std::max(mem->v_in_mps, v_floor)) / n;
    mem->cp_step_for_s = mem->episode_start_s;
  }
  double bound = std::numeric_limits<double>::infinity();
  const double delta = std::max(-g.gap_m, 0.0);
  if (delta > 0.0) {
    const double k_lin = 1.5 * mem->hertz_K * std::sqrt(delta);  // dF/d delta [N/m]
    bound = 2.0 * M_PI * std::sqrt(m_eff / k_lin) / n;
  }
  // Halved until within the bound: a few step lengths per episode, whose propagators are kept.
  double h = mem->cp_step_s;
  for (int k = 0; k < kMaxHalvings && h > bound; ++k) h *= 0.5;
  return h;
}

// The step a separated compliant pair approaching at its normal velocity allows [s]: to its
// touch at that speed, plus its impact's Hertz time over the count (inf: not approaching, or
// not evaluated).
double approachStep(const Ctx& c, const ContactGeom& g, const PairMemory& mem) {
  const Model& m = c.m;
  const double inf = std::numeric_limits<double>::infinity();
  if (event_driven::isActive(mem) || g.far || !(g.gap_m > 0.0) || !(g.vn < 0.0) ||
      g.params->law != ContactLaw::kCompliant || !(g.hertz_K > 0.0))
    return inf;
  const double m_eff = normalMass(m, g);
  if (!std::isfinite(m_eff)) return inf;
  const double v_mps = std::max(-g.vn, m.hc_min_impact_speed_mps);
  return g.gap_m / -g.vn + hertzContactTime(m_eff, g.hertz_K, v_mps) / m.integrator.contact_steps;
}

}  // namespace

double stepLength(const Ctx& c, double t_end_s, double v_bound_mps, double margin_m, bool* cut) {
  const Model& m = c.m;
  Workspace& ws = c.ws;
  double h = std::min(m.integrator.max_step_s, 0.5 * margin_m / v_bound_mps);
  for (size_t i = 0; i < ws.candidates.size(); ++i) {
    PairMemory& mem = event_driven::candidateMemory(ws, i);
    if (!event_driven::isActive(mem)) continue;
    h = std::min(h, contactStep(c, ws.geoms[i], &mem));
  }
  // A separated pair approaching: the step ends at most one of its own impact's steps past its
  // touch, so that its first step inside is no longer than its contact's steps (a fast kernel
  // meeting a tooth during a slow pressed contact's long steps would else start its impact
  // deep inside: a force spike).
  bool approach = false;
  for (size_t i = 0; i < ws.candidates.size(); ++i) {
    const double h_touch = approachStep(c, ws.geoms[i], event_driven::candidateMemory(ws, i));
    if (h_touch < h) {
      h = h_touch;
      approach = true;
    }
  }
  // Land on t_end: the last step, or two equal ones rather than a sliver.
  const double left = t_end_s - c.d.t_s;
  *cut = approach || left < 2.0 * h;
  if (left <= h) return left;
  if (left < 2.0 * h) return 0.5 * left;
  return h;
}

}  // namespace contact_phase
}  // namespace internal
}  // namespace threshing_sim
