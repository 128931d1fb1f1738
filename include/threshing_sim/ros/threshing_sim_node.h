// threshing_sim ROS layer: the node. A thin layer over the core (core/simulator.h).
//
// Three threads:
//  - the physics thread owns Model and Data. Paced by a Pacer on the steady clock (never a
//    ros::Timer: in sim clock mode the node itself produces /clock), it advances the core by
//    ~physics_dt per step, applies staged inputs (drum speed commands, reconfigured values,
//    reset) at step boundaries, and copies a Snapshot when an output stream is due;
//  - the output thread turns snapshots into messages, markers and transforms, publishes /clock
//    (sim clock mode, at most ~200 Hz of wall time, and always before a stamped message),
//    /diagnostics and the status line;
//  - the ROS spinner (main) runs the subscriber, services and dynamic_reconfigure callbacks,
//    which only stage values under a mutex.
//
// Output schedule: at real_time_factor > 0 the publish rates count wall time (for watching);
// at 0 they count simulated time, so that every output is a deterministic function of the
// scene and the applied commands (see docs/ros_interface.md, "Record, replay, re-simulate").
#pragma once

#include <diagnostic_updater/diagnostic_updater.h>
#include <dynamic_reconfigure/server.h>
#include <ros/ros.h>
#include <std_msgs/Float64.h>
#include <std_msgs/String.h>
#include <std_srvs/SetBool.h>
#include <std_srvs/Trigger.h>
#include <tf2_ros/static_transform_broadcaster.h>
#include <tf2_ros/transform_broadcaster.h>

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "threshing_sim/ThreshingSimConfig.h"
#include "threshing_sim/core/data.h"
#include "threshing_sim/core/model.h"
#include "threshing_sim/core/simulator.h"
#include "threshing_sim/ros/live_view.h"
#include "threshing_sim/ros/messages.h"
#include "threshing_sim/ros/node_params.h"
#include "threshing_sim/ros/pacer.h"
#include "threshing_sim/ros/snapshot.h"
#include "threshing_sim/ros/step_sampler.h"

namespace threshing_sim {

class ThreshingSimNode {
 public:
  // Loads and validates the parameters and the scene (throws std::invalid_argument naming the
  // offending parameter), advertises every interface and starts the threads.
  ThreshingSimNode(ros::NodeHandle nh, ros::NodeHandle pnh);
  ~ThreshingSimNode();

  // Stops and joins the threads and prints the final summary (idempotent).
  void stop();
  // The process's exit status after stop(): 1 when the run ended in an integrator failure.
  int exitStatus() const { return failed_ ? 1 : 0; }

 private:
  // A command scheduled by ~command_bag: applied at step boundary `step`.
  struct ScheduledCommand {
    long step;
    double speed_radps;
  };
  // Inputs staged by the callbacks, applied by the physics thread at a step boundary.
  struct Staged {
    std::optional<double> drum_target_radps;
    std::optional<ThreshingSimConfig> config;
    bool reset = false;
    long step_periods = 0;  // publish periods requested by ~step while paused
  };

  // --- start-up ---
  void loadCommandBag();
  void advertise(ros::NodeHandle& nh, ros::NodeHandle& pnh);
  void startReconfigure(ros::NodeHandle& pnh);

  // --- callbacks (spinner thread): stage and return ---
  void onDrumSpeedCommand(const std_msgs::Float64& msg);
  bool onPause(std_srvs::SetBool::Request& req, std_srvs::SetBool::Response& res);
  bool onStep(std_srvs::Trigger::Request& req, std_srvs::Trigger::Response& res);
  bool onReset(std_srvs::Trigger::Request& req, std_srvs::Trigger::Response& res);
  void onReconfigure(ThreshingSimConfig& config, std::uint32_t level);

  // --- physics thread ---
  void physicsLoop();
  void waitForSubscribers();
  void servePaused();
  void advanceOneStep(unsigned forced_streams);
  void applyStaged();
  void applyDrumTarget(double speed_radps);
  void applyConfig(const ThreshingSimConfig& config);
  void resetBodies();
  void requestReset(long ticket);
  void tryPendingReset();
  void finishReset(bool done, const std::string& message);
  void setRates(double contact_hz, double state_hz, double marker_hz);
  unsigned dueStreams();
  void trackPeaks();
  void takeSnapshot(unsigned streams);
  void publishCounters();

  // --- output thread ---
  void outputLoop();
  void publishSnapshot(const Snapshot& s, bool with_static_markers);
  void publishClock(const ros::Time& t);
  void printStatus(bool final_line);
  void diagnose(diagnostic_updater::DiagnosticStatusWrapper& stat);

  // --- live view (live_view_node.cc): what a user watches, plots and steers ---
  void startLiveView(ros::NodeHandle& nh, ros::NodeHandle& pnh);
  void loadCommandSchedule();
  bool onSkipToContact(std_srvs::Trigger::Request& req, std_srvs::Trigger::Response& res);
  void waitForViewer();
  bool pausedRepublishDue();
  StepStatus advanceSampled(long k);  // advance to boundary k, sampling strikes' accepted steps
  bool loopDue();                     // the drum passed the loop phase (~loop_revolutions)
  bool resetIfClear(bool full, const char* why);  // reset / re-seed unless bodies would overlap
  void reseedKernels();
  void adjustPace();  // free flight fast, contacts slow, skip to the next contact
  bool wallThrottle(double* last_s, double period_s) const;
  void fillLiveView(Snapshot* s);
  void publishLiveView(const Snapshot& s);

  ros::Time stampOf(long step) const;  // sim clock: step * physics_dt; wall clock: now
  long stepsPerPublishPeriod() const;  // the ~step service's advance

  // --- configuration (constant after start-up), then the model (physics thread) ---
  NodeParams params_;
  std::shared_ptr<const Model> model_;  // swapped for a recompiled copy on reconfigure
  double dt_s_ = 0;                     // physics step [s]
  std::int64_t dt_ns_ = 0;              // the same, in whole nanoseconds (stamps are k * dt_ns_)
  long end_step_ = 0;                   // stop after this boundary, 0 = never
  long reset_steps_ = 0;                // reset the bodies every this many steps, 0 = never
  std::vector<ScheduledCommand> schedule_;  // re-simulation: commands from ~command_bag

  // --- physics thread state ---
  Data data_;
  MonotonicClock clock_;
  Pacer pacer_;
  size_t next_scheduled_ = 0;         // first schedule_ entry not yet applied
  double rates_hz_[3] = {0, 0, 0};    // per stream bit: contact, state, marker [Hz]
  long period_steps_[3] = {1, 1, 1};  // schedule in steps (real_time_factor 0)
  double next_due_s_[3] = {0, 0, 0};  // schedule in steady seconds (real_time_factor > 0)
  std::vector<PeakContact> peaks_;
  std::vector<ContactEvent> pending_impacts_;
  std::vector<AppliedCommand> pending_commands_;
  bool pending_reset_ = false;
  bool reset_wanted_ = false;         // a reset (service or period) waits for a placement without
                                      // overlaps
  long reset_ticket_ = 0;             // the service ticket it answers (0: the periodic reset)
  long reset_wait_steps_ = 0;         // boundaries it has waited so far
  ThreadCpuClock cpu_clock_;          // the physics thread's CPU time
  StepMeter step_meter_{cpu_clock_};  // longest step since the last drum command
  double start_wall_s_ = 0;           // steady time the stepping began [s]
  double run_wall_s_ = 0;             // wall time from then until the physics thread ended [s]

  // --- shared: staged inputs and service hand-shakes (staged_mutex_) ---
  std::mutex staged_mutex_;
  std::condition_variable staged_cv_;  // wakes the physics thread
  std::condition_variable served_cv_;  // wakes a service waiting for the physics thread
  Staged staged_;
  std::atomic<bool> staged_dirty_{false};
  long resets_requested_ = 0, resets_done_ = 0;
  long steps_requested_ = 0, steps_done_ = 0;
  std::string reset_result_;  // the answer to the last served ~reset
  bool reset_ok_ = false;     // whether it reset the bodies
  std::string failure_text_;  // describe() of the last integrator failure
  double failure_t_s_ = 0;    // time of the state kept at the last integrator failure [s]
  std::optional<ThreshingSimConfig> last_good_config_;  // last reconfiguration accepted

  // --- shared: snapshot queue (queue_mutex_) ---
  std::mutex queue_mutex_;
  std::condition_variable queue_cv_;
  std::deque<Snapshot> queue_;

  // --- shared: flags and counters, written by the physics thread or callbacks ---
  std::atomic<bool> stop_{false}, paused_{false}, finished_{false}, failed_{false};
  std::atomic<bool> user_paused_{false};  // paused by ~pause or ~start_paused, not by a failure
  std::atomic<long> step_{0};             // last boundary reached
  std::atomic<long> rejected_commands_{0}, impacts_{0}, recoveries_{0};
  std::atomic<long> overruns_{0}, resyncs_{0};
  std::atomic<long> resets_deferred_{0}, resets_skipped_{0};  // resets that would overlap
  std::atomic<long> refused_reconfigures_{0};  // requests with a value NaN, inf or out of range
  std::atomic<double> advance_started_s_{-1};  // steady time the running advanceTo() began,
                                               // < 0 when none runs (the watchdog's input) [s]
  std::atomic<double> measured_rtf_{0}, step_rate_hz_{0}, peak_force_N_{0};
  std::atomic<double> longest_step_s_{0};        // longest step since the last drum command [CPU s]
  std::atomic<long> steps_since_command_{0};     // physics steps since then [-]
  std::atomic<double> max_deflection_ratio_{0};  // largest |w(L)| / L of the run [-]
  std::atomic<double> deflection_warning_s_{
      -1};  // first time beyond the valid range; < 0 never [s]

  // --- live view state (physics thread unless noted) ---
  StrikeRecorder strikes_{0.0};
  KernelImpulses kernel_impulses_;
  std::vector<StrikeRecord> pending_strikes_;
  std::unique_ptr<StepSampler> step_sampler_;  // advances to a boundary, sampling strikes
  double loop_anchor_rad_ = 0;                 // drum angle the loop phase counts from [rad]
  long loop_index_ = 0;                        // revolutions-of-the-loop passed [-]
  long loops_ = 0;                             // kernel re-seeds done [-]
  Data overlap_scratch_;                       // candidate state of a reset, for the overlap check
  std::atomic<double> slow_rtf_{1};            // ~real_time_factor as reconfigured (requested) [-]
  double free_flight_rtf_ = 0;         // factor away from contacts, 0 = same as slow_rtf_ [-]
  std::atomic<bool> skipping_{false};  // ~skip_to_contact running
  double skip_from_s_ = 0;             // simulation time the skip started at [s]
  double last_near_s_ = -1e9;          // last time a strike was near [s]
  bool skip_saw_free_ = false;         // the skip has passed free flight
  std::atomic<double> target_rtf_{1};  // factor the pacer aims at now [-]
  double last_paused_publish_s_ = 0;   // steady time of the last paused republish [s]
  double last_overlap_warn_s_ = -1e9;  // steady time of the last overlap warning [s]
  mutable double last_reject_warn_s_ = -1e9;  // spinner thread: rejected-command warning [s]
  DamageThresholds damage_;                   // kernel colours
  std::string scene_text_;                    // the scene as given (file text or parameter YAML)
  std::string scene_source_;                  // where it came from
  ros::Publisher drum_state_pub_, kernel_forces_pub_, strike_pub_, scene_pub_, static_marker_pub_;
  ros::Publisher view_box_pub_;
  ros::ServiceServer skip_srv_;
  bool static_published_ = false;  // output thread: static_markers sent
  bool reset_refused_ = false;     // the last ~reset would have overlapped (staged_mutex_)
  std::string last_overlap_;       // the pair a refused reset would overlap (staged_mutex_)

  // --- output thread state ---
  ContactStateBuilder contact_builder_;
  MarkerBuilder marker_builder_;
  Data scratch_;          // pose for the tooth shape functions
  ros::Time last_clock_;  // last /clock published
  bool clock_published_ = false;
  ros::Time last_tf_;          // last moving-transform stamp (tf2 drops repeats)
  bool tf_published_ = false;  // the t = 0 transforms go out too
  bool status_on_tty_ = false;

  // --- ROS interfaces ---
  ros::Publisher contact_pub_, impact_pub_, kernel_pub_, beam_pub_, marker_pub_, applied_pub_;
  ros::Publisher clock_pub_;
  ros::Subscriber command_sub_;
  ros::ServiceServer pause_srv_, step_srv_, reset_srv_;
  tf2_ros::TransformBroadcaster tf_;
  tf2_ros::StaticTransformBroadcaster static_tf_;
  diagnostic_updater::Updater diagnostics_;
  boost::recursive_mutex reconfigure_mutex_;
  std::unique_ptr<dynamic_reconfigure::Server<ThreshingSimConfig>> reconfigure_;

  std::thread physics_thread_, output_thread_;
  bool stopped_ = false;
};

}  // namespace threshing_sim
