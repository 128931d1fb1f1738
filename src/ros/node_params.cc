#include "threshing_sim/ros/node_params.h"

#include <ros/param.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <set>
#include <sstream>
#include <stdexcept>

#include "threshing_sim/scene/scene_loader.h"

namespace threshing_sim {
namespace {

// Private parameters that belong to the node; every other private parameter is a scene key.
// The dynamic_reconfigure names are included: the server writes them back under ~.
const std::set<std::string> kNodeKeys = {"scene",
                                         "clock_mode",
                                         "real_time_factor",
                                         "physics_dt",
                                         "max_drum_speed",
                                         "contact_state_rate",
                                         "state_rate",
                                         "marker_rate",
                                         "status_period",
                                         "end_time",
                                         "reset_period",
                                         "command_bag",
                                         "start_paused",
                                         "wait_for_subscribers",
                                         "force_arrow_scale",
                                         "beam_points",
                                         "tooth_kernel_restitution",
                                         "tooth_kernel_friction",
                                         "kernel_kernel_restitution",
                                         "kernel_kernel_friction",
                                         "kernel_obstacle_restitution",
                                         "kernel_obstacle_friction",
                                         "diagnostic_period",
                                         "watchdog_timeout",
                                         "scene_base_dir",
                                         "command_schedule",
                                         "loop_revolutions",
                                         "strike_sample_dt",
                                         "free_flight_factor",
                                         "wait_for_viewer",
                                         "strike_frames",
                                         "feed_interval",
                                         "view"};

// Event-driven scenes advance by this much simulated time per advanceTo call [s].
constexpr double kEventDrivenStep_s = 1e-5;

template <typename T>
std::string str(const T& value) {
  std::ostringstream os;
  os << value;
  return os.str();
}

[[noreturn]] void fail(const std::string& name, const std::string& what) {
  throw std::invalid_argument("~" + name + ": " + what);
}

// Reads ~name into value if set; a value of the wrong type is an error.
template <typename T>
void read(const ros::NodeHandle& pnh, const std::string& name, T* value) {
  if (pnh.hasParam(name) && !pnh.getParam(name, *value)) fail(name, "has the wrong type");
}

// Reads a finite number within [lo, hi].
void readNumber(const ros::NodeHandle& pnh, const std::string& name, double lo, double hi,
                double* value) {
  read(pnh, name, value);
  if (!std::isfinite(*value) || *value < lo || *value > hi)
    fail(name, "must be in [" + str(lo) + ", " + str(hi) + "] (got " + str(*value) + ")");
}

// A publish rate: finite, in (0, hi].
void readRate(const ros::NodeHandle& pnh, const std::string& name, double hi, double* value) {
  read(pnh, name, value);
  if (!std::isfinite(*value) || *value <= 0 || *value > hi)
    fail(name, "must be in (0, " + str(hi) + "] Hz (got " + str(*value) + ")");
}

std::string join(const std::string& path, const std::string& key) {
  return path.empty() ? key : path + "." + key;
}

// XmlRpc parameter tree -> YAML tree, as the scene loader expects.
YAML::Node toYaml(XmlRpc::XmlRpcValue& v, const std::string& path) {
  switch (v.getType()) {
    case XmlRpc::XmlRpcValue::TypeBoolean:
      return YAML::Node(static_cast<bool>(v));
    case XmlRpc::XmlRpcValue::TypeInt:
      return YAML::Node(static_cast<int>(v));
    case XmlRpc::XmlRpcValue::TypeDouble:
      return YAML::Node(static_cast<double>(v));
    case XmlRpc::XmlRpcValue::TypeString:
      return YAML::Node(static_cast<std::string>(v));
    case XmlRpc::XmlRpcValue::TypeArray: {
      YAML::Node node(YAML::NodeType::Sequence);
      for (int i = 0; i < v.size(); ++i) node.push_back(toYaml(v[i], join(path, str(i))));
      return node;
    }
    case XmlRpc::XmlRpcValue::TypeStruct: {
      YAML::Node node(YAML::NodeType::Map);
      for (auto& entry : v) node[entry.first] = toYaml(entry.second, join(path, entry.first));
      return node;
    }
    default:
      fail(path, "has a type a scene cannot hold");
  }
}

}  // namespace

NodeParams loadNodeParams(const ros::NodeHandle& pnh) {
  NodeParams p;
  read(pnh, "scene", &p.scene);

  std::string clock_mode = "wall";
  read(pnh, "clock_mode", &clock_mode);
  if (clock_mode != "wall" && clock_mode != "sim")
    fail("clock_mode", "must be 'wall' or 'sim' (got '" + clock_mode + "')");
  p.sim_clock = clock_mode == "sim";
  // In wall mode the node stamps with ros::Time::now(), which /use_sim_time would freeze.
  if (!p.sim_clock && ros::param::param("/use_sim_time", false))
    fail("clock_mode", "is 'wall' but /use_sim_time is true and nothing would publish /clock");

  readNumber(pnh, "real_time_factor", 0.0, 1e3, &p.real_time_factor);
  read(pnh, "physics_dt", &p.physics_dt_s);
  if (!std::isfinite(p.physics_dt_s) || p.physics_dt_s < 0 || p.physics_dt_s > 1e-3)
    fail("physics_dt",
         "must be in [0, 1e-3] s, 0 = scene default (got " + str(p.physics_dt_s) + ")");
  read(pnh, "max_drum_speed", &p.max_drum_speed_radps);
  if (!std::isfinite(p.max_drum_speed_radps) || p.max_drum_speed_radps <= 0)
    fail("max_drum_speed", "must be > 0 rad/s (got " + str(p.max_drum_speed_radps) + ")");
  readRate(pnh, "contact_state_rate", 1000.0, &p.contact_state_rate_hz);
  readRate(pnh, "state_rate", 1000.0, &p.state_rate_hz);
  readRate(pnh, "marker_rate", 200.0, &p.marker_rate_hz);
  readNumber(pnh, "status_period", 0.0, 3600.0, &p.status_period_s);
  readNumber(pnh, "diagnostic_period", 0.01, 60.0, &p.diagnostic_period_s);
  readNumber(pnh, "watchdog_timeout", 0.01, 3600.0, &p.watchdog_timeout_s);
  readNumber(pnh, "end_time", 0.0, 1e6, &p.end_time_s);
  readNumber(pnh, "reset_period", 0.0, 1e6, &p.reset_period_s);
  read(pnh, "command_bag", &p.command_bag);
  read(pnh, "start_paused", &p.start_paused);
  read(pnh, "wait_for_subscribers", &p.wait_for_subscribers);
  readNumber(pnh, "force_arrow_scale", 0.0, 1.0, &p.force_arrow_scale_mpN);
  read(pnh, "beam_points", &p.beam_points);
  if (p.beam_points < 2 || p.beam_points > 1000)
    fail("beam_points", "must be in [2, 1000] (got " + str(p.beam_points) + ")");
  read(pnh, "scene_base_dir", &p.scene_base_dir);
  if (!p.scene.empty()) p.scene = resolvePath("scene", p.scene, p.scene_base_dir);
  read(pnh, "command_schedule", &p.command_schedule);
  if (!p.command_schedule.empty())
    p.command_schedule = resolvePath("command_schedule", p.command_schedule, p.scene_base_dir);
  read(pnh, "loop_revolutions", &p.loop_revolutions);
  if (p.loop_revolutions < 0 || p.loop_revolutions > 1000000)
    fail("loop_revolutions", "must be in [0, 1e6] (got " + str(p.loop_revolutions) + ")");
  readNumber(pnh, "strike_sample_dt", 0.0, 1e-3, &p.strike_sample_dt_s);
  if (p.strike_sample_dt_s > 0 && p.strike_sample_dt_s < 1e-8)
    fail("strike_sample_dt", "must be 0 or >= 1e-8 s (got " + str(p.strike_sample_dt_s) + ")");
  readNumber(pnh, "free_flight_factor", 0.0, 1e3, &p.free_flight_factor);
  read(pnh, "wait_for_viewer", &p.wait_for_viewer);
  read(pnh, "strike_frames", &p.strike_frames);
  readNumber(pnh, "feed_interval", 1e-4, 1e4, &p.feed_interval_s);
  return p;
}

Model loadSceneFromParams(const ros::NodeHandle& pnh, const NodeParams& params, FeedSpec* feed) {
  // Every private parameter that is not the node's own is a scene key.
  XmlRpc::XmlRpcValue all;
  ros::param::get(pnh.getNamespace(), all);
  XmlRpc::XmlRpcValue scene_keys;
  if (all.getType() == XmlRpc::XmlRpcValue::TypeStruct)
    for (auto& entry : all)
      if (kNodeKeys.count(entry.first) == 0) scene_keys[entry.first] = entry.second;
  const bool have_keys = scene_keys.getType() == XmlRpc::XmlRpcValue::TypeStruct;

  try {
    if (!params.scene.empty()) {
      if (have_keys)
        fail(scene_keys.begin()->first,
             "unknown parameter (scene keys and ~scene cannot be combined)");
      return loadScene(params.scene, {}, nullptr, feed);
    }
    if (!have_keys) fail("scene", "not set, and no scene keys among the private parameters");
    return modelFromYaml(toYaml(scene_keys, ""), nullptr, feed);
  } catch (const SceneError& e) {
    const std::string source =
        params.scene.empty() ? "~ (scene keys)" : "~scene (" + params.scene + ")";
    throw std::invalid_argument(source + ": " + e.what());
  }
}

std::string resolvePath(const std::string& name, const std::string& path,
                        const std::string& base_dir) {
  namespace fs = std::filesystem;
  if (path.empty() || fs::path(path).is_absolute()) return path;
  std::error_code ec;
  const fs::path base = base_dir.empty() ? fs::current_path(ec) : fs::path(base_dir);
  const fs::path resolved = base / path;
  if (!fs::exists(resolved, ec))
    fail(name, "'" + path + "' not found: a relative path is resolved against " + base.string() +
                   (base_dir.empty() ? " (the node's working directory)"
                                     : " (~scene_base_dir, the launch's working directory)") +
                   "; give an absolute path or $(find threshing_sim)/config/...");
  return resolved.lexically_normal().string();
}

std::string sceneTextFromParams(const ros::NodeHandle& pnh, const NodeParams& params,
                                DamageThresholds* damage) {
  if (!params.scene.empty()) {
    std::ifstream in(params.scene);
    std::stringstream text;
    text << in.rdbuf();
    *damage = damageFromYaml(loadSceneYaml(params.scene));
    return text.str();
  }
  XmlRpc::XmlRpcValue all;
  ros::param::get(pnh.getNamespace(), all);
  XmlRpc::XmlRpcValue scene_keys;
  if (all.getType() == XmlRpc::XmlRpcValue::TypeStruct)
    for (auto& entry : all)
      if (kNodeKeys.count(entry.first) == 0) scene_keys[entry.first] = entry.second;
  const YAML::Node root = toYaml(scene_keys, "");
  *damage = damageFromYaml(root);
  YAML::Emitter out;
  out << root;
  return out.c_str();
}

double resolvePhysicsStep(const NodeParams& params, const Model& model) {
  const bool stepping = model.integrator.type == IntegratorType::kTimeStepping;
  const double h = model.integrator.dt_s;
  const double dt_s = params.physics_dt_s > 0 ? params.physics_dt_s
                      : stepping              ? h
                                              : kEventDrivenStep_s;
  // A time-stepping integrator lands on the boundaries only if its step divides them.
  const double ratio = dt_s / h;
  if (stepping && (ratio < 1 - 1e-9 || std::abs(ratio - std::round(ratio)) > 1e-6 * ratio))
    fail("physics_dt", "must be a whole multiple of the scene's integrator.dt = " + str(h) +
                           " s (got " + str(dt_s) + ")");
  // Stamps are whole multiples of the step: it must be a whole number of nanoseconds.
  if (std::abs(dt_s * 1e9 - std::round(dt_s * 1e9)) > 1e-6)
    fail("physics_dt", "must be a whole number of nanoseconds (got " + str(dt_s) + " s)");
  return dt_s;
}

}  // namespace threshing_sim
