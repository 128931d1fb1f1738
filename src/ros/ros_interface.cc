// The node's ROS interface (ros_interface.h).
#include "threshing_sim/ros/ros_interface.h"

#include <rosgraph_msgs/Clock.h>
#include <std_msgs/Float64MultiArray.h>
#include <std_msgs/String.h>

#include <cmath>
#include <cstdio>

#include "threshing_sim/ros/live_view.h"
#include "threshing_sim/ros/messages.h"
#include "threshing_sim/ros/reconfigure_check.h"

namespace threshing_sim {
namespace {

// How long a service waits for the physics thread [s].
constexpr double kServiceTimeout_s = 30.0;

}  // namespace

RosInterface::RosInterface(ros::NodeHandle nh, ros::NodeHandle pnh, const NodeParams& params,
                           const NodeTiming& timing, RunFlags* flags, RunCounters* counters,
                           Inbox* inbox)
    : nh_(nh),
      pnh_(pnh),
      params_(params),
      timing_(timing),
      flags_(*flags),
      counters_(*counters),
      inbox_(*inbox),
      diagnostics_(nh, pnh) {}

DamageThresholds RosInterface::start(const Model& model, const FeedSpec* feed) {
  feed_ = feed;
  DamageThresholds damage;
  advertise(model, &damage);
  pubs_.static_tf.sendTransform(staticTransforms(model, timing_.stampOf(0)));
  startReconfigure(model);
  return damage;
}

void RosInterface::advertise(const Model& model, DamageThresholds* damage) {
  ros::NodeHandle& nh = nh_;
  pubs_.contact = nh.advertise<ContactStateArray>("contact_state", 100);
  pubs_.impact = nh.advertise<ImpactEvent>("impact_events", 1000);
  pubs_.kernel = nh.advertise<KernelStateArray>("kernel_states", 100);
  pubs_.beam = nh.advertise<BeamShapeArray>("beam_shape", 100);
  pubs_.markers = nh.advertise<visualization_msgs::MarkerArray>("markers", 100);
  // Latched: a late subscriber still learns the drum's current target.
  pubs_.applied = nh.advertise<DrumSpeedCommand>("drum_speed_cmd_applied", 1000, true);
  if (params_.sim_clock) pubs_.clock = nh.advertise<rosgraph_msgs::Clock>("/clock", 10);
  // A re-simulation takes its commands from the bag only.
  if (params_.command_bag.empty()) {
    command_sub_ = nh.subscribe("drum_speed_cmd", 100, &RosInterface::onDrumSpeedCommand, this,
                                ros::TransportHints().tcpNoDelay());
    // Subscribed without a feed too: a command to a scene without one is refused and counted.
    feed_sub_ = nh.subscribe("feed_rate_cmd", 100, &RosInterface::onFeedRateCommand, this,
                             ros::TransportHints().tcpNoDelay());
  }
  if (feed_ != nullptr) {
    // The throughput per ~feed_interval; the commands as applied (latched, as the drum's).
    pubs_.feed_throughput = nh.advertise<FeedThroughput>("feed_throughput", 100);
    pubs_.feed_applied = nh.advertise<FeedRateCommand>("feed_rate_cmd_applied", 1000, true);
  }
  pause_srv_ = pnh_.advertiseService("pause", &RosInterface::onPause, this);
  step_srv_ = pnh_.advertiseService("step", &RosInterface::onStep, this);
  reset_srv_ = pnh_.advertiseService("reset", &RosInterface::onReset, this);
  diagnostics_.setHardwareID("threshing_sim");
  diagnostics_.add("simulation", this, &RosInterface::diagnose);

  // The live view: drum state, per-kernel forces, strike histories, the scene record.
  pubs_.drum_state = nh.advertise<DrumState>("drum_state", 100);
  pubs_.kernel_forces = nh.advertise<KernelContactForces>("kernel_contact_forces", 100);
  pubs_.strike = nh.advertise<StrikeHistory>("strike_history", 100);
  pubs_.scene = nh.advertise<std_msgs::String>("scene_yaml", 1, true);
  pubs_.static_markers = nh.advertise<visualization_msgs::MarkerArray>("static_markers", 1, true);
  pubs_.view_box = nh.advertise<std_msgs::Float64MultiArray>("view_box", 1, true);
  // The camera's box, for scripts/scene_rviz (latched: a recording carries it too).
  const SceneExtent view = viewBox(sceneExtent(model));
  std_msgs::Float64MultiArray box;
  box.data = {view.min_m.x(), view.min_m.y(), view.max_m.x(), view.max_m.y()};
  pubs_.view_box.publish(box);
  // The scene and the node settings that shape the physics outputs: compare_bags refuses to
  // call two runs identical when either differs.
  std_msgs::String scene;
  char settings[200];
  std::snprintf(settings, sizeof(settings),
                "\n# threshing_sim_node: physics_dt %.9g s, loop_revolutions %d, reset_period "
                "%.9g s, strike_sample_dt %.9g s\n",
                timing_.dt_s, params_.loop_revolutions, params_.reset_period_s,
                params_.strike_sample_dt_s);
  scene.data = sceneTextFromParams(pnh_, params_, damage) + settings;
  pubs_.scene.publish(scene);
  skip_srv_ = pnh_.advertiseService("skip_to_contact", &RosInterface::onSkipToContact, this);
}

void RosInterface::startReconfigure(const Model& model) {
  // The contact values start from the scene unless set explicitly as private parameters.
  const char* kinds[3] = {"tooth_kernel", "kernel_kernel", "kernel_obstacle"};
  for (int k = 0; k < 3; ++k) {
    const std::string base = kinds[k];
    if (!pnh_.hasParam(base + "_restitution"))
      pnh_.setParam(base + "_restitution", model.contact[k].restitution);
    if (!pnh_.hasParam(base + "_friction"))
      pnh_.setParam(base + "_friction", model.contact[k].friction);
  }
  reconfigure_ =
      std::make_unique<dynamic_reconfigure::Server<ThreshingSimConfig>>(reconfigure_mutex_, pnh_);
  reconfigure_->setCallback(
      [this](ThreshingSimConfig& config, std::uint32_t level) { onReconfigure(config, level); });
}

// ---------------------------------------------------------------------------------------------
// Callbacks: validate, stage, return (the physics thread applies at a step boundary)

void RosInterface::onDrumSpeedCommand(const std_msgs::Float64& msg) {
  const double speed_radps = msg.data;
  if (!std::isfinite(speed_radps) || std::abs(speed_radps) > params_.max_drum_speed_radps) {
    const long n = ++counters_.rejected_commands;
    // Throttled on the wall clock: simulated time crawls in slow motion.
    const double now_s = clock_.nowSeconds();
    if (now_s - last_reject_warn_s_ >= 1.0) {
      last_reject_warn_s_ = now_s;
      ROS_WARN(
          "drum_speed_cmd rejected: %g rad/s is not finite or exceeds ~max_drum_speed = %g "
          "rad/s (%ld rejected so far)",
          speed_radps, params_.max_drum_speed_radps, n);
    }
    return;
  }
  std::lock_guard<std::mutex> lock(inbox_.mutex);
  inbox_.staged.drum_target_radps = speed_radps;
  inbox_.dirty = true;
}

// As drum_speed_cmd: validated here (the core's test: finite, in [0, 1e6] 1/s, no more kernels
// on the mat than the pool holds), refused with a warning naming the value and counted, else
// staged for the next step boundary. A scene without a feed refuses every command.
void RosInterface::onFeedRateCommand(const std_msgs::Float64& msg) {
  const double rate_per_s = msg.data;
  char no_feed[128];
  std::snprintf(no_feed, sizeof(no_feed),
                "feed rate %.17g 1/s refused: the scene has no feed section", rate_per_s);
  const std::string why =
      feed_ != nullptr ? checkFeedRate(rate_per_s, *feed_, feed_->capacity) : no_feed;
  if (!why.empty()) {
    ++counters_.rejected_commands;
    const long n = ++counters_.rejected_feed_commands;
    // Throttled on the wall clock: simulated time crawls in slow motion.
    const double now_s = clock_.nowSeconds();
    if (now_s - last_feed_warn_s_ >= 1.0) {
      last_feed_warn_s_ = now_s;
      ROS_WARN("feed_rate_cmd rejected: %s (%ld feed rate commands rejected so far)", why.c_str(),
               n);
    }
    return;
  }
  std::lock_guard<std::mutex> lock(inbox_.mutex);
  inbox_.staged.feed_rate_per_s = rate_per_s;
  inbox_.dirty = true;
}

bool RosInterface::onPause(std_srvs::SetBool::Request& req, std_srvs::SetBool::Response& res) {
  {
    std::lock_guard<std::mutex> lock(inbox_.mutex);
    flags_.paused = req.data;
    flags_.user_paused = req.data;
  }
  inbox_.staged_cv.notify_all();
  res.success = true;
  res.message = (req.data ? "paused at t = " : "running from t = ") +
                std::to_string(flags_.step * timing_.dt_s) + " s";
  return true;
}

bool RosInterface::onStep(std_srvs::Trigger::Request&, std_srvs::Trigger::Response& res) {
  std::unique_lock<std::mutex> lock(inbox_.mutex);
  if (!flags_.paused || flags_.finished) {
    res.success = false;
    res.message = flags_.finished ? "the run has ended" : "not paused: call ~pause first";
    return true;
  }
  const long ticket = ++inbox_.steps_requested;
  ++inbox_.staged.step_periods;
  inbox_.dirty = true;
  inbox_.staged_cv.notify_all();
  res.success = inbox_.served_cv.wait_for(lock, seconds(kServiceTimeout_s), [&] {
    return inbox_.steps_done >= ticket || flags_.stop;
  }) && !flags_.stop;
  res.message = "t = " + std::to_string(flags_.step * timing_.dt_s) + " s";
  return true;
}

bool RosInterface::onReset(std_srvs::Trigger::Request&, std_srvs::Trigger::Response& res) {
  std::unique_lock<std::mutex> lock(inbox_.mutex);
  const long ticket = ++inbox_.resets_requested;
  inbox_.staged.reset = true;
  inbox_.dirty = true;
  inbox_.staged_cv.notify_all();
  const bool served = inbox_.served_cv.wait_for(lock, seconds(kServiceTimeout_s), [&] {
    return inbox_.resets_done >= ticket || flags_.stop;
  }) && !flags_.stop;
  res.success = served && inbox_.reset_ok;
  res.message = served ? inbox_.reset_result : "no answer from the physics thread";
  return true;
}

bool RosInterface::onSkipToContact(std_srvs::Trigger::Request&, std_srvs::Trigger::Response& res) {
  flags_.skipping = true;
  res.success = true;
  res.message = "running as fast as possible until the next tooth-kernel contact (at most " +
                std::to_string(kMaxSkip_s) + " s of simulated time)";
  inbox_.staged_cv.notify_all();
  return true;
}

// Values NaN, inf or outside the cfg ranges are refused and replaced, in the configuration the
// server keeps, by the last good ones (the server stores what this callback leaves in config).
void RosInterface::onReconfigure(ThreshingSimConfig& config, std::uint32_t) {
  std::lock_guard<std::mutex> lock(inbox_.mutex);
  const std::vector<std::string> refused =
      sanitizeConfig(&config, inbox_.last_good_config ? *inbox_.last_good_config
                                                      : ThreshingSimConfig::__getDefault__());
  if (!refused.empty()) {
    std::string list;
    for (const std::string& r : refused) list += (list.empty() ? "" : ", ") + r;
    const long n = ++counters_.refused_reconfigures;
    ROS_ERROR(
        "reconfigure refused %s (NaN, inf or out of range); the last good values stay "
        "(%ld refused requests so far)",
        list.c_str(), n);
  }
  inbox_.last_good_config = config;
  inbox_.staged.config = config;
  inbox_.dirty = true;
}

// ---------------------------------------------------------------------------------------------
// /diagnostics

double RosInterface::busySeconds() const {
  const double started_s = counters_.advance_started_s;
  return started_s >= 0 ? clock_.nowSeconds() - started_s : 0.0;
}

RunStatus RosInterface::status() const {
  std::string failure;
  {
    std::lock_guard<std::mutex> lock(inbox_.mutex);
    failure = inbox_.failure_text;
  }
  return runStatus(flags_, counters_, failure, busySeconds(), params_.watchdog_timeout_s);
}

void RosInterface::diagnose(diagnostic_updater::DiagnosticStatusWrapper& stat) {
  const double busy_s = busySeconds();
  std::string failure;
  double failure_t_s = 0;
  {
    std::lock_guard<std::mutex> lock(inbox_.mutex);
    failure = inbox_.failure_text;
    failure_t_s = inbox_.failure_t_s;
  }
  const double t_s = flags_.step * timing_.dt_s;
  if (busy_s > params_.watchdog_timeout_s)
    ROS_ERROR_THROTTLE(5.0, "watchdog: the physics thread has not returned for %.1f s (t = %g s)",
                       busy_s, t_s);
  const RunStatus status =
      runStatus(flags_, counters_, failure, busy_s, params_.watchdog_timeout_s);
  stat.summary(status.level, status.message);
  const bool failed = flags_.failed;
  // After a failure the state is the last good one, inside the failed physics step.
  stat.add("simulation time [s]", failed ? failure_t_s : t_s);
  stat.add("physics step [s]", timing_.dt_s);
  stat.add("step rate [Hz]", counters_.step_rate_hz.load());
  stat.add("measured real-time factor", counters_.measured_rtf.load());
  stat.add("target real-time factor", counters_.target_rtf.load());
  stat.add("requested real-time factor", counters_.requested_rtf.load());
  stat.add("overruns", counters_.overruns.load());
  stat.add("re-synchronisations", counters_.resyncs.load());
  stat.add("physics loop period [s]", counters_.loop_period_s.load());
  stat.add("longest physics step since the last drum command [CPU s]",
           counters_.longest_step_s.load());
  stat.add("physics steps since the last drum command", counters_.steps_since_command.load());
  stat.add("rejected commands", counters_.rejected_commands.load());
  stat.add("rejected feed rate commands", counters_.rejected_feed_commands.load());
  stat.add("numerical recoveries", counters_.recoveries.load());
  stat.add("impacts", counters_.impacts.load());
  // All 17 digits: the value is `simulate`'s to the last bit (scenes.test compares them).
  stat.addf("peak normal force [N]", "%.17g", counters_.peak_force_N.load());
  stat.add("paused", static_cast<bool>(flags_.paused));
  stat.add("max tip deflection / length", counters_.max_deflection_ratio.load());
  stat.add("first deflection warning [s]", counters_.deflection_warning_s.load());
  stat.add("failure", failed ? failure : std::string("none"));
  stat.add("physics step running [wall s]", busy_s);
  stat.add("resets deferred (overlap)", counters_.resets_deferred.load());
  stat.add("resets skipped (overlap)", counters_.resets_skipped.load());
  stat.add("refused reconfigure requests", counters_.refused_reconfigures.load());
  stat.add("boundaries interpolated between island steps",
           counters_.interpolated_boundaries.load());
}

}  // namespace threshing_sim
