// threshing_sim_node: runs a threshing scene live (see threshing_sim/ros/threshing_sim_node.h).
#include <ros/ros.h>

#include <stdexcept>

#include "threshing_sim/ros/threshing_sim_node.h"

int main(int argc, char** argv) {
  ros::init(argc, argv, "threshing_sim_node");
  // The handles outlive the node: the last one to go shuts ROS (and its logging) down.
  ros::NodeHandle nh, pnh("~");
  int status = 0;
  try {
    threshing_sim::ThreshingSimNode node(nh, pnh);
    ros::spin();
    node.stop();
    status = node.exitStatus();  // 1 after an integrator failure
  } catch (const std::invalid_argument& e) {
    ROS_FATAL("threshing_sim_node refuses to start: %s", e.what());
    status = 1;
  }
  return status;
}
