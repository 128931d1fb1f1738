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
      if (islands) island_view_.finish();
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
  if (watch) island_view_.finish();
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
  // Recorded, to be replayed in time order (finish()): the islands of a window come one after
  // the other, each from the window's start.
  Entry e;
  e.t_s = step.t_s;
  e.theta_rad = step.theta_rad;
  e.omega_radps = step.omega_radps;
  e.kernels_begin = kernels_.size();
  kernels_.insert(kernels_.end(), step.kernels->begin(), step.kernels->end());
  e.dofs_begin = dofs_.size();
  if (scratch_z_.size() != model.n_dof) {
    scratch_z_.setZero(model.n_dof);
    scratch_u_.setZero(model.n_dof);
  }
  step.writeState(model, &scratch_z_, &scratch_u_);
  auto keep = [this](int offset, int n) {
    for (int j = offset; j < offset + n; ++j) dofs_.push_back({j, scratch_z_[j], scratch_u_[j]});
  };
  for (int k : *step.teeth) keep(model.teeth[k].dof_offset, model.teeth[k].n_modes);
  for (int i : *step.kernels) keep(model.kernels[i].dof_offset, 3);
  e.contacts_begin = contacts_.size();
  contacts_.insert(contacts_.end(), step.contacts->begin(), step.contacts->end());
  e.events_begin = events_.size();
  events_.insert(events_.end(), step.events->begin(), step.events->end());
  entries_.push_back(e);
}

void StepSampler::IslandView::finish() {
  order_.resize(entries_.size());
  for (size_t k = 0; k < order_.size(); ++k) order_[k] = k;
  std::stable_sort(order_.begin(), order_.end(),
                   [this](size_t a, size_t b) { return entries_[a].t_s < entries_[b].t_s; });
  for (size_t k : order_) replay(k);
  entries_.clear();
  kernels_.clear();
  dofs_.clear();
  contacts_.clear();
  events_.clear();
}

void StepSampler::IslandView::replay(size_t k) {
  const Entry& e = entries_[k];
  const bool last = k + 1 == entries_.size();
  const Entry* next = last ? nullptr : &entries_[k + 1];
  view_.t_s = e.t_s;
  view_.theta_rad = e.theta_rad;
  view_.omega_radps = e.omega_radps;
  for (size_t j = e.dofs_begin; j < (last ? dofs_.size() : next->dofs_begin); ++j) {
    view_.z[dofs_[j].index] = dofs_[j].z;
    view_.u[dofs_[j].index] = dofs_[j].u;
  }
  // The island's contacts replace those it had (every pair has a kernel of its island).
  const auto k0 = kernels_.begin() + e.kernels_begin;
  const auto k1 = last ? kernels_.end() : kernels_.begin() + next->kernels_begin;
  auto of_island = [k0, k1](const ContactInfo& c) {
    const auto has = [k0, k1](int i) { return std::binary_search(k0, k1, i); };
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
  view_.contacts.insert(view_.contacts.end(), contacts_.begin() + e.contacts_begin,
                        last ? contacts_.end() : contacts_.begin() + next->contacts_begin);
  view_.events.assign(events_.begin() + e.events_begin,
                      last ? events_.end() : events_.begin() + next->events_begin);
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
