// The contact phase's friction: at the step end each closed contact's tangential force is the
// one that brings its slip velocity at the end to zero (stick), projected on the Coulomb cone
// |ft| <= mu fn (slip, against the slip velocity): Moreau's velocity-level law over the second
// half kick. Contacts that share a body are coupled: projected Gauss-Seidel, warm-started from
// the forces of the step start, a bounded number of sweeps.
#include <algorithm>
#include <cmath>

#include "contact_phase.h"

namespace threshing_sim {
namespace internal {
namespace contact_phase {

using event_driven::Ctx;

namespace {

constexpr int kMaxSweeps = 10;             // Gauss-Seidel sweeps over the closed contacts [-]
constexpr double kSweepTolerance = 1e-10;  // largest change relative to mu fn that stops them [-]

}  // namespace

double slipVelocity(const Model& m, const ContactGeom& g, const VecX& u, const VecX& u_eval) {
  double vt = g.vt;
  for (const BodyJac& s : g.side) {
    if (s.body < 0 || s.w_t.size() == 0) continue;
    const int off = bodyDofOffset(m, s.body);
    for (int j = 0; j < s.w_t.size(); ++j) vt += s.w_t[j] * (u[off + j] - u_eval[off + j]);
  }
  return vt;
}

void projectFriction(const Ctx& c, double half_h_s, const VecX& fn,
                     const std::vector<double>* target, VecX* ft) {
  Workspace& ws = c.ws;
  ContactPhaseScratch::ContactSpace& cs = ws.cp.cs;
  ws.cp.ft_trial.assign(ws.candidates.size(), 0.0);
  const int k = static_cast<int>(cs.cand.size());
  // The rows that carry friction (normal force, a friction coefficient, a tangential
  // compliance); one alone is solved by its first sweep (the second only confirms it).
  int rows = 0;
  for (int r = 0; r < k; ++r) {
    const size_t i = static_cast<size_t>(cs.cand[r]);
    rows += fn[i] > 0.0 && ws.geoms[i].params->friction > 0.0 && cs.W(2 * r + 1, 3 * r + 1) > 0.0;
  }
  const int sweeps = rows == 1 ? 1 : kMaxSweeps;
  for (int sweep = 0; sweep < sweeps && rows > 0; ++sweep) {
    double largest = 0.0;
    for (int r = 0; r < k; ++r) {
      const size_t i = static_cast<size_t>(cs.cand[r]);
      const double w = cs.W(2 * r + 1, 3 * r + 1);
      const double mu = ws.geoms[i].params->friction;
      if (fn[i] <= 0.0 || mu <= 0.0 || !(w > 0.0)) continue;
      const double limit = mu * fn[i];
      const double vt = cs.vt[r] - (target ? (*target)[i] : 0.0);
      const double trial = (*ft)[i] - vt / (half_h_s * w);
      ws.cp.ft_trial[i] = trial;
      const double f = std::clamp(trial, -limit, limit);
      const double df = f - (*ft)[i];
      if (df == 0.0) continue;
      addForceChange(&cs, r, 0.0, df, 0.0, half_h_s);
      (*ft)[i] = f;
      largest = std::max(largest, std::abs(df) / limit);
    }
    if (largest <= kSweepTolerance) break;
  }
}

void solveFriction(const Ctx& c, const StepState& s) {
  Workspace& ws = c.ws;
  ContactPhaseScratch& cp = ws.cp;
  const double half_h = 0.5 * s.h_s;
  // Warm start: the start's force, within the end's cone.
  for (size_t r = 0; r < cp.cs.cand.size(); ++r) {
    const size_t i = static_cast<size_t>(cp.cs.cand[r]);
    const double limit = ws.geoms[i].params->friction * cp.fn1[i];
    if (cp.fn1[i] <= 0.0 || limit <= 0.0 || cp.released[i] || cp.opened[i]) continue;
    cp.ft1[i] = std::clamp(cp.ft0[i], -limit, limit);
    if (cp.ft1[i] != 0.0) addForceChange(&cp.cs, static_cast<int>(r), 0.0, cp.ft1[i], 0.0, half_h);
  }
  projectFriction(c, half_h, cp.fn1, nullptr, &cp.ft1);
}

}  // namespace contact_phase
}  // namespace internal
}  // namespace threshing_sim
