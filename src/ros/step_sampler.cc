#include "threshing_sim/ros/step_sampler.h"

#include "threshing_sim/ros/live_view.h"

namespace threshing_sim {

StepSampler::StepSampler(const Model& model, bool enabled, double horizon_s)
    : enabled_(enabled && samplesSteps(model)), horizon_s_(horizon_s) {}

bool StepSampler::samplesSteps(const Model& model) {
  return model.integrator.type == IntegratorType::kEventDriven && !model.integrator.islands;
}

StepStatus StepSampler::advance(const Model& model, Data* data, double t_end_s,
                                const std::function<void(const Data&)>& sample) {
  if (enabled_ && data->t_s < t_end_s && StrikeRecorder::strikeNear(*data, horizon_s_)) {
    int stalled = 0;  // accepted steps in a row that left the time unchanged
    for (long n = 0; n < kMaxSampledSteps && data->t_s < t_end_s; ++n) {
      guard_z_ = data->z;
      guard_u_ = data->u;
      const double t0_s = data->t_s, theta0_rad = data->theta_rad, omega0_radps = data->omega_radps;
      const long steps0 = data->steps;
      const StepStatus s = step(model, data);
      if (s == StepStatus::kOk && data->z.allFinite() && data->u.allFinite()) {
        ++sampled_steps_;
        sample(*data);
        stalled = data->t_s > t0_s ? 0 : stalled + 1;
        if (stalled < kMaxStalledSteps) continue;
        break;  // advanceTo() decides whether time has stalled for good
      }
      // advanceTo() redoes this interval with its guard, recovery and work budget.
      data->z = guard_z_;
      data->u = guard_u_;
      data->t_s = t0_s;
      data->theta_rad = theta0_rad;
      data->omega_radps = omega0_radps;
      data->steps = steps0;
      ++fallbacks_;
      break;
    }
  }
  // Lone kernels stay on their own clocks until a snapshot reads them (syncBodies). A no-op
  // when the last sampled step ended at or past t_end_s.
  const StepStatus status = advanceToLazy(model, data, t_end_s);
  sample(*data);
  return status;
}

}  // namespace threshing_sim
