// threshing_sim ROS layer: the output thread - the overlay and the markers, every message and
// transform built from the physics thread's snapshots, /clock (sim clock mode, at most ~200 Hz
// of wall time, and always before a stamped message), /diagnostics updates and the status line.
// The end of a bounded run: once the last snapshot is out it lingers for recorders, then shuts
// the launch down.
#pragma once

#include <diagnostic_updater/diagnostic_updater.h>

#include <functional>

#include "threshing_sim/core/data.h"
#include "threshing_sim/ros/messages.h"
#include "threshing_sim/ros/node_params.h"
#include "threshing_sim/ros/node_shared.h"
#include "threshing_sim/ros/pacer.h"
#include "threshing_sim/ros/ros_interface.h"

namespace threshing_sim {

class OutputLoop {
 public:
  // status: the run's state now (RosInterface::status), shown on the overlay and the status line.
  OutputLoop(const NodeParams& params, const NodeTiming& timing, const RunFlags& flags,
             const RunCounters& counters, SnapshotQueue* queue, Publishers* pubs,
             diagnostic_updater::Updater* diagnostics, std::function<RunStatus()> status);
  // Where the overlay and the chart go and the kernels' damage colours.
  // feed: the scene's feed (its grate and mat drawn), nullptr without one.
  void setView(const SceneExtent& extent, const DamageThresholds& damage, const FeedSpec* feed) {
    marker_builder_.setView(extent, damage);
    marker_builder_.setFeed(feed);
  }

  void run();  // the thread's body: returns on stop, or after a bounded run's end
  void printStatus(bool final_line);

 private:
  void publishSnapshot(const Snapshot& s, bool with_static_markers);
  void publishClock(const ros::Time& t);
  void finish();  // a bounded run's end: linger, then shut the launch down

  const NodeParams& params_;
  const NodeTiming& timing_;
  const RunFlags& flags_;
  const RunCounters& counters_;
  SnapshotQueue& queue_;
  Publishers& pubs_;
  diagnostic_updater::Updater& diagnostics_;
  std::function<RunStatus()> status_;
  MonotonicClock clock_;
  ContactStateBuilder contact_builder_;
  MarkerBuilder marker_builder_;
  Data scratch_;          // pose for the tooth shape functions
  ros::Time last_clock_;  // last /clock published
  bool clock_published_ = false;
  ros::Time last_tf_;              // last moving-transform stamp (tf2 drops repeats)
  bool tf_published_ = false;      // the t = 0 transforms go out too
  bool static_published_ = false;  // static_markers sent
  bool status_on_tty_ = false;     // the status line is rewritten in place
};

}  // namespace threshing_sim
