// threshing_sim ROS layer: the physics thread. It owns the model and its Data.
//
// Paced by a Pacer on the steady clock (never a ros::Timer: in sim clock mode the node itself
// produces /clock), it advances the core by ~physics_dt per step, applies staged inputs (drum
// speed commands, reconfigured values, reset) and scheduled commands at step boundaries,
// re-seeds the demo loop, and hands a Snapshot to the output thread when a stream is due.
//
//  - StreamSchedule: when contact_state, the state topics and the markers are due (simulated
//    time at real_time_factor 0, wall time otherwise);
//  - Pace: the factor the pacer aims at (slow near strikes, ~free_flight_factor away from them,
//    as fast as possible during ~skip_to_contact);
//  - PhysicsLoop: the loop, pausing, ~step, resets, reconfiguration and snapshots; at
//    real_time_factor 0 (a recording) also the strike's frames (StrikeFrames: markers every
//    1 us of simulated time through a strike), so that a replay can show the strike.
#pragma once

#include <ros/publisher.h>

#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "threshing_sim/ThreshingSimConfig.h"
#include "threshing_sim/core/data.h"
#include "threshing_sim/core/model.h"
#include "threshing_sim/ros/demo_loop.h"
#include "threshing_sim/ros/node_feed.h"
#include "threshing_sim/ros/node_params.h"
#include "threshing_sim/ros/node_shared.h"
#include "threshing_sim/ros/pacer.h"
#include "threshing_sim/ros/recording.h"
#include "threshing_sim/ros/step_history.h"

namespace threshing_sim {

class StreamSchedule {
 public:
  explicit StreamSchedule(double dt_s) : dt_s_(dt_s) {}
  void setRates(double contact_hz, double state_hz, double marker_hz);
  // Stream bits due at boundary k: by step count at factor 0, else by wall time now_s.
  unsigned due(long k, bool by_steps, double now_s);
  // The ~step service's advance: one contact_state period of simulated time at factor rtf.
  long stepsPerPublishPeriod(double rtf) const;

 private:
  double dt_s_;
  double rates_hz_[3] = {0, 0, 0};    // per stream bit: contact, state, marker [Hz]
  long period_steps_[3] = {1, 1, 1};  // schedule in steps (real_time_factor 0)
  double next_due_s_[3] = {0, 0, 0};  // schedule in steady seconds (real_time_factor > 0)
};

class Pace {
 public:
  explicit Pace(double free_flight_rtf) : free_flight_rtf_(free_flight_rtf) {}
  void setFreeFlight(double rtf) { free_flight_rtf_ = rtf; }
  // The factor for the step just taken: requested_rtf near strikes, the free-flight factor
  // away from them, 0 while skipping (skipping is cleared when the skip ends).
  double next(const Model& model, const Data& data, double requested_rtf,
              std::atomic<bool>* skipping);

 private:
  double free_flight_rtf_;      // factor away from contacts, 0 = same as requested [-]
  double skip_from_s_ = 0;      // simulation time the skip started at [s]
  double last_near_s_ = -1e9;   // last time a strike was near [s]
  bool skip_saw_free_ = false;  // the skip has passed free flight
};

// The strike's frames of a recording (real-time factor 0, sim clock): the states drawn every
// kFrame_ns of simulated time (1 us: 33 frames for the default scene's 33 us strike) while a
// tooth-kernel pair is closed at either end of an accepted integrator step. Each frame is the
// cubic Hermite interpolant (positions and their derivatives u = dz/dt) between the two
// accepted steps around it, which the sampler hands over; the integrator's steps are not
// changed. A frame is only drawn strictly between two step boundaries (the boundary's own
// snapshot draws the state there), so the frames' stamps increase.
class StrikeFrames {
 public:
  static constexpr std::int64_t kFrame_ns = 1000;  // frame spacing in simulated time [ns]
  // Frames of one stretch of closed tooth-kernel contact at most (a kernel resting on a tooth
  // would otherwise add a frame per us for as long as it rests) [-].
  static constexpr long kMaxEpisodeFrames = 200;
  // Frames of a step with only one end in contact, next to that end at most [-].
  static constexpr long kTailFrames = 3;
  // The state at a step boundary, where the next interpolation starts (after any reset).
  void start(const Data& data);
  // The state after an accepted step (or at the step end that passed a boundary): calls
  // emit(frame) for every frame time in (previous state, data.t_s].
  void sample(const Data& data, const std::function<void(const FrameState&)>& emit);

 private:
  StepState prev_, next_;
  FrameState frame_;
  long episode_frames_ = 0;  // frames of the current stretch of closed contact
};

// What the physics thread reads of the ROS interface: the outputs whose subscribers it waits
// for, and how it hands back the contact values in force after a refused reconfiguration.
struct PhysicsHooks {
  std::vector<const ros::Publisher*> outputs;  // ~wait_for_subscribers
  const ros::Publisher* markers = nullptr;     // ~wait_for_viewer
  std::function<void(const ThreshingSimConfig&)> restore_config;
};

class PhysicsLoop {
 public:
  PhysicsLoop(const NodeParams& params, const NodeTiming& timing,
              std::shared_ptr<const Model> model, RunFlags* flags, RunCounters* counters,
              Inbox* inbox, SnapshotQueue* queue);
  void setHooks(PhysicsHooks hooks) { hooks_ = std::move(hooks); }
  // A scene with a `feed` section (before run()): the feed starts at t = 0, takes feed rate
  // commands and replaces the demo loop (a fed drum is not re-seeded); plastic_force_N is the
  // damage threshold of the throughput counts [N].
  void setFeed(const FeedSpec& spec, double plastic_force_N);

  void run();  // the thread's body: returns on stop or at the end of a bounded run
  double runWallSeconds() const { return run_wall_s_; }  // after run() returned [s]

 private:
  void waitForSubscribers();
  void waitForViewer();
  bool pausedRepublishDue();
  void servePaused();
  void advanceOneStep(unsigned forced_streams);
  void fail(const std::string& text);
  void applyStaged();
  void applyDrumTarget(double speed_radps);
  void applyFeedRate(double rate_per_s);
  void applyConfig(const ThreshingSimConfig& config);
  void resetBodies();
  void requestReset(long ticket);
  void tryPendingReset();
  void finishReset(bool done, const std::string& message);
  void adjustPace();
  void takeSnapshot(unsigned streams, bool frame_only = false);
  void takeFrame(const FrameState& frame);
  Snapshot runFields() const;  // the fields snapshots and frames share
  void publishCounters();

  struct ResetRequest {
    bool wanted = false;  // a reset (service or period) waits for a placement without overlaps
    long ticket = 0;      // the service ticket it answers (0: the periodic reset)
    long wait_steps = 0;  // boundaries it has waited so far
  };

  const NodeParams& params_;
  const NodeTiming& timing_;
  RunFlags& flags_;
  RunCounters& counters_;
  Inbox& inbox_;
  SnapshotQueue& queue_;
  PhysicsHooks hooks_;
  std::shared_ptr<const Model> model_;  // swapped for a recompiled copy on reconfigure
  Data data_;
  MonotonicClock clock_;
  Pacer pacer_;
  StreamSchedule streams_;
  Pace pace_;
  CommandSchedule schedule_;
  StrikeLog log_;
  DemoLoop demo_;
  long reset_steps_ = 0;  // reset the bodies every this many steps, 0 = never
  ResetRequest reset_;
  bool pending_reset_ = false;            // the next snapshot starts the markers over
  StrikeFrames frames_;                   // the strike's frames at factor 0
  std::vector<Snapshot> frames_pending_;  // frames for the next snapshot
  StepHistory history_;       // island scheme, live factor: the last advance's accepted steps
  FrameState boundary_;       // a boundary's state interpolated from history_
  ThreadCpuClock cpu_clock_;  // the physics thread's CPU time
  StepMeter step_meter_{cpu_clock_};  // longest step since the last drum command
  double start_wall_s_ = 0;           // steady time the stepping began [s]
  double run_wall_s_ = 0;             // wall time from then until the thread ended [s]
  double last_paused_publish_s_ = 0;  // steady time of the last paused republish [s]
  std::unique_ptr<NodeFeed> feed_;    // the continuous feed, if the scene has one
};

}  // namespace threshing_sim
