#include "threshing_sim/ros/threshing_sim_node.h"

#include <rosgraph_msgs/Clock.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <utility>

#include "threshing_sim/core/overlap.h"
#include "threshing_sim/core/simulator.h"
#include "threshing_sim/ros/command_bag.h"
#include "threshing_sim/ros/launch_end.h"
#include "threshing_sim/ros/reconfigure_check.h"

namespace threshing_sim {
namespace {

// The snapshot queue holds at most this many; the physics thread waits when it is full.
constexpr size_t kMaxQueuedSnapshots = 64;
// /clock is published at most this often in wall time (plus before each stamped message) [s].
constexpr double kClockPeriod_s = 1.0 / 200.0;
// Static geometry (drum, obstacles) is republished this often, for late subscribers [s].
constexpr double kStaticMarkerPeriod_s = 1.0;
// After the last message of a bounded run the node waits this long before shutting down, so
// that recorders receive everything [s].
constexpr double kLinger_s = 1.0;
// How long a finished node waits for the roslaunch it asked to shut down [s].
constexpr double kLaunchShutdownWait_s = 10.0;
// How long a service waits for the physics thread [s].
constexpr double kServiceTimeout_s = 30.0;
// A measured real-time factor below this fraction of the target is a warning [-].
constexpr double kSlowFraction = 0.9;
// A reset whose start poses overlap a body (the tooth passing the kernel's start) waits for
// the drum to turn on, at most this much simulated time, then is skipped [s].
constexpr double kMaxResetWait_s = 0.1;

PacerOptions pacerOptions(const NodeParams& params, double dt_s) {
  PacerOptions o;
  o.step_s = dt_s;
  o.real_time_factor = params.real_time_factor;
  return o;
}

std::chrono::duration<double> seconds(double s) { return std::chrono::duration<double>(s); }

}  // namespace

ThreshingSimNode::ThreshingSimNode(ros::NodeHandle nh, ros::NodeHandle pnh)
    : params_(loadNodeParams(pnh)),
      model_(std::make_shared<const Model>(loadSceneFromParams(pnh, params_))),
      dt_s_(resolvePhysicsStep(params_, *model_)),
      pacer_(clock_, pacerOptions(params_, dt_s_)),
      marker_builder_(params_.force_arrow_scale_mpN, params_.beam_points),
      diagnostics_(nh, pnh) {
  dt_ns_ = std::llround(dt_s_ * 1e9);
  if (params_.sim_clock && !ros::param::param("/use_sim_time", false))
    ROS_WARN(
        "~clock_mode is 'sim' but /use_sim_time is not set: other nodes will not follow "
        "the /clock this node publishes");

  if (params_.end_time_s > 0)
    end_step_ = static_cast<long>(std::ceil(params_.end_time_s / dt_s_ - 1e-9));
  reset_steps_ = std::lround(params_.reset_period_s / dt_s_);
  if (!params_.command_bag.empty()) loadCommandBag();

  resetData(*model_, &data_);
  setRates(params_.contact_state_rate_hz, params_.state_rate_hz, params_.marker_rate_hz);
  paused_ = params_.start_paused;
  user_paused_ = params_.start_paused;
  status_on_tty_ = isatty(STDOUT_FILENO) != 0;

  advertise(nh, pnh);
  startLiveView(nh, pnh);
  static_tf_.sendTransform(staticTransforms(*model_, stampOf(0)));
  startReconfigure(pnh);
  ROS_INFO(
      "threshing_sim_node: %zu teeth, %zu kernels, %zu obstacles; physics step %g s, "
      "real-time factor %g, %s clock%s",
      model_->teeth.size(), model_->kernels.size(), model_->obstacles.size(), dt_s_,
      params_.real_time_factor, params_.sim_clock ? "sim" : "wall",
      params_.command_bag.empty() ? "" : ", re-simulating the commands of ~command_bag");

  output_thread_ = std::thread(&ThreshingSimNode::outputLoop, this);
  physics_thread_ = std::thread(&ThreshingSimNode::physicsLoop, this);
}

ThreshingSimNode::~ThreshingSimNode() { stop(); }

void ThreshingSimNode::stop() {
  if (stopped_) return;
  stopped_ = true;
  stop_ = true;
  staged_cv_.notify_all();
  served_cv_.notify_all();
  queue_cv_.notify_all();
  if (physics_thread_.joinable()) physics_thread_.join();
  if (output_thread_.joinable()) output_thread_.join();
  // Final summary on stdout.
  if (status_on_tty_ && params_.status_period_s > 0) std::printf("\n");
  const double wall_s = run_wall_s_;
  // After a failure the state is the last good one, inside the failed physics step.
  const double sim_s = failed_ ? failure_t_s_ : step_ * dt_s_;
  std::printf(
      "threshing_sim_node: simulated %.6f s in %.2f s of wall time (real-time factor %.3g "
      "overall), %ld impacts, peak normal force %.1f N, %ld overruns, %ld rejected commands, "
      "%ld numerical recoveries%s\n",
      sim_s, wall_s, wall_s > 0 ? sim_s / wall_s : 0.0, impacts_.load(), peak_force_N_.load(),
      overruns_.load(), rejected_commands_.load(), recoveries_.load(),
      failed_ ? "; the integrator failed" : "");
  std::fflush(stdout);
}

// ---------------------------------------------------------------------------------------------
// Start-up

void ThreshingSimNode::loadCommandBag() {
  const CommandBagContents bag =
      readCommandBag(params_.command_bag, dt_ns_, params_.max_drum_speed_radps);
  for (const BagCommand& c : bag.commands) schedule_.push_back({c.step, c.speed_radps});
  // Without ~end_time, run up to the last contact_state the recording holds.
  if (end_step_ == 0) {
    end_step_ = bag.last_contact_step;
    if (end_step_ == 0)
      throw std::invalid_argument("~command_bag (" + params_.command_bag +
                                  "): holds no contact_state to end the run at; set ~end_time");
  }
  ROS_INFO("re-simulating %zu drum speed commands up to t = %g s", schedule_.size(),
           end_step_ * dt_s_);
}

void ThreshingSimNode::advertise(ros::NodeHandle& nh, ros::NodeHandle& pnh) {
  contact_pub_ = nh.advertise<ContactStateArray>("contact_state", 100);
  impact_pub_ = nh.advertise<ImpactEvent>("impact_events", 1000);
  kernel_pub_ = nh.advertise<KernelStateArray>("kernel_states", 100);
  beam_pub_ = nh.advertise<BeamShapeArray>("beam_shape", 100);
  marker_pub_ = nh.advertise<visualization_msgs::MarkerArray>("markers", 100);
  // Latched: a late subscriber still learns the drum's current target.
  applied_pub_ = nh.advertise<DrumSpeedCommand>("drum_speed_cmd_applied", 1000, true);
  if (params_.sim_clock) clock_pub_ = nh.advertise<rosgraph_msgs::Clock>("/clock", 10);
  // A re-simulation takes its commands from the bag only.
  if (params_.command_bag.empty())
    command_sub_ = nh.subscribe("drum_speed_cmd", 100, &ThreshingSimNode::onDrumSpeedCommand, this,
                                ros::TransportHints().tcpNoDelay());
  pause_srv_ = pnh.advertiseService("pause", &ThreshingSimNode::onPause, this);
  step_srv_ = pnh.advertiseService("step", &ThreshingSimNode::onStep, this);
  reset_srv_ = pnh.advertiseService("reset", &ThreshingSimNode::onReset, this);
  diagnostics_.setHardwareID("threshing_sim");
  diagnostics_.add("simulation", this, &ThreshingSimNode::diagnose);
}

void ThreshingSimNode::startReconfigure(ros::NodeHandle& pnh) {
  // The contact values start from the scene unless set explicitly as private parameters.
  const char* kinds[3] = {"tooth_kernel", "kernel_kernel", "kernel_obstacle"};
  for (int k = 0; k < 3; ++k) {
    const std::string base = kinds[k];
    if (!pnh.hasParam(base + "_restitution"))
      pnh.setParam(base + "_restitution", model_->contact[k].restitution);
    if (!pnh.hasParam(base + "_friction"))
      pnh.setParam(base + "_friction", model_->contact[k].friction);
  }
  reconfigure_ =
      std::make_unique<dynamic_reconfigure::Server<ThreshingSimConfig>>(reconfigure_mutex_, pnh);
  reconfigure_->setCallback(
      [this](ThreshingSimConfig& config, std::uint32_t level) { onReconfigure(config, level); });
}

// ---------------------------------------------------------------------------------------------
// Callbacks: validate, stage, return (the physics thread applies at a step boundary)

void ThreshingSimNode::onDrumSpeedCommand(const std_msgs::Float64& msg) {
  const double speed_radps = msg.data;
  if (!std::isfinite(speed_radps) || std::abs(speed_radps) > params_.max_drum_speed_radps) {
    const long n = ++rejected_commands_;
    // Throttled on the wall clock: simulated time crawls in slow motion.
    if (wallThrottle(&last_reject_warn_s_, 1.0))
      ROS_WARN(
          "drum_speed_cmd rejected: %g rad/s is not finite or exceeds ~max_drum_speed = %g "
          "rad/s (%ld rejected so far)",
          speed_radps, params_.max_drum_speed_radps, n);
    return;
  }
  std::lock_guard<std::mutex> lock(staged_mutex_);
  staged_.drum_target_radps = speed_radps;
  staged_dirty_ = true;
}

bool ThreshingSimNode::onPause(std_srvs::SetBool::Request& req, std_srvs::SetBool::Response& res) {
  {
    std::lock_guard<std::mutex> lock(staged_mutex_);
    paused_ = req.data;
    user_paused_ = req.data;
  }
  staged_cv_.notify_all();
  res.success = true;
  res.message =
      (req.data ? "paused at t = " : "running from t = ") + std::to_string(step_ * dt_s_) + " s";
  return true;
}

bool ThreshingSimNode::onStep(std_srvs::Trigger::Request&, std_srvs::Trigger::Response& res) {
  std::unique_lock<std::mutex> lock(staged_mutex_);
  if (!paused_ || finished_) {
    res.success = false;
    res.message = finished_ ? "the run has ended" : "not paused: call ~pause first";
    return true;
  }
  const long ticket = ++steps_requested_;
  ++staged_.step_periods;
  staged_dirty_ = true;
  staged_cv_.notify_all();
  res.success = served_cv_.wait_for(lock, seconds(kServiceTimeout_s), [&] {
    return steps_done_ >= ticket || stop_;
  }) && !stop_;
  res.message = "t = " + std::to_string(step_ * dt_s_) + " s";
  return true;
}

bool ThreshingSimNode::onReset(std_srvs::Trigger::Request&, std_srvs::Trigger::Response& res) {
  std::unique_lock<std::mutex> lock(staged_mutex_);
  const long ticket = ++resets_requested_;
  staged_.reset = true;
  staged_dirty_ = true;
  staged_cv_.notify_all();
  const bool served = served_cv_.wait_for(lock, seconds(kServiceTimeout_s), [&] {
    return resets_done_ >= ticket || stop_;
  }) && !stop_;
  res.success = served && reset_ok_;
  res.message = served ? reset_result_ : "no answer from the physics thread";
  return true;
}

// Values NaN, inf or outside the cfg ranges are refused and replaced, in the configuration the
// server keeps, by the last good ones (the server stores what this callback leaves in config).
void ThreshingSimNode::onReconfigure(ThreshingSimConfig& config, std::uint32_t) {
  std::lock_guard<std::mutex> lock(staged_mutex_);
  const std::vector<std::string> refused = sanitizeConfig(
      &config, last_good_config_ ? *last_good_config_ : ThreshingSimConfig::__getDefault__());
  if (!refused.empty()) {
    std::string list;
    for (const std::string& r : refused) list += (list.empty() ? "" : ", ") + r;
    const long n = ++refused_reconfigures_;
    ROS_ERROR(
        "reconfigure refused %s (NaN, inf or out of range); the last good values stay "
        "(%ld refused requests so far)",
        list.c_str(), n);
  }
  last_good_config_ = config;
  staged_.config = config;
  staged_dirty_ = true;
}

// ---------------------------------------------------------------------------------------------
// Physics thread

void ThreshingSimNode::physicsLoop() {
  waitForSubscribers();
  waitForViewer();
  loop_anchor_rad_ = data_.theta_rad;
  start_wall_s_ = clock_.nowSeconds();
  pending_reset_ = true;  // markers start with DELETEALL: clears a previous run's
  takeSnapshot(kAllStreams);
  pacer_.restart();
  while (!stop_ && !finished_) {
    if (paused_) {
      servePaused();
      continue;
    }
    // Run the steps due, then sleep until more are (woken early by stop).
    const int n = pacer_.nextBatch();
    const double rtf = pacer_.realTimeFactor();
    for (int i = 0; i < n && !paused_ && !stop_ && !finished_; ++i) {
      advanceOneStep(0);
      adjustPace();  // a new pace starts a new batch
      if (pacer_.realTimeFactor() != rtf) break;
    }
    publishCounters();
    if (n == 0) {
      std::unique_lock<std::mutex> lock(staged_mutex_);
      staged_cv_.wait_for(lock, seconds(pacer_.secondsUntilDue()),
                          [&] { return stop_.load() || paused_.load(); });
    }
  }
  publishCounters();
  run_wall_s_ = clock_.nowSeconds() - start_wall_s_;
}

void ThreshingSimNode::waitForSubscribers() {
  if (!params_.wait_for_subscribers) return;
  const ros::Publisher* outputs[] = {&contact_pub_,    &impact_pub_,        &kernel_pub_,
                                     &beam_pub_,       &marker_pub_,        &applied_pub_,
                                     &drum_state_pub_, &kernel_forces_pub_, &strike_pub_};
  ROS_INFO("~wait_for_subscribers: holding t = 0 until every output topic has a subscriber");
  auto allHeard = [&] {
    return std::all_of(std::begin(outputs), std::end(outputs),
                       [](const ros::Publisher* p) { return p->getNumSubscribers() > 0; });
  };
  while (!stop_ && ros::ok() && !allHeard()) std::this_thread::sleep_for(seconds(0.01));
}

void ThreshingSimNode::servePaused() {
  std::unique_lock<std::mutex> lock(staged_mutex_);
  staged_cv_.wait_for(lock, seconds(0.1), [&] {
    return stop_ || !paused_ || staged_.step_periods > 0 || staged_.reset;
  });
  const long steps = std::exchange(staged_.step_periods, 0) * stepsPerPublishPeriod();
  const long ticket = steps_requested_;
  lock.unlock();
  // ~step: publish periods of steps, then everything is published; ~reset is applied now.
  for (long i = 1; i <= steps && !stop_ && !finished_; ++i)
    advanceOneStep(i == steps ? kAllStreams : 0u);
  if (steps == 0) applyStaged();
  // While paused, markers (static geometry included) go out now and then for a new viewer.
  if (steps == 0 && paused_ && !stop_ && pausedRepublishDue()) takeSnapshot(kMarkerStream);
  publishCounters();
  lock.lock();
  steps_done_ = ticket;
  served_cv_.notify_all();
  lock.unlock();
  if (!paused_) pacer_.restart();  // the paused time is not owed
}

void ThreshingSimNode::advanceOneStep(unsigned forced_streams) {
  applyStaged();
  const long k = step_ + 1;
  advance_started_s_ = clock_.nowSeconds();
  step_meter_.begin();
  const StepStatus status = advanceSampled(k);
  step_meter_.end();
  advance_started_s_ = -1;
  step_ = k;
  if (status == StepStatus::kFailed) {
    const std::string text = describe(data_.stats.failure);
    {
      std::lock_guard<std::mutex> lock(staged_mutex_);
      failure_text_ = text;
      failure_t_s_ = data_.t_s;
    }
    failed_ = true;
    if (end_step_ > 0) {
      // A bounded run (~end_time) ends here, with exit status 1, instead of waiting paused.
      ROS_ERROR("the integrator failed: %s; state kept at the last good step; the run ends",
                text.c_str());
      finished_ = true;
    } else {
      paused_ = true;
      ROS_ERROR(
          "the integrator failed: %s; state kept at the last good step; paused: ~reset "
          "continues from the scene's initial bodies",
          text.c_str());
    }
  }
  // Completed impacts go out with the next snapshot.
  for (const ContactEvent& e : data_.events)
    if (e.is_impact) pending_impacts_.push_back(e);
  data_.events.clear();
  trackPeaks();

  // The last step of a bounded run (or the failed one that ends it) and a periodic reset
  // publish everything.
  const bool last = (end_step_ > 0 && k >= end_step_) || finished_;
  unsigned streams = dueStreams() | forced_streams | (last ? kAllStreams : 0u);
  if (reset_steps_ > 0 && k % reset_steps_ == 0 && !reset_wanted_) requestReset(0);
  if (loopDue() && resetIfClear(false, "demo loop re-seed")) streams = kAllStreams;
  if (streams != 0) takeSnapshot(streams);
  tryPendingReset();
  if (last) finished_ = true;
}

void ThreshingSimNode::applyStaged() {
  // Re-simulation: the recorded commands at their recorded boundaries.
  const long k = step_;
  while (next_scheduled_ < schedule_.size() && schedule_[next_scheduled_].step <= k)
    applyDrumTarget(schedule_[next_scheduled_++].speed_radps);
  if (!staged_dirty_) return;

  Staged staged;
  long reset_ticket = 0;
  {
    std::lock_guard<std::mutex> lock(staged_mutex_);
    staged = std::exchange(staged_, Staged());
    staged_.step_periods = staged.step_periods;  // consumed by servePaused only
    reset_ticket = resets_requested_;
    staged_dirty_ = false;
  }
  if (staged.drum_target_radps) applyDrumTarget(*staged.drum_target_radps);
  if (staged.config) applyConfig(*staged.config);
  if (staged.reset) {
    requestReset(reset_ticket);
    tryPendingReset();
  }
}

void ThreshingSimNode::requestReset(long ticket) {
  if (reset_wanted_ && reset_ticket_ > 0) finishReset(false, "superseded by a later ~reset");
  reset_wanted_ = true;
  reset_ticket_ = ticket;
  reset_wait_steps_ = 0;
}

// A reset puts the kernels back at their start poses: only when that overlaps no tooth, kernel
// or obstacle (the scene loader's test at the current drum angle). Otherwise it waits for the
// tooth to pass, up to kMaxResetWait_s of simulated time (while paused the drum cannot move:
// refused at once), then is skipped. Deferred and skipped resets are counted (/diagnostics).
void ThreshingSimNode::tryPendingReset() {
  if (!reset_wanted_) return;
  const Overlap overlap = findInitialOverlap(*model_, data_.theta_rad);
  const std::string at = " at t = " + std::to_string(step_ * dt_s_) + " s";
  if (!overlap.found) {
    // A reset after a failure runs again, unless the user paused the run.
    const bool resume = failed_ && paused_ && !user_paused_;
    resetBodies();
    strikes_.clear();
    kernel_impulses_.clear();
    takeSnapshot(kAllStreams);
    if (resume) paused_ = false;
    finishReset(true, "bodies reset" + at + (resume ? "; running again after the failure" : ""));
    return;
  }
  if (reset_wait_steps_++ == 0) ++resets_deferred_;
  const bool give_up = paused_ || reset_wait_steps_ * dt_s_ > kMaxResetWait_s;
  if (!give_up) return;
  ++resets_skipped_;
  const std::string why = "reset skipped" + at + ": the start poses overlap (" + describe(overlap) +
                          ") at drum angle " + std::to_string(data_.theta_rad) + " rad" +
                          (paused_ ? "; unpause to let the tooth pass" : "");
  ROS_WARN("%s (%ld skipped so far)", why.c_str(), resets_skipped_.load());
  finishReset(false, why);
}

void ThreshingSimNode::finishReset(bool done, const std::string& message) {
  const long ticket = reset_ticket_;
  reset_wanted_ = false;
  reset_ticket_ = 0;
  if (ticket == 0) return;  // the periodic reset answers nobody
  std::lock_guard<std::mutex> lock(staged_mutex_);
  reset_ok_ = done;
  reset_result_ = message;
  resets_done_ = ticket;
  served_cv_.notify_all();
}

void ThreshingSimNode::applyDrumTarget(double speed_radps) {
  setDrumTarget(*model_, &data_, speed_radps);
  step_meter_.mark();
  pending_commands_.push_back({stampOf(step_), speed_radps});
}

void ThreshingSimNode::applyConfig(const ThreshingSimConfig& config) {
  setRates(config.contact_state_rate, config.state_rate, config.marker_rate);
  slow_rtf_ = config.real_time_factor;  // adjustPace hands it to the pacer
  free_flight_rtf_ = config.free_flight_factor;
  // Contact values live in the constant model: swap in a recompiled copy when they change.
  const double values[3][2] = {
      {config.tooth_kernel_restitution, config.tooth_kernel_friction},
      {config.kernel_kernel_restitution, config.kernel_kernel_friction},
      {config.kernel_obstacle_restitution, config.kernel_obstacle_friction}};
  bool changed = false;
  for (int k = 0; k < 3; ++k)
    changed |= model_->contact[k].restitution != values[k][0] ||
               model_->contact[k].friction != values[k][1];
  if (!changed) return;
  auto model = std::make_shared<Model>(*model_);
  for (int k = 0; k < 3; ++k) {
    model->contact[k].restitution = values[k][0];
    model->contact[k].friction = values[k][1];
  }
  try {
    compileModel(model.get());
    model_ = std::move(model);
    ROS_INFO("contact parameters reconfigured at t = %g s", step_ * dt_s_);
  } catch (const std::exception& e) {
    ROS_ERROR("reconfigure rejected, contact parameters unchanged: %s", e.what());
    // Hand the contact values in force back to the server, so that it does not keep the
    // refused ones (which would make every later request fail as well).
    ThreshingSimConfig restored = config;
    restored.tooth_kernel_restitution = model_->contact[0].restitution;
    restored.tooth_kernel_friction = model_->contact[0].friction;
    restored.kernel_kernel_restitution = model_->contact[1].restitution;
    restored.kernel_kernel_friction = model_->contact[1].friction;
    restored.kernel_obstacle_restitution = model_->contact[2].restitution;
    restored.kernel_obstacle_friction = model_->contact[2].friction;
    {
      std::lock_guard<std::mutex> lock(staged_mutex_);
      last_good_config_ = restored;
    }
    reconfigure_->updateConfig(restored);
  }
}

void ThreshingSimNode::resetBodies() {
  resetBodiesKeepTime(*model_, &data_);
  peaks_.clear();
  pending_reset_ = true;
  failed_ = false;
}

void ThreshingSimNode::setRates(double contact_hz, double state_hz, double marker_hz) {
  const double hz[3] = {contact_hz, state_hz, marker_hz};
  for (int i = 0; i < 3; ++i) {
    if (hz[i] == rates_hz_[i]) continue;
    rates_hz_[i] = hz[i];
    period_steps_[i] = std::max(1L, std::lround(1.0 / (hz[i] * dt_s_)));
    next_due_s_[i] = 0;
  }
}

unsigned ThreshingSimNode::dueStreams() {
  unsigned due = 0;
  const long k = step_;
  // Factor 0: a schedule in simulated time, identical from run to run.
  if (pacer_.realTimeFactor() == 0) {
    for (int i = 0; i < 3; ++i)
      if (k % period_steps_[i] == 0) due |= 1u << i;
    return due;
  }
  // Otherwise a schedule in wall time, without bursts after a late boundary.
  const double now_s = clock_.nowSeconds();
  for (int i = 0; i < 3; ++i) {
    if (now_s < next_due_s_[i]) continue;
    due |= 1u << i;
    next_due_s_[i] += 1.0 / rates_hz_[i];
    if (next_due_s_[i] <= now_s) next_due_s_[i] = now_s + 1.0 / rates_hz_[i];
  }
  return due;
}

void ThreshingSimNode::trackPeaks() {
  // A pair's episode restarts when it closes after being apart at the previous boundary; it
  // keeps the state, point and force of its largest normal force.
  const long k = step_;
  for (const ContactInfo& c : data_.contacts) {
    if (c.state == ContactState::kSeparated) continue;
    auto it = std::find_if(peaks_.begin(), peaks_.end(),
                           [&](const PeakContact& p) { return p.pair == c.pair; });
    if (it == peaks_.end()) it = peaks_.insert(peaks_.end(), PeakContact{c.pair});
    if (it->last_closed_step != k - 1 || c.normal_force_N > it->normal_force_N) {
      it->state = c.state;
      it->p_W = c.p_W;
      it->f_W = c.normal_force_N * c.n_W + c.tangential_force_N * Vec2(-c.n_W.y(), c.n_W.x());
      it->normal_force_N = c.normal_force_N;
    }
    it->last_closed_step = k;
  }
}

void ThreshingSimNode::takeSnapshot(unsigned streams) {
  // The island scheme leaves lone kernels on their own clocks between snapshots.
  if (syncBodies(*model_, &data_) == StepStatus::kFailed) failed_ = true;
  Snapshot s;
  s.model = model_;
  s.step = step_;
  s.t_s = s.step * dt_s_;
  s.stamp = stampOf(s.step);
  s.theta_rad = data_.theta_rad;
  s.omega_radps = data_.omega_radps;
  s.z = data_.z;
  s.u = data_.u;
  s.kernel_attached = data_.kernel_attached;
  s.contacts = data_.contacts;
  s.kernel_peak_force_N = data_.stats.kernel_peak_normal_force_N;
  s.kernel_impacts = data_.stats.kernel_impacts;
  s.impacts = std::exchange(pending_impacts_, {});
  s.commands = std::exchange(pending_commands_, {});
  s.peaks = peaks_;
  s.streams = streams;
  fillLiveView(&s);
  s.reset = std::exchange(pending_reset_, false);
  // Back-pressure: at factor 0 the simulation waits for the publisher rather than drop.
  std::unique_lock<std::mutex> lock(queue_mutex_);
  queue_cv_.wait(lock, [&] { return queue_.size() < kMaxQueuedSnapshots || stop_; });
  queue_.push_back(std::move(s));
  queue_cv_.notify_all();
}

void ThreshingSimNode::publishCounters() {
  measured_rtf_ = pacer_.measuredRealTimeFactor();
  step_rate_hz_ = pacer_.stepRateHz();
  overruns_ = pacer_.overruns();
  resyncs_ = pacer_.resyncs();
  longest_step_s_ = step_meter_.longestSeconds();
  steps_since_command_ = step_meter_.steps();
  impacts_ = data_.stats.impacts;
  peak_force_N_ = data_.stats.peak_normal_force_N;
  recoveries_ = data_.stats.numerical_recoveries;
  max_deflection_ratio_ = data_.stats.max_tip_deflection_ratio;
  deflection_warning_s_ = data_.stats.deflection_warning_time_s;
}

// ---------------------------------------------------------------------------------------------
// Output thread

void ThreshingSimNode::outputLoop() {
  double next_clock_s = 0, next_static_s = 0, next_status_s = 0, next_diagnostics_s = 0;
  while (ros::ok()) {
    std::deque<Snapshot> batch;
    {
      std::unique_lock<std::mutex> lock(queue_mutex_);
      queue_cv_.wait_for(lock, seconds(kClockPeriod_s), [&] { return !queue_.empty() || stop_; });
      batch.swap(queue_);
    }
    queue_cv_.notify_all();
    if (batch.empty() && stop_) break;

    const double now_s = clock_.nowSeconds();
    if (params_.sim_clock && now_s >= next_clock_s) {
      publishClock(stampOf(step_));
      next_clock_s = now_s + kClockPeriod_s;
    }
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
    if (finished_) {
      std::unique_lock<std::mutex> lock(queue_mutex_);
      if (!queue_.empty()) continue;
      lock.unlock();
      if (params_.status_period_s > 0) printStatus(true);
      diagnostics_.force_update();
      std::this_thread::sleep_for(seconds(kLinger_s));
      // A normal end shuts the launch down as Ctrl-C would (no "REQUIRED process has died"):
      // roslaunch then stops this node too. A failed run exits with status 1 at once.
      if (!failed_ && requestLaunchShutdown()) {
        const double until_s = clock_.nowSeconds() + kLaunchShutdownWait_s;
        while (!ros::isShuttingDown() && clock_.nowSeconds() < until_s)
          std::this_thread::sleep_for(seconds(0.05));
      }
      ros::requestShutdown();
      break;
    }
  }
}

void ThreshingSimNode::publishSnapshot(const Snapshot& s, bool with_static_markers) {
  // In sim clock mode /clock is never behind a stamp the node publishes.
  if (params_.sim_clock) publishClock(s.stamp);
  loadPose(s, &scratch_);
  if (s.streams & kContactStream) contact_pub_.publish(contact_builder_.build(s));
  for (const ContactEvent& e : s.impacts)
    impact_pub_.publish(impactEventMsg(
        e, params_.sim_clock ? ros::Time().fromNSec(std::llround(e.t_s * 1e9)) : s.stamp));
  for (const AppliedCommand& c : s.commands) applied_pub_.publish(drumSpeedCommandMsg(c));
  if (s.streams & kStateStream) {
    kernel_pub_.publish(kernelStatesMsg(s));
    beam_pub_.publish(beamShapeMsg(s, scratch_, params_.beam_points));
    // tf2 listeners drop (and complain about) repeated stamps.
    if (!tf_published_ || s.stamp > last_tf_) {
      tf_.sendTransform(movingTransforms(s, scratch_));
      last_tf_ = s.stamp;
      tf_published_ = true;
    }
  }
  publishLiveView(s);
  if ((s.streams & kMarkerStream) || s.reset)
    marker_pub_.publish(marker_builder_.build(s, scratch_, with_static_markers));
}

void ThreshingSimNode::publishClock(const ros::Time& t) {
  if (clock_published_ && t <= last_clock_) return;
  clock_published_ = true;
  rosgraph_msgs::Clock msg;
  msg.clock = t;
  clock_pub_.publish(msg);
  last_clock_ = t;
}

void ThreshingSimNode::printStatus(bool final_line) {
  char line[256];
  std::snprintf(line, sizeof(line),
                "t = %.6f s | real-time factor %.3g (requested %g, pace %g) | impacts %ld | "
                "peak force %.1f N%s",
                step_ * dt_s_, measured_rtf_.load(), slow_rtf_.load(), target_rtf_.load(),
                impacts_.load(), peak_force_N_.load(),
                finished_ ? " | finished"
                : paused_ ? " | paused"
                          : "");
  // On a terminal the line is rewritten in place; otherwise one line per period.
  if (status_on_tty_ && !final_line)
    std::printf("\r%s\033[K", line);
  else
    std::printf("%s%s\n", status_on_tty_ ? "\r" : "", line);
  std::fflush(stdout);
}

void ThreshingSimNode::diagnose(diagnostic_updater::DiagnosticStatusWrapper& stat) {
  const double rtf = measured_rtf_;
  const double target = target_rtf_;
  const double started_s = advance_started_s_;
  const double busy_s = started_s >= 0 ? clock_.nowSeconds() - started_s : 0.0;
  std::string failure;
  double failure_t_s = 0;
  {
    std::lock_guard<std::mutex> lock(staged_mutex_);
    failure = failure_text_;
    failure_t_s = failure_t_s_;
  }
  if (busy_s > params_.watchdog_timeout_s) {
    ROS_ERROR_THROTTLE(5.0, "watchdog: the physics thread has not returned for %.1f s (t = %g s)",
                       busy_s, step_ * dt_s_);
    stat.summary(diagnostic_msgs::DiagnosticStatus::ERROR,
                 "watchdog: physics step running for " + std::to_string(busy_s) + " s");
  } else if (failed_) {
    stat.summary(diagnostic_msgs::DiagnosticStatus::ERROR,
                 "integrator failed (" + failure + "): call ~reset");
  } else if (recoveries_ > 0)
    stat.summary(diagnostic_msgs::DiagnosticStatus::WARN, "numerical recoveries");
  else if (!paused_ && !finished_ && target > 0 && rtf < kSlowFraction * target)
    stat.summary(diagnostic_msgs::DiagnosticStatus::WARN, "slower than the target real time");
  else if (deflection_warning_s_ >= 0)
    stat.summary(diagnostic_msgs::DiagnosticStatus::WARN,
                 "tooth deflection outside the small-deflection range of the beam model");
  else if (resets_skipped_ > 0)
    stat.summary(diagnostic_msgs::DiagnosticStatus::WARN,
                 "resets skipped: the start poses overlapped a body");
  else
    stat.summary(diagnostic_msgs::DiagnosticStatus::OK, finished_ ? "finished"
                                                        : paused_ ? "paused"
                                                                  : "running");
  // After a failure the state is the last good one, inside the failed physics step.
  stat.add("simulation time [s]", failed_ ? failure_t_s : step_ * dt_s_);
  stat.add("physics step [s]", dt_s_);
  stat.add("step rate [Hz]", step_rate_hz_.load());
  stat.add("measured real-time factor", rtf);
  stat.add("target real-time factor", target);
  stat.add("requested real-time factor", slow_rtf_.load());
  stat.add("overruns", overruns_.load());
  stat.add("re-synchronisations", resyncs_.load());
  stat.add("physics loop period [s]", pacer_.tickSeconds());
  stat.add("longest physics step since the last drum command [CPU s]", longest_step_s_.load());
  stat.add("physics steps since the last drum command", steps_since_command_.load());
  stat.add("rejected commands", rejected_commands_.load());
  stat.add("numerical recoveries", recoveries_.load());
  stat.add("impacts", impacts_.load());
  stat.add("peak normal force [N]", peak_force_N_.load());
  stat.add("paused", static_cast<bool>(paused_));
  stat.add("max tip deflection / length", max_deflection_ratio_.load());
  stat.add("first deflection warning [s]", deflection_warning_s_.load());
  stat.add("failure", failed_ ? failure : std::string("none"));
  stat.add("physics step running [wall s]", busy_s);
  stat.add("resets deferred (overlap)", resets_deferred_.load());
  stat.add("resets skipped (overlap)", resets_skipped_.load());
  stat.add("refused reconfigure requests", refused_reconfigures_.load());
}

ros::Time ThreshingSimNode::stampOf(long step) const {
  return params_.sim_clock ? ros::Time().fromNSec(step * dt_ns_) : ros::Time::now();
}

long ThreshingSimNode::stepsPerPublishPeriod() const {
  // One contact_state period of simulated time (at factor f > 0 a wall period is f times that).
  const double rtf = slow_rtf_;
  const double period_s = (rtf > 0 ? rtf : 1.0) / rates_hz_[0];
  return std::max(1L, std::lround(period_s / dt_s_));
}

}  // namespace threshing_sim
