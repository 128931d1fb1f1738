// The node: its parts wired together, the threads started and stopped (threshing_sim_node.h).
#include "threshing_sim/ros/threshing_sim_node.h"

#include <unistd.h>

#include <cmath>
#include <cstdio>

#include "threshing_sim/ros/live_view.h"

namespace threshing_sim {
namespace {

NodeTiming timingOf(const NodeParams& params, const Model& model) {
  NodeTiming t;
  t.dt_s = resolvePhysicsStep(params, model);
  t.dt_ns = std::llround(t.dt_s * 1e9);
  t.sim_clock = params.sim_clock;
  return t;
}

}  // namespace

ThreshingSimNode::ThreshingSimNode(ros::NodeHandle nh, ros::NodeHandle pnh)
    : params_(loadNodeParams(pnh)),
      model_(std::make_shared<const Model>(loadSceneFromParams(pnh, params_, &feed_))),
      timing_(timingOf(params_, *model_)),
      ros_(nh, pnh, params_, timing_, &flags_, &counters_, &inbox_),
      physics_(params_, timing_, model_, &flags_, &counters_, &inbox_, &queue_),
      output_(params_, timing_, flags_, counters_, &queue_, &ros_.publishers(), &ros_.diagnostics(),
              [this] { return ros_.status(); }) {
  if (params_.sim_clock && !ros::param::param("/use_sim_time", false))
    ROS_WARN(
        "~clock_mode is 'sim' but /use_sim_time is not set: other nodes will not follow "
        "the /clock this node publishes");
  flags_.paused = params_.start_paused;
  flags_.user_paused = params_.start_paused;

  const FeedSpec* feed = feed_.capacity > 0 ? &feed_ : nullptr;
  const DamageThresholds damage = ros_.start(*model_, feed);
  output_.setView(sceneExtent(*model_, feed), damage, feed);
  if (feed != nullptr) physics_.setFeed(feed_, damage.plastic_force_N);
  Publishers& pubs = ros_.publishers();
  physics_.setHooks({pubs.outputs(), &pubs.markers,
                     [this](const ThreshingSimConfig& c) { ros_.restoreConfig(c); }});
  ROS_INFO(
      "threshing_sim_node: %zu teeth, %zu kernels, %zu obstacles; physics step %g s, "
      "real-time factor %g, %s clock%s",
      model_->teeth.size(), model_->kernels.size(), model_->obstacles.size(), timing_.dt_s,
      params_.real_time_factor, params_.sim_clock ? "sim" : "wall",
      params_.command_bag.empty() ? "" : ", re-simulating the commands of ~command_bag");
  if (feed != nullptr)
    ROS_INFO(
        "continuous feed: %g kernels/s on a mat at %g m/s, pool of %d kernel slots; "
        "feed_rate_cmd [1/s], feed_throughput every %g s",
        feed_.rate_per_s, feed_.mat_speed_mps, feed_.capacity, params_.feed_interval_s);

  output_thread_ = std::thread([this] { output_.run(); });
  physics_thread_ = std::thread([this] { physics_.run(); });
}

ThreshingSimNode::~ThreshingSimNode() { stop(); }

void ThreshingSimNode::stop() {
  if (stopped_) return;
  stopped_ = true;
  flags_.stop = true;
  inbox_.staged_cv.notify_all();
  inbox_.served_cv.notify_all();
  queue_.wake();
  if (physics_thread_.joinable()) physics_thread_.join();
  if (output_thread_.joinable()) output_thread_.join();
  // Final summary on stdout.
  if (isatty(STDOUT_FILENO) != 0 && params_.status_period_s > 0) std::printf("\n");
  const double wall_s = physics_.runWallSeconds();
  // After a failure the state is the last good one, inside the failed physics step.
  const double sim_s = flags_.failed ? inbox_.failure_t_s : flags_.step * timing_.dt_s;
  std::printf(
      "threshing_sim_node: simulated %.6f s in %.2f s of wall time (real-time factor %.3g "
      "overall), %ld impacts, peak normal force %.17g N, %ld overruns, %ld rejected commands, "
      "%ld numerical recoveries%s\n",
      sim_s, wall_s, wall_s > 0 ? sim_s / wall_s : 0.0, counters_.impacts.load(),
      counters_.peak_force_N.load(), counters_.overruns.load(), counters_.rejected_commands.load(),
      counters_.recoveries.load(), flags_.failed ? "; the integrator failed" : "");
  std::fflush(stdout);
}

}  // namespace threshing_sim
