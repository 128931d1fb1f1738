// Strike histories, what a snapshot records, and the commands a run replays (recording.h).
#include "threshing_sim/ros/recording.h"

#include <ros/console.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <utility>

#include "threshing_sim/ros/command_bag.h"

namespace threshing_sim {
namespace {

// A strike is "near" when a tooth-kernel pair closes within this many physics steps [-].
constexpr double kStrikeHorizonSteps = 3.0;

}  // namespace

StrikeLog::StrikeLog(const Model& model, const NodeParams& params, double dt_s)
    : sampler_(std::make_unique<StepSampler>(model, params.strike_sample_dt_s > 0,
                                             kStrikeHorizonSteps * dt_s)),
      // Event-driven (either scheme; islands: every island step, StepObserver): every accepted
      // step near a strike is a sample; time stepping: the integrator step is the finest
      // evaluation point there is. The integrator's steps are never cut for a sample.
      strikes_(model.integrator.type == IntegratorType::kTimeStepping ? model.integrator.dt_s
                                                                      : dt_s) {}

StepStatus StrikeLog::advance(const Model& model, Data* data, double t_s, double t_stop_s,
                              const std::function<void(const Data&)>& sample) {
  const StepStatus status = sampler_->advance(model, data, t_s, t_stop_s, [&](const Data& d) {
    strikes_.sample(d);
    kernel_impulses_.update(model, d);
    if (sample) sample(d);
  });
  for (StrikeRecord& r : strikes_.finished()) pending_strikes_.push_back(std::move(r));
  strikes_.finished().clear();
  return status;
}

void StrikeLog::afterStep(Data* data, long step) {
  // Completed impacts go out with the next snapshot.
  for (const ContactEvent& e : data->events)
    if (e.is_impact) impacts_.push_back(e);
  data->events.clear();
  trackPeaks(*data, step);
}

void StrikeLog::clearStrikes() {
  strikes_.clear();
  kernel_impulses_.clear();
}

void StrikeLog::trackPeaks(const Data& data, long k) {
  // A pair's episode restarts when it closes after being apart at the previous boundary; it
  // keeps the state, point and force of its largest normal force.
  for (const ContactInfo& c : data.contacts) {
    if (c.state == ContactState::kSeparated) continue;
    auto it = std::find_if(peaks_.begin(), peaks_.end(),
                           [&](const PeakContact& p) { return p.pair == c.pair; });
    if (it == peaks_.end()) it = peaks_.insert(peaks_.end(), PeakContact{c.pair});
    if (it->last_closed_step != k - 1 || c.normal_force_N > it->normal_force_N) {
      it->state = c.state;
      it->p_W = c.p_W;
      it->f_W = c.normal_force_N * c.n_W + c.tangential_force_N * Vec2(-c.n_W.y(), c.n_W.x());
      it->normal_force_N = c.normal_force_N;
    }
    it->last_closed_step = k;
  }
}

void StrikeLog::fill(const Model& model, const Data& data, Snapshot* s) {
  s->impacts = std::exchange(impacts_, {});
  s->commands = std::exchange(commands_, {});
  s->peaks = peaks_;
  s->kernel_forces = kernel_impulses_.forces(model, data);
  if (s->streams & kStateStream) s->strike_focus_W = strikeFocus(model, data);
  s->strikes = std::exchange(pending_strikes_, {});
}

CommandSchedule::CommandSchedule(const NodeParams& params, double dt_s, std::int64_t dt_ns) {
  if (params.end_time_s > 0)
    end_step_ = static_cast<long>(std::ceil(params.end_time_s / dt_s - 1e-9));
  if (!params.command_bag.empty()) loadBag(params, dt_s, dt_ns);
  if (!params.command_schedule.empty()) loadSchedule(params, dt_s);
}

void CommandSchedule::loadBag(const NodeParams& params, double dt_s, std::int64_t dt_ns) {
  const CommandBagContents bag =
      readCommandBag(params.command_bag, dt_ns, params.max_drum_speed_radps);
  for (const BagCommand& c : bag.commands) commands_.push_back({c.step, c.speed_radps, false});
  for (const BagFeedCommand& c : bag.feed_commands)
    commands_.push_back({c.step, c.rate_per_s, true});
  // In boundary order; at one boundary drum and feed commands act on separate state.
  std::stable_sort(commands_.begin(), commands_.end(),
                   [](const Command& a, const Command& b) { return a.step < b.step; });
  // Without ~end_time, run up to the last contact_state the recording holds.
  if (end_step_ == 0) {
    end_step_ = bag.last_contact_step;
    if (end_step_ == 0)
      throw std::invalid_argument("~command_bag (" + params.command_bag +
                                  "): holds no contact_state to end the run at; set ~end_time");
  }
  ROS_INFO("re-simulating %zu drum speed and %zu feed rate commands up to t = %g s",
           bag.commands.size(), bag.feed_commands.size(), end_step_ * dt_s);
}

void CommandSchedule::loadSchedule(const NodeParams& params, double dt_s) {
  const std::string where = "~command_schedule (" + params.command_schedule + "): ";
  if (!params.command_bag.empty())
    throw std::invalid_argument(where + "cannot be combined with ~command_bag");
  try {
    const YAML::Node root = YAML::LoadFile(params.command_schedule);
    if (!root["commands"] || !root["commands"].IsSequence())
      throw std::invalid_argument(where + "needs a list 'commands' of {time: s, speed: rad/s}");
    for (const YAML::Node& c : root["commands"]) {
      const double t_s = c["time"].as<double>(), speed_radps = c["speed"].as<double>();
      if (!std::isfinite(t_s) || t_s < 0 || !std::isfinite(speed_radps) ||
          std::abs(speed_radps) > params.max_drum_speed_radps)
        throw std::invalid_argument(where + "bad command (time " + std::to_string(t_s) +
                                    " s, speed " + std::to_string(speed_radps) + " rad/s)");
      // Applied at the first step boundary at or after its time.
      commands_.push_back({static_cast<long>(std::ceil(t_s / dt_s - 1e-9)), speed_radps, false});
    }
  } catch (const YAML::Exception& e) {
    throw std::invalid_argument(where + e.what());
  }
  std::stable_sort(commands_.begin(), commands_.end(),
                   [](const Command& a, const Command& b) { return a.step < b.step; });
  ROS_INFO("~command_schedule: %zu drum speed commands", commands_.size());
}

}  // namespace threshing_sim
