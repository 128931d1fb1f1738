#include "threshing_sim/ros/step_sampler.h"

#include <cmath>
#include <limits>

#include "threshing_sim/ros/live_view.h"

namespace threshing_sim {

StepSampler::StepSampler(const Model& model, bool enabled, double horizon_s)
    : enabled_(enabled && samplesSteps(model)), horizon_s_(horizon_s) {}

bool StepSampler::samplesSteps(const Model& model) {
  return model.integrator.type == IntegratorType::kEventDriven;
}

StepStatus StepSampler::advance(const Model& model, Data* data, double t_end_s, double t_stop_s,
                                const std::function<void(const Data&)>& sample) {
  t_end_s = std::min(t_end_s, t_stop_s);
  if (enabled_ && data->t_s < t_end_s && StrikeRecorder::strikeNear(*data, horizon_s_)) {
    // One step (island scheme: one window) per call: advancePast to just past the current time
    // takes the step the integrator chooses, with advanceTo's guard, recovery and budget. Under
    // the island scheme the lone kernels are brought to the step's end for the sample.
    long n = 0;
    for (; n < kMaxSampledSteps && data->t_s < t_end_s; ++n) {
      const double just_past_s = std::nextafter(data->t_s, std::numeric_limits<double>::infinity());
      const StepStatus status = advancePast(model, data, just_past_s, t_stop_s);
      if (status == StepStatus::kFailed) return status;
      ++sampled_steps_;
      if (data->t_s < t_end_s) sample(*data);
    }
    if (n == kMaxSampledSteps) ++handovers_;
  }
  // Away from strikes: to the boundary in one call, the last step ending at or past it. Lone
  // kernels stay on their own clocks until a snapshot reads them (syncBodies).
  const StepStatus status = advancePastLazy(model, data, t_end_s, t_stop_s);
  sample(*data);
  return status;
}

}  // namespace threshing_sim
