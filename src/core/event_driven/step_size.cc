// The event-driven integrator's step size: the motion bound, the trial step (stage 3) and the
// step-size law with its adaptive steps (stage 5).
#include <algorithm>
#include <cmath>

#include "context.h"

namespace threshing_sim {
namespace internal {
namespace event_driven {

namespace {

// The step-size law: the factor by which a step with error norm err (1 = the tolerance) is
// scaled, for a retry (err > 1) or for the next step (err <= 1).
double retryFactor(double err) {
  return std::max(0.1, 0.9 * std::pow(std::isfinite(err) ? err : 1e10, -0.2));
}
double growthFactor(double err) {
  return std::min(5.0, 0.9 * std::pow(std::max(err, 1e-10), -0.2));
}

}  // namespace

// Size of the next trial step: bounded by the broad-phase margin over the fastest motion.
double motionBound(const Ctx& c) {
  double v = 1e-6;
  for (const ToothModel& tm : c.m.teeth)
    v = std::max(
        v, std::abs(c.d.omega_radps) * (c.m.drum.radius_m + tm.length_m) +
               (tm.n_modes == 0 ? 0.0
                : tm.beam_model == ToothBeamModel::kLargeDeflection
                    // |theta_dot| <= sum |q_dot_i| (|phi_i| <= 1), points within L of the root.
                    ? tm.length_m * c.d.u.segment(tm.dof_offset, tm.n_modes).lpNorm<1>()
                    : 30.0 * c.d.u.segment(tm.dof_offset, tm.n_modes).norm()));
  for (int i = 0; i < static_cast<int>(c.m.kernels.size()); ++i)
    v = std::max(v, kernelSpeedBound(c.m, c.d.u, i));
  return v;
}

// Stage 3: the trial step length: the last proposal, within max_step and the broad-phase
// margin over the motion bound, cut short to land on t_end or on the end of a drum ramp.
void planStep(const Ctx& c, double v_bound_mps, StepPlan* plan) {
  const Model& m = c.m;
  const Data& d = c.d;
  double h = c.ws.ed.h > 0 ? c.ws.ed.h : std::min(m.integrator.max_step_s, 1e-6);
  h = std::min({h, m.integrator.max_step_s, plan->margin_m / v_bound_mps});
  // A step cut short to land on t_end (or on the end of a drum ramp) must not shrink the
  // step-size proposal for the steps after it.
  plan->h_wanted_s = h;
  h = std::min(h, plan->t_end_s - d.t_s);
  plan->truncated = h < plan->h_wanted_s;
  const double ramp = timeToTarget(m, d);
  if (ramp > 1e-15 && ramp < h) h = ramp;
  if (!(h > 0)) h = plan->t_end_s - d.t_s;
  plan->h_s = h;
}

// Stage 5: adaptive Dormand-Prince steps from the step start until the error is within the
// tolerance; the end state in ws.ed.z1, ws.ed.u1. False after too many rejections.
bool integrateAdaptive(const Ctx& c, StepPlan* plan) {
  Workspace& ws = c.ws;
  Data* d = &c.d;
  const int n = c.m.n_dof;
  ws.ed.udot_end.resize(n);
  ws.ed.z1.resize(n);
  ws.ed.u1.resize(n);
  double err = 0, torque1 = 0;
  double& h = plan->h_s;
  for (int attempt = 0;; ++attempt) {
    if (!dopriStep(c, d->t_s, h, d->z, d->u, &ws.ed.z1, &ws.ed.u1, &err, &torque1)) err = kInf;
    if (err <= 1.0) break;
    plan->rejected = true;
    ++d->stats.rejected_steps;
    h *= retryFactor(err);
    if (h < 1e-15 || attempt > 200) return false;
  }
  plan->h_next_s = h * growthFactor(err);
  return true;
}

}  // namespace event_driven
}  // namespace internal
}  // namespace threshing_sim
