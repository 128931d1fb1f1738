// threshing_sim ROS layer: what the node's parts share across threads.
//
//  - NodeTiming: the physics step and the stamps (constant after start-up);
//  - RunFlags: run, pause, failure and end flags and the last boundary reached (atomics);
//  - RunCounters: the numbers the physics thread and the callbacks publish for the status line,
//    /diagnostics and the overlay (atomics);
//  - Inbox: inputs the callbacks stage for the physics thread, and the hand-shakes of the
//    services that wait for it (one mutex);
//  - SnapshotQueue: snapshots from the physics thread to the output thread;
//  - RunStatus / runStatus(): the run's state in one line, the same for /diagnostics, the
//    status line and the overlay.
#pragma once

#include <ros/time.h>

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <mutex>
#include <optional>
#include <string>

#include "threshing_sim/ThreshingSimConfig.h"
#include "threshing_sim/ros/snapshot.h"

namespace threshing_sim {

struct NodeTiming {
  double dt_s = 0;         // physics step [s]
  std::int64_t dt_ns = 0;  // the same, in whole nanoseconds (stamps are k * dt_ns)
  bool sim_clock = false;  // stamps in simulated time (else wall time)
  // sim clock: step * physics_dt; wall clock: now.
  ros::Time stampOf(long step) const {
    return sim_clock ? ros::Time().fromNSec(step * dt_ns) : ros::Time::now();
  }
};

struct RunFlags {
  std::atomic<bool> stop{false}, paused{false}, finished{false}, failed{false};
  std::atomic<bool> user_paused{false};  // paused by ~pause or ~start_paused, not by a failure
  std::atomic<bool> skipping{false};     // ~skip_to_contact running
  std::atomic<long> step{0};             // last boundary reached
};

struct RunCounters {
  std::atomic<long> rejected_commands{0}, impacts{0}, recoveries{0};
  std::atomic<long> rejected_feed_commands{0};  // feed_rate_cmd refused (also counted above) [-]
  std::atomic<long> overruns{0}, resyncs{0};
  std::atomic<long> resets_deferred{0}, resets_skipped{0};  // resets that would overlap
  std::atomic<long> refused_reconfigures{0};     // requests with a value NaN, inf or out of range
  std::atomic<long> interpolated_boundaries{0};  // boundaries published between two accepted
                                                 // steps (island scheme, live factor) [-]
  std::atomic<double> advance_started_s{-1};     // steady time the running advanceTo() began,
                                                 // < 0 when none runs (the watchdog's input) [s]
  std::atomic<double> measured_rtf{0}, step_rate_hz{0}, peak_force_N{0};
  std::atomic<double> longest_step_s{0};         // longest step since the last drum command [CPU s]
  std::atomic<long> steps_since_command{0};      // physics steps since then [-]
  std::atomic<double> max_deflection_ratio{0};   // largest |w(L)| / L of the run [-]
  std::atomic<double> deflection_warning_s{-1};  // first time beyond the valid range; < 0 never
  std::atomic<double> requested_rtf{1};          // ~real_time_factor as reconfigured [-]
  std::atomic<double> target_rtf{1};             // factor the pacer aims at now [-]
  std::atomic<double> loop_period_s{0};          // the physics loop's period [s]
};

// Inputs staged by the callbacks, applied by the physics thread at a step boundary.
struct StagedInputs {
  std::optional<double> drum_target_radps;
  std::optional<double> feed_rate_per_s;  // feed_rate_cmd, checked against the pool [1/s]
  std::optional<ThreshingSimConfig> config;
  bool reset = false;
  long step_periods = 0;  // publish periods requested by ~step while paused
};

// Guarded by `mutex`; staged_cv wakes the physics thread, served_cv a waiting service.
struct Inbox {
  std::mutex mutex;
  std::condition_variable staged_cv;
  std::condition_variable served_cv;
  StagedInputs staged;
  std::atomic<bool> dirty{false};  // staged holds something
  long resets_requested = 0, resets_done = 0;
  long steps_requested = 0, steps_done = 0;
  std::string reset_result;  // the answer to the last served ~reset
  bool reset_ok = false;     // whether it reset the bodies
  std::string failure_text;  // describe() of the last integrator failure
  double failure_t_s = 0;    // time of the state kept at the last integrator failure [s]
  std::optional<ThreshingSimConfig> last_good_config;  // last reconfiguration accepted
};

// Snapshots from the physics thread to the output thread, bounded: the producer waits when full.
class SnapshotQueue {
 public:
  static constexpr size_t kMaxQueued = 64;
  // Back-pressure: waits while the queue is full, unless stop is set.
  void push(Snapshot s, const std::atomic<bool>& stop);
  // Everything queued, after waiting up to timeout_s for something (or stop).
  std::deque<Snapshot> takeAll(double timeout_s, const std::atomic<bool>& stop);
  bool empty();
  void wake() { cv_.notify_all(); }

 private:
  std::mutex mutex_;
  std::condition_variable cv_;
  std::deque<Snapshot> queue_;
};

// The run's state as /diagnostics, the status line and the overlay show it: one computation,
// so that the overlay and /diagnostics agree.
struct RunStatus {
  enum Level : std::uint8_t { kOk = 0, kWarn = 1, kError = 2 };  // diagnostic_msgs' levels
  Level level = kOk;
  // "RUNNING", "PAUSED", "FINISHED", "SLOW" (the pace is not held), "FAILED" (integrator
  // failure) or "STALLED" (the watchdog: a physics step runs too long).
  std::string state = "RUNNING";
  std::string message = "running";  // the /diagnostics summary: the state's cause
};

// A measured real-time factor below this fraction of the target is a warning [-].
constexpr double kSlowFraction = 0.9;
// ~skip_to_contact gives up after this much simulated time without a strike [s].
constexpr double kMaxSkip_s = 2.0;

// busy_s: how long the running physics step has run [wall s]; failure: describe() of the
// last integrator failure. Errors first (watchdog, failure), then warnings (numerical
// recoveries, the pace not held, deflection beyond the beam model, skipped resets), else OK.
RunStatus runStatus(const RunFlags& flags, const RunCounters& counters, const std::string& failure,
                    double busy_s, double watchdog_timeout_s);

inline std::chrono::duration<double> seconds(double s) { return std::chrono::duration<double>(s); }

}  // namespace threshing_sim
