// ThreshingSimNode, the live view: strike histories, per-kernel forces, drum state, the demo
// loop with its overlap check, pace changes (free flight, skip to the next contact), the
// viewer wait, timed commands and the scene record. Kept apart from threshing_sim_node.cc.
#include <std_msgs/Float64MultiArray.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>

#include "threshing_sim/core/constants.h"
#include "threshing_sim/core/simulator.h"
#include "threshing_sim/core/state_overlap.h"
#include "threshing_sim/ros/threshing_sim_node.h"

namespace threshing_sim {
namespace {

// Markers are republished this often while paused or waiting for the viewer [wall s].
constexpr double kPausedRepublish_s = 1.0;
// The viewer wait gives up after this long and starts anyway [wall s].
constexpr double kViewerTimeout_s = 120.0;
// Overlap warnings are printed at most this often [wall s].
constexpr double kWarnPeriod_s = 2.0;
// A strike is "near" when a tooth-kernel pair closes within this many physics steps [-].
constexpr double kStrikeHorizonSteps = 3.0;
// Pace: slow down this much simulated time before a tooth can reach a kernel, and stay slow
// this long after [s].
constexpr double kSlowBefore_s = 1e-3;
constexpr double kSlowAfter_s = 1e-3;
// ~skip_to_contact gives up after this much simulated time without a strike [s].
constexpr double kMaxSkip_s = 2.0;

}  // namespace

void ThreshingSimNode::startLiveView(ros::NodeHandle& nh, ros::NodeHandle& pnh) {
  const bool stepping = model_->integrator.type == IntegratorType::kTimeStepping;
  // Event-driven (global scheme): every accepted step near a strike is a sample; time stepping:
  // the integrator step is the finest evaluation point there is; the island scheme: the
  // physics step. The integrator's steps are never cut for a sample.
  step_sampler_ = std::make_unique<StepSampler>(*model_, params_.strike_sample_dt_s > 0,
                                                kStrikeHorizonSteps * dt_s_);
  strikes_ = StrikeRecorder(stepping ? model_->integrator.dt_s : dt_s_);
  slow_rtf_ = params_.real_time_factor;
  free_flight_rtf_ = params_.free_flight_factor;
  target_rtf_ = slow_rtf_.load();
  resetData(*model_, &overlap_scratch_);
  scene_text_ = sceneTextFromParams(pnh, params_, &damage_);
  marker_builder_.setView(sceneExtent(*model_), damage_);
  // The camera's box, for scripts/scene_rviz (latched: a recording carries it too).
  const SceneExtent view = viewBox(sceneExtent(*model_));
  if (!params_.command_schedule.empty()) loadCommandSchedule();

  drum_state_pub_ = nh.advertise<DrumState>("drum_state", 100);
  kernel_forces_pub_ = nh.advertise<KernelContactForces>("kernel_contact_forces", 100);
  strike_pub_ = nh.advertise<StrikeHistory>("strike_history", 100);
  scene_pub_ = nh.advertise<std_msgs::String>("scene_yaml", 1, true);
  static_marker_pub_ = nh.advertise<visualization_msgs::MarkerArray>("static_markers", 1, true);
  view_box_pub_ = nh.advertise<std_msgs::Float64MultiArray>("view_box", 1, true);
  std_msgs::Float64MultiArray box;
  box.data = {view.min_m.x(), view.min_m.y(), view.max_m.x(), view.max_m.y()};
  view_box_pub_.publish(box);
  // The scene and the node settings that shape the physics outputs: compare_bags refuses to
  // call two runs identical when either differs.
  std_msgs::String scene;
  char settings[200];
  std::snprintf(settings, sizeof(settings),
                "\n# threshing_sim_node: physics_dt %.9g s, loop_revolutions %d, reset_period "
                "%.9g s, strike_sample_dt %.9g s\n",
                dt_s_, params_.loop_revolutions, params_.reset_period_s,
                params_.strike_sample_dt_s);
  scene.data = scene_text_ + settings;
  scene_pub_.publish(scene);
  skip_srv_ = pnh.advertiseService("skip_to_contact", &ThreshingSimNode::onSkipToContact, this);
}

void ThreshingSimNode::loadCommandSchedule() {
  const std::string where = "~command_schedule (" + params_.command_schedule + "): ";
  if (!params_.command_bag.empty())
    throw std::invalid_argument(where + "cannot be combined with ~command_bag");
  try {
    const YAML::Node root = YAML::LoadFile(params_.command_schedule);
    if (!root["commands"] || !root["commands"].IsSequence())
      throw std::invalid_argument(where + "needs a list 'commands' of {time: s, speed: rad/s}");
    for (const YAML::Node& c : root["commands"]) {
      const double t_s = c["time"].as<double>(), speed_radps = c["speed"].as<double>();
      if (!std::isfinite(t_s) || t_s < 0 || !std::isfinite(speed_radps) ||
          std::abs(speed_radps) > params_.max_drum_speed_radps)
        throw std::invalid_argument(where + "bad command (time " + std::to_string(t_s) +
                                    " s, speed " + std::to_string(speed_radps) + " rad/s)");
      // Applied at the first step boundary at or after its time.
      schedule_.push_back({static_cast<long>(std::ceil(t_s / dt_s_ - 1e-9)), speed_radps});
    }
  } catch (const YAML::Exception& e) {
    throw std::invalid_argument(where + e.what());
  }
  std::stable_sort(
      schedule_.begin(), schedule_.end(),
      [](const ScheduledCommand& a, const ScheduledCommand& b) { return a.step < b.step; });
  ROS_INFO("~command_schedule: %zu drum speed commands", schedule_.size());
}

bool ThreshingSimNode::onSkipToContact(std_srvs::Trigger::Request&,
                                       std_srvs::Trigger::Response& res) {
  skipping_ = true;
  res.success = true;
  res.message = "running as fast as possible until the next tooth-kernel contact (at most " +
                std::to_string(kMaxSkip_s) + " s of simulated time)";
  staged_cv_.notify_all();
  return true;
}

void ThreshingSimNode::waitForViewer() {
  if (!params_.wait_for_viewer) return;
  ROS_INFO("~wait_for_viewer: holding t = 0 until a viewer subscribes to markers");
  const double end_s = clock_.nowSeconds() + kViewerTimeout_s;
  while (!stop_ && ros::ok() && marker_pub_.getNumSubscribers() == 0) {
    if (clock_.nowSeconds() > end_s) {
      ROS_WARN("~wait_for_viewer: nobody subscribed to markers within %g s; starting anyway",
               kViewerTimeout_s);
      return;
    }
    if (pausedRepublishDue()) takeSnapshot(kMarkerStream);
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  // A newly connected rviz: the initial state once more, static geometry included.
  std::this_thread::sleep_for(std::chrono::milliseconds(500));
}

bool ThreshingSimNode::pausedRepublishDue() {
  const double now_s = clock_.nowSeconds();
  if (now_s - last_paused_publish_s_ < kPausedRepublish_s) return false;
  last_paused_publish_s_ = now_s;
  return true;
}

StepStatus ThreshingSimNode::advanceSampled(long k) {
  const StepStatus status =
      step_sampler_->advance(*model_, &data_, k * dt_s_, [this](const Data& d) {
        strikes_.sample(d);
        kernel_impulses_.update(*model_, d);
      });
  for (StrikeRecord& r : strikes_.finished()) pending_strikes_.push_back(std::move(r));
  strikes_.finished().clear();
  return status;
}

bool ThreshingSimNode::loopDue() {
  if (params_.loop_revolutions <= 0) return false;
  const double period_rad = 2 * kPi * params_.loop_revolutions;
  const long index =
      static_cast<long>(std::floor((data_.theta_rad - loop_anchor_rad_) / period_rad));
  if (index == loop_index_) return false;
  loop_index_ = index;
  return true;
}

bool ThreshingSimNode::resetIfClear(bool full, const char* why) {
  // The candidate: the current drum angle and teeth (full: undeflected teeth), kernels back at
  // their initial poses.
  Data& c = overlap_scratch_;
  c.theta_rad = data_.theta_rad;
  c.z = data_.z;
  if (full)
    for (const ToothModel& tooth : model_->teeth)
      c.z.segment(tooth.dof_offset, tooth.n_modes).setZero();
  for (const KernelModel& kernel : model_->kernels) {
    c.z.segment<2>(kernel.dof_offset) = kernel.initial_position_m;
    c.z[kernel.dof_offset + 2] = kernel.initial_angle_rad;
  }
  std::string what;
  if (bodiesOverlap(*model_, c, &what)) {
    {
      std::lock_guard<std::mutex> lock(staged_mutex_);
      last_overlap_ = what;
    }
    if (wallThrottle(&last_overlap_warn_s_, kWarnPeriod_s))
      ROS_WARN("%s at t = %.6f s skipped: the reset would place bodies overlapping (%s)", why,
               data_.t_s, what.c_str());
    return false;
  }
  if (full)
    resetBodies();
  else
    reseedKernels();
  strikes_.clear();
  kernel_impulses_.clear();
  return true;
}

void ThreshingSimNode::reseedKernels() {
  // resetBodiesKeepTime restores every body and the drum's target: keep the teeth and the
  // commanded speed as they are, so that only the kernels start over.
  const double target_radps = data_.omega_target_radps;
  const VecX z = data_.z, u = data_.u;
  resetBodiesKeepTime(*model_, &data_);
  for (const ToothModel& tooth : model_->teeth) {
    data_.z.segment(tooth.dof_offset, tooth.n_modes) = z.segment(tooth.dof_offset, tooth.n_modes);
    data_.u.segment(tooth.dof_offset, tooth.n_modes) = u.segment(tooth.dof_offset, tooth.n_modes);
  }
  data_.omega_target_radps = target_radps;
  data_.stats.energy_initial_J = mechanicalEnergy(*model_, data_);
  ++loops_;
  peaks_.clear();
  pending_reset_ = true;
  failed_ = false;
}

void ThreshingSimNode::adjustPace() {
  double rtf = slow_rtf_;
  const bool watch = skipping_ || free_flight_rtf_ > 0;
  if (watch && timeToStrike(*model_, data_) < kSlowBefore_s) last_near_s_ = data_.t_s;
  const bool near = watch && data_.t_s - last_near_s_ < kSlowAfter_s;
  if (skipping_) {
    // Skips past the strike now near (if any) to the next: ends when one comes near after a
    // stretch of free flight, or after kMaxSkip_s without one.
    skip_saw_free_ = skip_saw_free_ || !near;
    if ((near && skip_saw_free_) || data_.t_s > skip_from_s_ + kMaxSkip_s)
      skipping_ = false;
    else
      rtf = 0;
  } else {
    skip_from_s_ = data_.t_s;
    skip_saw_free_ = false;
    if (!near) rtf = freeFlightPace(slow_rtf_, free_flight_rtf_);
  }
  if (rtf == pacer_.realTimeFactor()) return;
  pacer_.setRealTimeFactor(rtf);
  pacer_.restart();
  target_rtf_ = rtf;
}

bool ThreshingSimNode::wallThrottle(double* last_s, double period_s) const {
  const double now_s = clock_.nowSeconds();
  if (now_s - *last_s < period_s) return false;
  *last_s = now_s;
  return true;
}

void ThreshingSimNode::fillLiveView(Snapshot* s) {
  s->omega_target_radps = data_.omega_target_radps;
  s->alpha_radps2 = data_.alpha_radps2;
  s->loops = loops_;
  s->target_rtf = target_rtf_;
  s->requested_rtf = slow_rtf_;
  s->measured_rtf = measured_rtf_;
  s->kernel_forces = kernel_impulses_.forces(*model_, data_);
  if (s->streams & kStateStream) s->strike_focus_W = strikeFocus(*model_, data_);
  s->strikes = std::exchange(pending_strikes_, {});
}

void ThreshingSimNode::publishLiveView(const Snapshot& s) {
  if (!static_published_) {
    static_marker_pub_.publish(marker_builder_.staticGeometry(s));
    static_published_ = true;
  }
  if (s.streams & kStateStream) drum_state_pub_.publish(drumStateMsg(s));
  if (s.streams & kContactStream) kernel_forces_pub_.publish(kernelContactForcesMsg(s));
  marker_builder_.noteStrikes(s.strikes);
  for (const StrikeRecord& r : s.strikes) {
    const ros::Time stamp =
        params_.sim_clock ? ros::Time().fromNSec(std::llround(r.t_s.back() * 1e9)) : s.stamp;
    strike_pub_.publish(strikeHistoryMsg(r, stamp));
  }
}

}  // namespace threshing_sim
