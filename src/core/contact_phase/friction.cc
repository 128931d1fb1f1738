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

// w_t^T M^-1 w_t over both sides: the slip velocity's change per unit tangential impulse [1/kg].
double tangentialCompliance(const Model& m, const ContactGeom& g) {
  double w = 0.0;
  for (const BodyJac& s : g.side)
    if (s.body >= 0 && s.w_t.size() > 0) w += weightedDot(m, nullptr, s.body, s.w_t, s.w_t);
  return w;
}

// Adds a change dft of contact g's tangential force to the kick acceleration *a and to the
// velocity *u it kicks over half_h_s.
void applyChange(const Model& m, const ContactGeom& g, double dft, double half_h_s, VecX* a,
                 VecX* u) {
  for (const BodyJac& s : g.side) {
    applyInverseMass(m, nullptr, s.body, s.w_t, dft, a);
    applyInverseMass(m, nullptr, s.body, s.w_t, half_h_s * dft, u);
  }
}

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

void projectFriction(const Ctx& c, double half_h_s, const VecX& fn, const VecX& u_eval,
                     const std::vector<double>* target, VecX* ft, VecX* a, VecX* u) {
  const Model& m = c.m;
  Workspace& ws = c.ws;
  const size_t n = ws.candidates.size();
  ws.cp.ft_trial.assign(n, 0.0);
  // The contacts that carry friction, with their tangential compliances.
  std::vector<int>& rows = ws.cp.friction_rows;
  std::vector<double>& compliance = ws.cp.friction_compliance;
  rows.clear();
  compliance.clear();
  for (size_t i = 0; i < n; ++i) {
    const ContactGeom& g = ws.geoms[i];
    if (fn[i] <= 0.0 || g.params->friction <= 0.0) continue;
    const double w = tangentialCompliance(m, g);
    if (!(w > 0.0)) continue;
    rows.push_back(static_cast<int>(i));
    compliance.push_back(w);
  }
  // One contact alone is solved by its first sweep (the second only confirms it).
  const int sweeps = rows.size() == 1 ? 1 : kMaxSweeps;
  for (int sweep = 0; sweep < sweeps; ++sweep) {
    double largest = 0.0;
    for (size_t r = 0; r < rows.size(); ++r) {
      const size_t i = static_cast<size_t>(rows[r]);
      const ContactGeom& g = ws.geoms[i];
      const double limit = g.params->friction * fn[i];
      const double w = compliance[r];
      const double vt = slipVelocity(m, g, *u, u_eval) - (target ? (*target)[i] : 0.0);
      const double trial = (*ft)[i] - vt / (half_h_s * w);
      ws.cp.ft_trial[i] = trial;
      const double f = std::clamp(trial, -limit, limit);
      const double df = f - (*ft)[i];
      if (df == 0.0) continue;
      applyChange(m, g, df, half_h_s, a, u);
      (*ft)[i] = f;
      largest = std::max(largest, std::abs(df) / limit);
    }
    if (largest <= kSweepTolerance) break;
  }
}

void solveFriction(const Ctx& c, const StepState& s) {
  const Model& m = c.m;
  Workspace& ws = c.ws;
  ContactPhaseScratch& cp = ws.cp;
  const size_t n = ws.candidates.size();
  const double half_h = 0.5 * s.h_s;
  // Warm start: the start's force, within the end's cone.
  for (size_t i = 0; i < n; ++i) {
    const double limit = ws.geoms[i].params->friction * cp.fn1[i];
    if (cp.fn1[i] <= 0.0 || limit <= 0.0 || cp.released[i] || cp.opened[i]) continue;
    cp.ft1[i] = std::clamp(cp.ft0[i], -limit, limit);
    if (cp.ft1[i] != 0.0) applyChange(m, ws.geoms[i], cp.ft1[i], half_h, &cp.a1, &cp.u_end);
  }
  projectFriction(c, half_h, cp.fn1, cp.u_pred, nullptr, &cp.ft1, &cp.a1, &cp.u_end);
}

}  // namespace contact_phase
}  // namespace internal
}  // namespace threshing_sim
