// The output thread (output_loop.h).
#include "threshing_sim/ros/output_loop.h"

#include <rosgraph_msgs/Clock.h>
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <thread>
#include <utility>

#include "threshing_sim/ros/launch_end.h"

namespace threshing_sim {
namespace {

// /clock is published at most this often in wall time (plus before each stamped message) [s].
constexpr double kClockPeriod_s = 1.0 / 200.0;
// Static geometry (drum, obstacles) is republished this often, for late subscribers [s].
constexpr double kStaticMarkerPeriod_s = 1.0;
// After the last message of a bounded run the node waits this long before shutting down, so
// that recorders receive everything [s].
constexpr double kLinger_s = 1.0;
// How long a finished node waits for the roslaunch it asked to shut down [s].
constexpr double kLaunchShutdownWait_s = 10.0;

}  // namespace

OutputLoop::OutputLoop(const NodeParams& params, const NodeTiming& timing, const RunFlags& flags,
                       const RunCounters& counters, SnapshotQueue* queue, Publishers* pubs,
                       diagnostic_updater::Updater* diagnostics, std::function<RunStatus()> status)
    : params_(params),
      timing_(timing),
      flags_(flags),
      counters_(counters),
      queue_(*queue),
      pubs_(*pubs),
      diagnostics_(*diagnostics),
      status_(std::move(status)),
      marker_builder_(params.force_arrow_scale_mpN, params.beam_points),
      status_on_tty_(isatty(STDOUT_FILENO) != 0) {}

void OutputLoop::run() {
  double next_clock_s = 0, next_static_s = 0, next_status_s = 0, next_diagnostics_s = 0;
  while (ros::ok()) {
    const std::deque<Snapshot> batch = queue_.takeAll(kClockPeriod_s, flags_.stop);
    if (batch.empty() && flags_.stop) break;

    const double now_s = clock_.nowSeconds();
    if (params_.sim_clock && now_s >= next_clock_s) {
      publishClock(timing_.stampOf(flags_.step));
      next_clock_s = now_s + kClockPeriod_s;
    }
    // The overlay and the status markers show the state /diagnostics reports now.
    if (!batch.empty()) marker_builder_.setStatus(status_());
    for (const Snapshot& s : batch) {
      const bool with_static = (s.streams & kMarkerStream) && now_s >= next_static_s;
      if (with_static) next_static_s = now_s + kStaticMarkerPeriod_s;
      publishSnapshot(s, with_static);
    }
    if (params_.status_period_s > 0 && now_s >= next_status_s) {
      printStatus(false);
      next_status_s = now_s + params_.status_period_s;
    }
    if (now_s >= next_diagnostics_s) {
      diagnostics_.force_update();
      next_diagnostics_s = now_s + params_.diagnostic_period_s;
    }
    // A bounded run: once the last snapshot is out, linger for the recorders, then shut down.
    if (flags_.finished) {
      if (!queue_.empty()) continue;
      finish();
      break;
    }
  }
}

void OutputLoop::finish() {
  if (params_.status_period_s > 0) printStatus(true);
  diagnostics_.force_update();
  std::this_thread::sleep_for(seconds(kLinger_s));
  // A normal end shuts the launch down as Ctrl-C would (no "REQUIRED process has died"):
  // roslaunch then stops this node too. A failed run exits with status 1 at once.
  if (!flags_.failed && requestLaunchShutdown()) {
    const double until_s = clock_.nowSeconds() + kLaunchShutdownWait_s;
    while (!ros::isShuttingDown() && clock_.nowSeconds() < until_s)
      std::this_thread::sleep_for(seconds(0.05));
  }
  ros::requestShutdown();
}

void OutputLoop::publishSnapshot(const Snapshot& s, bool with_static_markers) {
  // In sim clock mode /clock is never behind a stamp the node publishes.
  if (params_.sim_clock) publishClock(s.stamp);
  loadPose(s, &scratch_);
  if (s.streams & kContactStream) pubs_.contact.publish(contact_builder_.build(s));
  for (const ContactEvent& e : s.impacts)
    pubs_.impact.publish(impactEventMsg(
        e, params_.sim_clock ? ros::Time().fromNSec(std::llround(e.t_s * 1e9)) : s.stamp));
  for (const AppliedCommand& c : s.commands) pubs_.applied.publish(drumSpeedCommandMsg(c));
  for (const AppliedFeedCommand& c : s.feed.commands)
    pubs_.feed_applied.publish(feedRateCommandMsg(c));
  for (const FeedIntervalRecord& r : s.feed.intervals)
    pubs_.feed_throughput.publish(feedThroughputMsg(r));
  if (s.streams & kStateStream) {
    pubs_.kernel.publish(kernelStatesMsg(s));
    pubs_.beam.publish(beamShapeMsg(s, scratch_, params_.beam_points));
    // tf2 listeners drop (and complain about) repeated stamps.
    if (!tf_published_ || s.stamp > last_tf_) {
      pubs_.tf.sendTransform(movingTransforms(s, scratch_));
      last_tf_ = s.stamp;
      tf_published_ = true;
    }
  }
  // The live view: static geometry once (latched), drum state, kernel forces, strikes.
  if (!static_published_) {
    pubs_.static_markers.publish(marker_builder_.staticGeometry(s));
    static_published_ = true;
  }
  if (s.streams & kStateStream) pubs_.drum_state.publish(drumStateMsg(s));
  if (s.streams & kContactStream) pubs_.kernel_forces.publish(kernelContactForcesMsg(s));
  marker_builder_.noteStrikes(s.strikes);
  for (const StrikeRecord& r : s.strikes) {
    const ros::Time stamp =
        params_.sim_clock ? ros::Time().fromNSec(std::llround(r.t_s.back() * 1e9)) : s.stamp;
    pubs_.strike.publish(strikeHistoryMsg(r, stamp));
  }
  if ((s.streams & kMarkerStream) || s.reset) {
    // The strike's frames first, in one message with the snapshot's own markers.
    visualization_msgs::MarkerArray out;
    for (const Snapshot& f : s.frames) {
      loadPose(f, &scratch_);
      visualization_msgs::MarkerArray frame = marker_builder_.build(f, scratch_, false);
      out.markers.insert(out.markers.end(), frame.markers.begin(), frame.markers.end());
    }
    if (!s.frames.empty()) loadPose(s, &scratch_);
    visualization_msgs::MarkerArray own = marker_builder_.build(s, scratch_, with_static_markers);
    out.markers.insert(out.markers.end(), own.markers.begin(), own.markers.end());
    pubs_.markers.publish(out);
  }
}

void OutputLoop::publishClock(const ros::Time& t) {
  if (clock_published_ && t <= last_clock_) return;
  clock_published_ = true;
  rosgraph_msgs::Clock msg;
  msg.clock = t;
  pubs_.clock.publish(msg);
  last_clock_ = t;
}

void OutputLoop::printStatus(bool final_line) {
  char line[256];
  std::snprintf(line, sizeof(line),
                "t = %.6f s | real-time factor %.3g (requested %g, pace %g) | impacts %ld | "
                "peak force %.1f N%s",
                flags_.step * timing_.dt_s, counters_.measured_rtf.load(),
                counters_.requested_rtf.load(), counters_.target_rtf.load(),
                counters_.impacts.load(), counters_.peak_force_N.load(),
                flags_.finished ? " | finished"
                : flags_.paused ? " | paused"
                                : "");
  // On a terminal the line is rewritten in place; otherwise one line per period.
  if (status_on_tty_ && !final_line)
    std::printf("\r%s\033[K", line);
  else
    std::printf("%s%s\n", status_on_tty_ ? "\r" : "", line);
  std::fflush(stdout);
}

}  // namespace threshing_sim
