// threshing_sim ROS layer, physics thread: strike histories and what is recorded between two
// snapshots, and the commands a run replays.
//
//  - StrikeLog: advances the core to a boundary sampling strikes (StepSampler), keeps the
//    strike histories, per-kernel impulses, each pair's peak contact, completed impacts and
//    applied commands until the next snapshot takes them;
//  - CommandSchedule: drum speed commands at step boundaries, from ~command_bag (a recording
//    re-simulated) or ~command_schedule (timed commands), feed rate commands from ~command_bag,
//    and the boundary a bounded run ends at.
#pragma once

#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "threshing_sim/core/data.h"
#include "threshing_sim/core/model.h"
#include "threshing_sim/core/simulator.h"
#include "threshing_sim/ros/live_view.h"
#include "threshing_sim/ros/node_params.h"
#include "threshing_sim/ros/snapshot.h"
#include "threshing_sim/ros/step_sampler.h"

namespace threshing_sim {

class StrikeLog {
 public:
  // dt_s: the physics step; strikes are sampled at the integrator's accepted steps (event-driven
  // global scheme), its step (time stepping) or the physics step (island scheme).
  StrikeLog(const Model& model, const NodeParams& params, double dt_s);

  // Advances data past boundary time t_s (StepSampler: to the first step end at or past it; no
  // step is cut but at t_stop_s, the run's end), sampling strikes and kernel impulses on the
  // way. With `sample`, also calls sample(data) with every state the sampler hands over (after
  // each step near a strike, and at the end): the strike's frames (StrikeFrames).
  StepStatus advance(const Model& model, Data* data, double t_s, double t_stop_s,
                     const std::function<void(const Data&)>& sample = {});
  // After boundary `step`: the completed impacts of data.events (cleared) and the pairs' peaks.
  void afterStep(Data* data, long step);
  void noteCommand(const AppliedCommand& c) { commands_.push_back(c); }
  // The bodies moved (reset, re-seed): open strikes and impulse sums are forgotten.
  void clearStrikes();
  void clearPeaks() { peaks_.clear(); }
  const std::vector<PeakContact>& peaks() const { return peaks_; }
  // Moves what was recorded since the previous snapshot into s (kernel forces, strike focus on
  // the state stream, finished strikes, impacts, commands, peaks).
  void fill(const Model& model, const Data& data, Snapshot* s);

 private:
  void trackPeaks(const Data& data, long step);

  std::unique_ptr<StepSampler> sampler_;  // advances to a boundary, sampling strikes
  StrikeRecorder strikes_;
  KernelImpulses kernel_impulses_;
  std::vector<StrikeRecord> pending_strikes_;
  std::vector<PeakContact> peaks_;
  std::vector<ContactEvent> impacts_;     // completed since the previous snapshot
  std::vector<AppliedCommand> commands_;  // applied since the previous snapshot
};

class CommandSchedule {
 public:
  // Reads ~command_bag, then ~command_schedule (refused together) and ~end_time; throws
  // std::invalid_argument naming the parameter.
  CommandSchedule(const NodeParams& params, double dt_s, std::int64_t dt_ns);

  // Commands due at boundary k not yet handed out, in order (each once): drum(speed [rad/s])
  // for a drum speed command, feed(rate [1/s]) for a feed rate command.
  template <typename Drum, typename Feed>
  void applyDue(long k, Drum drum, Feed feed) {
    while (next_ < commands_.size() && commands_[next_].step <= k) {
      const Command& c = commands_[next_++];
      if (c.feed)
        feed(c.value);
      else
        drum(c.value);
    }
  }
  long endStep() const { return end_step_; }  // stop after this boundary, 0 = never

 private:
  struct Command {
    long step;
    double value;  // drum speed [rad/s] or feed rate [1/s]
    bool feed;     // a feed rate command
  };
  void loadBag(const NodeParams& params, double dt_s, std::int64_t dt_ns);
  void loadSchedule(const NodeParams& params, double dt_s);

  std::vector<Command> commands_;
  size_t next_ = 0;    // first entry not yet applied
  long end_step_ = 0;  // stop after this boundary, 0 = never
};

}  // namespace threshing_sim
