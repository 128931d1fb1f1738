// threshing_sim ROS layer: the node, a thin layer over the core (core/simulator.h), made of
// parts split by thread and by job:
//  - RosInterface (ros_interface.h): topics, services, dynamic_reconfigure (the live
//    parameters) and /diagnostics; its callbacks run on the ROS spinner (main) and only stage
//    values (the start-up parameters: node_params.h);
//  - PhysicsLoop (physics_loop.h), the physics thread: pacing, sampling, commands at step
//    boundaries, with its DemoLoop (demo_loop.h: re-seeding) and StrikeLog / CommandSchedule
//    (recording.h: strike histories and what a snapshot records; the commands replayed);
//  - OutputLoop (output_loop.h), the output thread: the overlay and the markers, messages,
//    transforms, /clock and the status line;
//  - node_shared.h: the flags, counters, staged inputs and snapshot queue they share.
//
// Output schedule: at real_time_factor > 0 the publish rates count wall time (for watching);
// at 0 they count simulated time, so that every output is a deterministic function of the
// scene and the applied commands (see docs/ros_interface.md, "Record, replay, re-simulate").
#pragma once

#include <ros/ros.h>

#include <memory>
#include <thread>

#include "threshing_sim/core/model.h"
#include "threshing_sim/ros/node_params.h"
#include "threshing_sim/ros/node_shared.h"
#include "threshing_sim/ros/output_loop.h"
#include "threshing_sim/ros/physics_loop.h"
#include "threshing_sim/ros/ros_interface.h"

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
  int exitStatus() const { return flags_.failed ? 1 : 0; }

 private:
  NodeParams params_;
  FeedSpec feed_;                       // the scene's feed (capacity 0: none)
  std::shared_ptr<const Model> model_;  // as loaded (the physics thread may swap its own copy)
  NodeTiming timing_;
  RunFlags flags_;
  RunCounters counters_;
  Inbox inbox_;
  SnapshotQueue queue_;
  RosInterface ros_;
  PhysicsLoop physics_;
  OutputLoop output_;
  std::thread physics_thread_, output_thread_;
  bool stopped_ = false;
};

}  // namespace threshing_sim
