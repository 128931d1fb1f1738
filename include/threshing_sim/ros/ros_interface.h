// threshing_sim ROS layer: the node's ROS interface - topics, services, dynamic_reconfigure
// and /diagnostics (see docs/ros_interface.md).
//
// The callbacks run on the ROS spinner (main): they validate, stage the value in the Inbox
// under its mutex, and return (~step and ~reset wait, with a timeout, for the physics thread to
// serve them). Nothing here steps the model.
#pragma once

#include <diagnostic_updater/diagnostic_updater.h>
#include <dynamic_reconfigure/server.h>
#include <ros/ros.h>
#include <std_msgs/Float64.h>
#include <std_srvs/SetBool.h>
#include <std_srvs/Trigger.h>
#include <tf2_ros/static_transform_broadcaster.h>
#include <tf2_ros/transform_broadcaster.h>

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "threshing_sim/ThreshingSimConfig.h"
#include "threshing_sim/core/feed.h"
#include "threshing_sim/core/model.h"
#include "threshing_sim/ros/node_params.h"
#include "threshing_sim/ros/node_shared.h"
#include "threshing_sim/ros/pacer.h"
#include "threshing_sim/scene/outcomes.h"

namespace threshing_sim {

// Every topic the node publishes (the output thread publishes; the physics thread only counts
// subscribers).
struct Publishers {
  ros::Publisher contact, impact, kernel, beam, markers, applied, clock;
  ros::Publisher drum_state, kernel_forces, strike, scene, static_markers, view_box;
  ros::Publisher feed_throughput, feed_applied;  // a scene with a feed only
  tf2_ros::TransformBroadcaster tf;
  tf2_ros::StaticTransformBroadcaster static_tf;
  // The outputs ~wait_for_subscribers waits for.
  std::vector<const ros::Publisher*> outputs() const {
    std::vector<const ros::Publisher*> out = {&contact,    &impact,        &kernel,
                                              &beam,       &markers,       &applied,
                                              &drum_state, &kernel_forces, &strike};
    if (feed_throughput) out.push_back(&feed_throughput);
    return out;
  }
};

class RosInterface {
 public:
  RosInterface(ros::NodeHandle nh, ros::NodeHandle pnh, const NodeParams& params,
               const NodeTiming& timing, RunFlags* flags, RunCounters* counters, Inbox* inbox);

  // Advertises every topic and service, publishes the latched scene, view box and static
  // transforms of `model`, and starts dynamic_reconfigure (whose first callback stages the
  // initial configuration).
  // feed: the scene's feed, nullptr without one (feed_rate_cmd is then refused and counted).
  // Returns the scene's damage thresholds (the kernels' colours).
  DamageThresholds start(const Model& model, const FeedSpec* feed);

  Publishers& publishers() { return pubs_; }
  diagnostic_updater::Updater& diagnostics() { return diagnostics_; }
  // The physics thread refused a reconfiguration: the server takes back the values in force.
  void restoreConfig(const ThreshingSimConfig& config) { reconfigure_->updateConfig(config); }
  // The run's state now, as /diagnostics reports it (the overlay shows the same).
  RunStatus status() const;

 private:
  void advertise(const Model& model, DamageThresholds* damage);
  void startReconfigure(const Model& model);
  void onDrumSpeedCommand(const std_msgs::Float64& msg);
  void onFeedRateCommand(const std_msgs::Float64& msg);
  bool onPause(std_srvs::SetBool::Request& req, std_srvs::SetBool::Response& res);
  bool onStep(std_srvs::Trigger::Request& req, std_srvs::Trigger::Response& res);
  bool onReset(std_srvs::Trigger::Request& req, std_srvs::Trigger::Response& res);
  bool onSkipToContact(std_srvs::Trigger::Request& req, std_srvs::Trigger::Response& res);
  void onReconfigure(ThreshingSimConfig& config, std::uint32_t level);
  void diagnose(diagnostic_updater::DiagnosticStatusWrapper& stat);
  double busySeconds() const;  // how long the running physics step has run [wall s]

  ros::NodeHandle nh_, pnh_;
  const NodeParams& params_;
  const NodeTiming& timing_;
  RunFlags& flags_;
  RunCounters& counters_;
  Inbox& inbox_;
  MonotonicClock clock_;
  Publishers pubs_;
  ros::Subscriber command_sub_, feed_sub_;
  const FeedSpec* feed_ = nullptr;  // the scene's feed (constant), nullptr without one
  ros::ServiceServer pause_srv_, step_srv_, reset_srv_, skip_srv_;
  diagnostic_updater::Updater diagnostics_;
  boost::recursive_mutex reconfigure_mutex_;
  std::unique_ptr<dynamic_reconfigure::Server<ThreshingSimConfig>> reconfigure_;
  double last_reject_warn_s_ = -1e9;  // steady time of the last rejected-command warning [s]
  double last_feed_warn_s_ = -1e9;    // the same for feed_rate_cmd [s]
};

}  // namespace threshing_sim
