#include "threshing_sim/ros/step_sampler.h"

#include <algorithm>
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
    // the island scheme the islands' steps inside the window are sampled as they are taken
    // (IslandView), and the lone kernels are brought to the window's end for its sample.
    const bool islands = model.integrator.islands;
    long n = 0;
    for (; n < kMaxSampledSteps && data->t_s < t_end_s; ++n) {
      const double just_past_s = std::nextafter(data->t_s, std::numeric_limits<double>::infinity());
      if (islands) {
        island_view_.begin(*data, &sample, -1.0);
        data->observer = &island_view_;
      }
      const StepStatus status = advancePast(model, data, just_past_s, t_stop_s);
      data->observer = nullptr;
      if (status == StepStatus::kFailed) return status;
      sampled_steps_ += islands ? std::max(1L, island_view_.steps()) : 1;
      if (data->t_s < t_end_s) sample(*data);
    }
    if (n == kMaxSampledSteps) ++handovers_;
  }
  // Away from strikes: to the boundary in one call, the last step ending at or past it. Lone
  // kernels stay on their own clocks until a snapshot reads them (syncBodies). Under islands a
  // pair out of every island is not among the contacts, so a strike can begin and end inside
  // this call's windows: the islands' steps are watched, and sampled while a strike is near.
  const bool watch = enabled_ && model.integrator.islands && data->t_s < t_end_s;
  if (watch) {
    island_view_.begin(*data, &sample, horizon_s_);
    data->observer = &island_view_;
  }
  const StepStatus status = advancePastLazy(model, data, t_end_s, t_stop_s);
  data->observer = nullptr;
  if (watch) sampled_steps_ += island_view_.sampled();
  sample(*data);
  return status;
}

void StepSampler::IslandView::begin(const Data& data,
                                    const std::function<void(const Data&)>* sample,
                                    double horizon_s) {
  source_ = &data;
  sample_ = sample;
  horizon_s_ = horizon_s;
  steps_ = 0;
  sampled_ = 0;
  was_near_ = false;
}

void StepSampler::IslandView::copySource() {
  const Data& data = *source_;
  view_.t_s = data.t_s;
  view_.steps = data.steps;
  view_.theta_rad = data.theta_rad;
  view_.omega_radps = data.omega_radps;
  view_.omega_target_radps = data.omega_target_radps;
  view_.alpha_radps2 = data.alpha_radps2;
  view_.z = data.z;
  view_.u = data.u;
  view_.kernel_attached = data.kernel_attached;
  view_.contacts = data.contacts;
  view_.events.clear();
}

void StepSampler::IslandView::islandStep(const Model& model, const IslandStep& step) {
  // The whole state is copied at the advance's first island step only: an advance without
  // islands (lone bodies only) costs nothing per kernel.
  if (steps_++ == 0) copySource();
  view_.t_s = step.t_s;
  view_.theta_rad = step.theta_rad;
  view_.omega_radps = step.omega_radps;
  step.writeState(model, &view_.z, &view_.u);
  // The island's contacts replace those it had (every pair has a kernel of its island).
  const std::vector<int>& kernels = *step.kernels;
  auto of_island = [&kernels](const ContactInfo& c) {
    const auto has = [&kernels](int i) {
      return std::binary_search(kernels.begin(), kernels.end(), i);
    };
    switch (c.pair.kind) {
      case PairKind::kToothKernel:
        return has(c.pair.b);
      case PairKind::kKernelKernel:
        return has(c.pair.a) || has(c.pair.b);
      default:
        return has(c.pair.a);
    }
  };
  view_.contacts.erase(std::remove_if(view_.contacts.begin(), view_.contacts.end(), of_island),
                       view_.contacts.end());
  view_.contacts.insert(view_.contacts.end(), step.contacts->begin(), step.contacts->end());
  view_.events = *step.events;
  // Watching (horizon_s_ >= 0): the steps near a strike, and the first after (its end).
  if (horizon_s_ >= 0) {
    const bool near = StrikeRecorder::strikeNear(view_, horizon_s_);
    const bool take = near || was_near_;
    was_near_ = near;
    if (!take) return;
  }
  ++sampled_;
  (*sample_)(view_);
}

}  // namespace threshing_sim
