// threshing_sim ROS layer: the node's private parameters and the scene it simulates.
//
// Every parameter is private (~name), validated once at start-up; a bad value throws
// std::invalid_argument whose message names the parameter, e.g.
// "~real_time_factor: must be >= 0 (got -1)". The table with units, defaults and ranges is in
// docs/ros_interface.md.
#pragma once

#include <ros/node_handle.h>

#include <string>

#include "threshing_sim/core/feed.h"
#include "threshing_sim/core/model.h"
#include "threshing_sim/scene/outcomes.h"

namespace threshing_sim {

// Units in brackets; the ~name each field comes from is in docs/ros_interface.md.
struct NodeParams {
  std::string scene;                     // ~scene: scene file; empty = scene keys as private params
  bool sim_clock = false;                // ~clock_mode "sim": publish /clock, stamp with sim time
  double real_time_factor = 1.0;         // sim s per wall s; 0 = as fast as possible [-]
  double physics_dt_s = 0;               // sim time per advanceTo call; 0 = scene default [s]
  double max_drum_speed_radps = 400.0;   // larger |drum_speed_cmd| are rejected [rad/s]
  double contact_state_rate_hz = 100.0;  // contact_state [Hz]
  double state_rate_hz = 50.0;           // kernel_states, beam_shape, tf [Hz]
  double marker_rate_hz = 30.0;          // markers [Hz]
  double status_period_s = 1.0;          // status line period, 0 = off [wall s]
  double diagnostic_period_s = 1.0;      // /diagnostics period [wall s]
  double watchdog_timeout_s = 5.0;       // a physics step running longer is an ERROR [wall s]
  double end_time_s = 0;                 // stop at this simulation time, 0 = never [s]
  double reset_period_s = 0;             // reset the bodies every ..., 0 = never [s]
  std::string command_bag;               // re-simulate the commands applied in this bag
  bool start_paused = false;             // start paused
  bool wait_for_subscribers = false;     // hold t = 0 until every output is heard
  double force_arrow_scale_mpN = 5e-4;   // force arrow length per newton [m/N]
  int beam_points = 20;                  // centreline samples per tooth [-]
  // --- live view ---
  std::string scene_base_dir;        // relative ~scene/~command_schedule resolve here
  std::string command_schedule;      // timed drum speed commands (YAML), "" = none
  int loop_revolutions = 0;          // re-seed kernels every n drum revolutions, 0 = never
  double strike_sample_dt_s = 2e-7;  // strike history sampling, 0 = per physics step [s]
  double free_flight_factor = 0;     // factor away from contacts, 0 = real_time_factor [-]
  bool wait_for_viewer = false;      // hold t = 0 (publishing markers) until rviz listens
  bool strike_frames = true;         // factor 0, sim clock: markers every 1 us through strikes
  double feed_interval_s = 0.01;     // feed_throughput interval, on the step grid [s]
};

// A relative path resolved against ~scene_base_dir (the launch's working directory), else
// the node's working directory; throws std::invalid_argument naming ~name, the path and what
// it was resolved against when the file does not exist.
std::string resolvePath(const std::string& name, const std::string& path,
                        const std::string& base_dir);

// Reads and validates the node's parameters from the private handle pnh. physics_dt_s is left
// 0 when not set (the scene decides, see resolvePhysicsStep).
NodeParams loadNodeParams(const ros::NodeHandle& pnh);

// The scene: the file named by ~scene, or else the scene keys among the private parameters
// (every private parameter that is not a node parameter). Validated and compiled by the scene
// loader; throws std::invalid_argument naming the offending key.
// A `feed` section is returned in *feed (capacity 0: none).
Model loadSceneFromParams(const ros::NodeHandle& pnh, const NodeParams& params, FeedSpec* feed);

// The scene as given (the file's text, or the scene keys as YAML) and its damage thresholds.
std::string sceneTextFromParams(const ros::NodeHandle& pnh, const NodeParams& params,
                                DamageThresholds* damage);

// The physics step: ~physics_dt if set, else the scene's time step (time stepping) or 1e-5 s
// (event-driven). Checks that it is a whole number of nanoseconds and that a time-stepping
// scene's step divides it. Throws std::invalid_argument naming ~physics_dt.
double resolvePhysicsStep(const NodeParams& params, const Model& model);

}  // namespace threshing_sim
