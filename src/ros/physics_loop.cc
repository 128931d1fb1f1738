// The physics thread (physics_loop.h).
#include "threshing_sim/ros/physics_loop.h"

#include <ros/ros.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <thread>
#include <utility>

#include "threshing_sim/core/overlap.h"
#include "threshing_sim/core/simulator.h"

namespace threshing_sim {
namespace {

// A reset whose start poses overlap a body (the tooth passing the kernel's start) waits for
// the drum to turn on, at most this much simulated time, then is skipped [s].
constexpr double kMaxResetWait_s = 0.1;
// Markers are republished this often while paused or waiting for the viewer [wall s].
constexpr double kPausedRepublish_s = 1.0;
// The viewer wait gives up after this long and starts anyway [wall s].
constexpr double kViewerTimeout_s = 120.0;
// Pace: slow down this much simulated time before a tooth can reach a kernel, and stay slow
// this long after [s].
constexpr double kSlowBefore_s = 1e-3;
constexpr double kSlowAfter_s = 1e-3;

PacerOptions pacerOptions(const NodeParams& params, double dt_s) {
  PacerOptions o;
  o.step_s = dt_s;
  o.real_time_factor = params.real_time_factor;
  return o;
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// StreamSchedule, Pace

void StreamSchedule::setRates(double contact_hz, double state_hz, double marker_hz) {
  const double hz[3] = {contact_hz, state_hz, marker_hz};
  for (int i = 0; i < 3; ++i) {
    if (hz[i] == rates_hz_[i]) continue;
    rates_hz_[i] = hz[i];
    period_steps_[i] = std::max(1L, std::lround(1.0 / (hz[i] * dt_s_)));
    next_due_s_[i] = 0;
  }
}

unsigned StreamSchedule::due(long k, bool by_steps, double now_s) {
  unsigned due = 0;
  // Factor 0: a schedule in simulated time, identical from run to run.
  if (by_steps) {
    for (int i = 0; i < 3; ++i)
      if (k % period_steps_[i] == 0) due |= 1u << i;
    return due;
  }
  // Otherwise a schedule in wall time, without bursts after a late boundary.
  for (int i = 0; i < 3; ++i) {
    if (now_s < next_due_s_[i]) continue;
    due |= 1u << i;
    next_due_s_[i] += 1.0 / rates_hz_[i];
    if (next_due_s_[i] <= now_s) next_due_s_[i] = now_s + 1.0 / rates_hz_[i];
  }
  return due;
}

long StreamSchedule::stepsPerPublishPeriod(double rtf) const {
  // One contact_state period of simulated time (at factor f > 0 a wall period is f times that).
  const double period_s = (rtf > 0 ? rtf : 1.0) / rates_hz_[0];
  return std::max(1L, std::lround(period_s / dt_s_));
}

double Pace::next(const Model& model, const Data& data, double requested_rtf,
                  std::atomic<bool>* skipping) {
  double rtf = requested_rtf;
  const bool watch = *skipping || free_flight_rtf_ > 0;
  if (watch && timeToStrike(model, data) < kSlowBefore_s) last_near_s_ = data.t_s;
  const bool near = watch && data.t_s - last_near_s_ < kSlowAfter_s;
  if (*skipping) {
    // Skips past the strike now near (if any) to the next: ends when one comes near after a
    // stretch of free flight, or after kMaxSkip_s without one.
    skip_saw_free_ = skip_saw_free_ || !near;
    if ((near && skip_saw_free_) || data.t_s > skip_from_s_ + kMaxSkip_s)
      *skipping = false;
    else
      rtf = 0;
  } else {
    skip_from_s_ = data.t_s;
    skip_saw_free_ = false;
    if (!near) rtf = freeFlightPace(requested_rtf, free_flight_rtf_);
  }
  return rtf;
}

// ---------------------------------------------------------------------------------------------
// StrikeFrames

void StrikeFrames::start(const Data& data) { copyStepState(data, &prev_); }

void StrikeFrames::sample(const Data& data, const std::function<void(const FrameState&)>& emit) {
  copyStepState(data, &next_);
  const StepState& a = prev_;
  const StepState& b = next_;
  const double h_s = b.t_s - a.t_s;
  if (!a.closed && !b.closed) episode_frames_ = 0;
  if ((a.closed || b.closed) && h_s > 0 && a.z.size() == b.z.size()) {
    // Frame times on the kFrame_ns grid in (a.t_s, b.t_s] (b may be past the boundary: the
    // boundary's step end, which the boundary's snapshot draws after the frames).
    const std::int64_t first = static_cast<std::int64_t>(std::floor(a.t_s * 1e9 / kFrame_ns)) + 1;
    for (std::int64_t m = first;; ++m) {
      const std::int64_t t_ns = m * kFrame_ns;
      const double t_s = t_ns * 1e-9;
      if (t_s <= a.t_s || t_ns <= std::llround(a.t_s * 1e9)) continue;
      if (t_s > b.t_s || episode_frames_ >= kMaxEpisodeFrames) break;
      // A step with one end closed (the contact's first or last): its frames near that end
      // only (steps are not cut at boundaries, and the one leaving a contact can be long).
      if (!a.closed && t_s < b.t_s - kTailFrames * kFrame_ns * 1e-9) continue;
      if (!b.closed && t_s > a.t_s + kTailFrames * kFrame_ns * 1e-9) break;
      ++episode_frames_;
      frame_.t_ns = t_ns;
      interpolateStep(a, b, t_s, &frame_);
      emit(frame_);
    }
  }
  std::swap(prev_, next_);
}

// ---------------------------------------------------------------------------------------------
// PhysicsLoop

PhysicsLoop::PhysicsLoop(const NodeParams& params, const NodeTiming& timing,
                         std::shared_ptr<const Model> model, RunFlags* flags, RunCounters* counters,
                         Inbox* inbox, SnapshotQueue* queue)
    : params_(params),
      timing_(timing),
      flags_(*flags),
      counters_(*counters),
      inbox_(*inbox),
      queue_(*queue),
      model_(std::move(model)),
      pacer_(clock_, pacerOptions(params, timing.dt_s)),
      streams_(timing.dt_s),
      pace_(params.free_flight_factor),
      schedule_(params, timing.dt_s, timing.dt_ns),
      log_(*model_, params, timing.dt_s),
      demo_(*model_, params.loop_revolutions, clock_) {
  reset_steps_ = std::lround(params.reset_period_s / timing.dt_s);
  resetData(*model_, &data_);
  streams_.setRates(params.contact_state_rate_hz, params.state_rate_hz, params.marker_rate_hz);
  counters_.requested_rtf = params.real_time_factor;
  counters_.target_rtf = params.real_time_factor;
  counters_.loop_period_s = pacer_.tickSeconds();
}

void PhysicsLoop::setFeed(const FeedSpec& spec, double plastic_force_N) {
  const long interval_steps = std::max(1L, std::lround(params_.feed_interval_s / timing_.dt_s));
  feed_ = std::make_unique<NodeFeed>(spec, plastic_force_N, interval_steps);
  if (!feed_->start(&model_, &data_)) fail(feed_->error());
  if (params_.loop_revolutions > 0)
    ROS_INFO("~loop_revolutions ignored: a fed drum is not re-seeded (the feed brings kernels)");
}

void PhysicsLoop::run() {
  waitForSubscribers();
  waitForViewer();
  demo_.start(data_);
  start_wall_s_ = clock_.nowSeconds();
  pending_reset_ = true;  // markers start with DELETEALL: clears a previous run's
  takeSnapshot(kAllStreams);
  pacer_.restart();
  while (!flags_.stop && !flags_.finished) {
    if (flags_.paused) {
      servePaused();
      continue;
    }
    // Run the steps due, then sleep until more are (woken early by stop).
    const int n = pacer_.nextBatch();
    const double rtf = pacer_.realTimeFactor();
    for (int i = 0; i < n && !flags_.paused && !flags_.stop && !flags_.finished; ++i) {
      advanceOneStep(0);
      adjustPace();  // a new pace starts a new batch
      if (pacer_.realTimeFactor() != rtf) break;
    }
    publishCounters();
    if (n == 0) {
      std::unique_lock<std::mutex> lock(inbox_.mutex);
      inbox_.staged_cv.wait_for(lock, seconds(pacer_.secondsUntilDue()),
                                [&] { return flags_.stop.load() || flags_.paused.load(); });
    }
  }
  publishCounters();
  run_wall_s_ = clock_.nowSeconds() - start_wall_s_;
}

void PhysicsLoop::waitForSubscribers() {
  if (!params_.wait_for_subscribers) return;
  ROS_INFO("~wait_for_subscribers: holding t = 0 until every output topic has a subscriber");
  auto allHeard = [&] {
    return std::all_of(hooks_.outputs.begin(), hooks_.outputs.end(),
                       [](const ros::Publisher* p) { return p->getNumSubscribers() > 0; });
  };
  while (!flags_.stop && ros::ok() && !allHeard()) std::this_thread::sleep_for(seconds(0.01));
}

void PhysicsLoop::waitForViewer() {
  if (!params_.wait_for_viewer || !hooks_.markers) return;
  ROS_INFO("~wait_for_viewer: holding t = 0 until a viewer subscribes to markers");
  const double end_s = clock_.nowSeconds() + kViewerTimeout_s;
  while (!flags_.stop && ros::ok() && hooks_.markers->getNumSubscribers() == 0) {
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

bool PhysicsLoop::pausedRepublishDue() {
  const double now_s = clock_.nowSeconds();
  if (now_s - last_paused_publish_s_ < kPausedRepublish_s) return false;
  last_paused_publish_s_ = now_s;
  return true;
}

void PhysicsLoop::servePaused() {
  std::unique_lock<std::mutex> lock(inbox_.mutex);
  inbox_.staged_cv.wait_for(lock, seconds(0.1), [&] {
    return flags_.stop || !flags_.paused || inbox_.staged.step_periods > 0 || inbox_.staged.reset;
  });
  const long steps = std::exchange(inbox_.staged.step_periods, 0) *
                     streams_.stepsPerPublishPeriod(counters_.requested_rtf);
  const long ticket = inbox_.steps_requested;
  lock.unlock();
  // ~step: publish periods of steps, then everything is published; ~reset is applied now.
  for (long i = 1; i <= steps && !flags_.stop && !flags_.finished; ++i)
    advanceOneStep(i == steps ? kAllStreams : 0u);
  if (steps == 0) applyStaged();
  // While paused, markers (static geometry included) go out now and then for a new viewer.
  if (steps == 0 && flags_.paused && !flags_.stop && pausedRepublishDue())
    takeSnapshot(kMarkerStream);
  publishCounters();
  lock.lock();
  inbox_.steps_done = ticket;
  inbox_.served_cv.notify_all();
  lock.unlock();
  if (!flags_.paused) pacer_.restart();  // the paused time is not owed
}

void PhysicsLoop::advanceOneStep(unsigned forced_streams) {
  applyStaged();
  const long k = flags_.step + 1;
  counters_.advance_started_s = clock_.nowSeconds();
  step_meter_.begin();
  // At factor 0 (a recording) the strike's frames go out between the boundaries (StrikeFrames;
  // a live view at a factor > 0 shows its markers at marker_rate of wall time instead). The
  // boundary after them draws the state it reached, whatever the marker schedule.
  bool framed = false;
  std::function<void(const Data&)> sample;
  if (params_.strike_frames && counters_.requested_rtf == 0 && params_.sim_clock) {
    frames_.start(data_);
    sample = [this, &framed](const Data& d) {
      frames_.sample(d, [this, &framed](const FrameState& f) {
        takeFrame(f);
        framed = true;
      });
    };
  }
  // Past the boundary to a step end (no step is cut but at the run's end, as `simulate` cuts
  // none but at its duration): the boundary's state is the step end's, commands apply there.
  // The end: ~end_time, else a re-simulation's last recorded boundary, else none.
  const long end_step = schedule_.endStep();
  const bool bounded = end_step > 0;
  const double t_stop_s = params_.end_time_s > 0 ? params_.end_time_s
                          : bounded              ? end_step * timing_.dt_s
                                                 : std::numeric_limits<double>::infinity();
  const bool final = bounded && k >= end_step;
  const double t_target_s = final ? t_stop_s : k * timing_.dt_s;
  // Island scheme at a live factor: the states the sampler hands over on the way (after the
  // islands' accepted steps near a strike, and the end), so that every boundary this advance
  // passes is published at its own time (one window can hold a whole strike; StepHistory).
  const bool live_islands = model_->integrator.islands && counters_.requested_rtf > 0;
  if (!live_islands) history_.clear();
  if (live_islands && !sample && data_.t_s < t_target_s) {
    // Lone kernels at the start's time too (a snapshot would bring them there as well: no step
    // changes), so that the history's first state is the whole state at one time.
    if (syncBodies(*model_, &data_) == StepStatus::kFailed) flags_.failed = true;
    history_.begin(data_);
    sample = [this](const Data& d) { history_.add(d); };
  }
  const StepStatus status = log_.advance(*model_, &data_, t_target_s, t_stop_s, sample);
  step_meter_.end();
  counters_.advance_started_s = -1;
  flags_.step = k;
  if (status == StepStatus::kFailed) fail(describe(data_.stats.failure));
  log_.afterStep(&data_, k);
  // The feed at the boundary: kernels that left retired, kernels due placed, the throughput
  // interval closed on the step grid.
  if (feed_ && status != StepStatus::kFailed &&
      !feed_->update(&model_, &data_, k, t_target_s, final, timing_.stampOf(k)))
    fail(feed_->error());

  // The last step of a bounded run (or the failed one that ends it) and a periodic reset
  // publish everything.
  const bool last = (end_step > 0 && k >= end_step) || flags_.finished;
  unsigned streams = streams_.due(k, pacer_.realTimeFactor() == 0, clock_.nowSeconds()) |
                     forced_streams | (last ? kAllStreams : 0u);
  // Markers only for the frames: drawn as a frame too (without the chart) unless a strike ended.
  const bool frame_only = framed && !(streams & kMarkerStream);
  if (framed) streams |= kMarkerStream;
  if (reset_steps_ > 0 && k % reset_steps_ == 0 && !reset_.wanted) requestReset(0);
  if (!feed_ && demo_.due(data_) && demo_.reseedIfClear(*model_, &data_)) {
    history_.clear();
    log_.clearStrikes();
    log_.clearPeaks();
    pending_reset_ = true;
    flags_.failed = false;
    streams = kAllStreams;
  }
  if (streams != 0) takeSnapshot(streams, frame_only && streams == kMarkerStream);
  tryPendingReset();
  if (last) flags_.finished = true;
}

void PhysicsLoop::fail(const std::string& text) {
  {
    std::lock_guard<std::mutex> lock(inbox_.mutex);
    inbox_.failure_text = text;
    inbox_.failure_t_s = data_.t_s;
  }
  flags_.failed = true;
  if (schedule_.endStep() > 0) {
    // A bounded run (~end_time) ends here, with exit status 1, instead of waiting paused.
    ROS_ERROR("the integrator failed: %s; state kept at the last good step; the run ends",
              text.c_str());
    flags_.finished = true;
  } else {
    flags_.paused = true;
    ROS_ERROR(
        "the integrator failed: %s; state kept at the last good step; paused: ~reset "
        "continues from the scene's initial bodies",
        text.c_str());
  }
}

void PhysicsLoop::applyStaged() {
  // Re-simulation: the recorded commands at their recorded boundaries.
  schedule_.applyDue(
      flags_.step, [this](double speed_radps) { applyDrumTarget(speed_radps); },
      [this](double rate_per_s) { applyFeedRate(rate_per_s); });
  if (!inbox_.dirty) return;

  StagedInputs staged;
  long reset_ticket = 0;
  {
    std::lock_guard<std::mutex> lock(inbox_.mutex);
    staged = std::exchange(inbox_.staged, StagedInputs());
    inbox_.staged.step_periods = staged.step_periods;  // consumed by servePaused only
    reset_ticket = inbox_.resets_requested;
    inbox_.dirty = false;
  }
  if (staged.drum_target_radps) applyDrumTarget(*staged.drum_target_radps);
  if (staged.feed_rate_per_s) applyFeedRate(*staged.feed_rate_per_s);
  if (staged.config) applyConfig(*staged.config);
  if (staged.reset) {
    requestReset(reset_ticket);
    tryPendingReset();
  }
}

void PhysicsLoop::requestReset(long ticket) {
  if (reset_.wanted && reset_.ticket > 0) finishReset(false, "superseded by a later ~reset");
  reset_ = {true, ticket, 0};
}

// A reset puts the kernels back at their start poses: only when that overlaps no tooth, kernel
// or obstacle (the scene loader's test at the current drum angle). Otherwise it waits for the
// tooth to pass, up to kMaxResetWait_s of simulated time (while paused the drum cannot move:
// refused at once), then is skipped. Deferred and skipped resets are counted (/diagnostics).
void PhysicsLoop::tryPendingReset() {
  if (!reset_.wanted) return;
  const Overlap overlap = findInitialOverlap(*model_, data_.theta_rad);
  const std::string at = " at t = " + std::to_string(flags_.step * timing_.dt_s) + " s";
  if (!overlap.found) {
    // A reset after a failure runs again, unless the user paused the run.
    const bool resume = flags_.failed && flags_.paused && !flags_.user_paused;
    resetBodies();
    log_.clearStrikes();
    takeSnapshot(kAllStreams);
    if (resume) flags_.paused = false;
    finishReset(true, "bodies reset" + at + (resume ? "; running again after the failure" : ""));
    return;
  }
  if (reset_.wait_steps++ == 0) ++counters_.resets_deferred;
  const bool give_up = flags_.paused || reset_.wait_steps * timing_.dt_s > kMaxResetWait_s;
  if (!give_up) return;
  ++counters_.resets_skipped;
  const std::string why = "reset skipped" + at + ": the start poses overlap (" + describe(overlap) +
                          ") at drum angle " + std::to_string(data_.theta_rad) + " rad" +
                          (flags_.paused ? "; unpause to let the tooth pass" : "");
  ROS_WARN("%s (%ld skipped so far)", why.c_str(), counters_.resets_skipped.load());
  finishReset(false, why);
}

void PhysicsLoop::finishReset(bool done, const std::string& message) {
  const long ticket = reset_.ticket;
  reset_ = ResetRequest();
  if (ticket == 0) return;  // the periodic reset answers nobody
  std::lock_guard<std::mutex> lock(inbox_.mutex);
  inbox_.reset_ok = done;
  inbox_.reset_result = message;
  inbox_.resets_done = ticket;
  inbox_.served_cv.notify_all();
}

void PhysicsLoop::applyDrumTarget(double speed_radps) {
  setDrumTarget(*model_, &data_, speed_radps);
  step_meter_.mark();
  log_.noteCommand({timing_.stampOf(flags_.step), speed_radps});
}

// The callback checked the command against the pool already (checkFeedRate); a re-simulated
// one is checked here by the same test.
void PhysicsLoop::applyFeedRate(double rate_per_s) {
  const std::string why = feed_ ? feed_->setRate(rate_per_s, data_)
                                : "the scene has no feed section (feed_rate_cmd needs one)";
  if (!why.empty()) {
    ++counters_.rejected_commands;
    const long n = ++counters_.rejected_feed_commands;
    ROS_WARN("feed_rate_cmd rejected at t = %g s: %s (%ld rejected so far)", data_.t_s, why.c_str(),
             n);
    return;
  }
  feed_->noteCommand({timing_.stampOf(flags_.step), rate_per_s});
}

void PhysicsLoop::applyConfig(const ThreshingSimConfig& config) {
  streams_.setRates(config.contact_state_rate, config.state_rate, config.marker_rate);
  counters_.requested_rtf = config.real_time_factor;  // adjustPace hands it to the pacer
  pace_.setFreeFlight(config.free_flight_factor);
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
    ROS_INFO("contact parameters reconfigured at t = %g s", flags_.step * timing_.dt_s);
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
      std::lock_guard<std::mutex> lock(inbox_.mutex);
      inbox_.last_good_config = restored;
    }
    if (hooks_.restore_config) hooks_.restore_config(restored);
  }
}

void PhysicsLoop::resetBodies() {
  resetBodiesKeepTime(*model_, &data_);
  history_.clear();
  log_.clearPeaks();
  pending_reset_ = true;
  flags_.failed = false;
  // A fed drum starts its feed again from now, with the rate in force (counts from zero).
  if (feed_ && !feed_->start(&model_, &data_)) fail(feed_->error());
}

void PhysicsLoop::adjustPace() {
  const double rtf = pace_.next(*model_, data_, counters_.requested_rtf, &flags_.skipping);
  if (rtf == pacer_.realTimeFactor()) return;
  pacer_.setRealTimeFactor(rtf);
  pacer_.restart();
  counters_.target_rtf = rtf;
}

// The fields a boundary's snapshot and a strike's frame share: the model, the step, the
// kernels' attachment and per-kernel statistics, the drum's target, the demo's loops and the pace.
Snapshot PhysicsLoop::runFields() const {
  Snapshot s;
  s.model = model_;
  s.step = flags_.step;
  s.kernel_attached = data_.kernel_attached;
  s.kernel_active = data_.kernel_active;
  if (feed_) feed_->fillState(&s);
  s.kernel_peak_force_N = data_.stats.kernel_peak_normal_force_N;
  s.kernel_impacts = data_.stats.kernel_impacts;
  s.omega_target_radps = data_.omega_target_radps;
  s.alpha_radps2 = data_.alpha_radps2;
  s.loops = demo_.loops();
  s.target_rtf = counters_.target_rtf;
  s.requested_rtf = counters_.requested_rtf;
  s.measured_rtf = counters_.measured_rtf;
  return s;
}

void PhysicsLoop::takeSnapshot(unsigned streams, bool frame_only) {
  // The island scheme leaves lone kernels on their own clocks between snapshots.
  if (syncBodies(*model_, &data_) == StepStatus::kFailed) flags_.failed = true;
  // The history's last state is this one: now with the lone kernels brought to it as well.
  if (history_.size() > 0 && history_.lastTime() == data_.t_s) history_.add(data_);
  Snapshot s = runFields();
  // After a failure the state is the last good one, inside the failed physics step (the time
  // /diagnostics reports too).
  s.t_s = flags_.failed ? data_.t_s : s.step * timing_.dt_s;
  s.stamp = timing_.stampOf(s.step);
  // The bodies are those of the step end at or past the boundary (less than one integrator step
  // later: no step is cut at a boundary); the drum, whose motion over the step is known in
  // closed form (the step's acceleration; steps end where a ramp does), at the boundary itself,
  // so that its angle and speed follow the stamps exactly.
  const double late_s = flags_.failed ? 0.0 : std::max(0.0, data_.t_s - s.t_s);
  s.theta_rad =
      data_.theta_rad - data_.omega_radps * late_s + 0.5 * data_.alpha_radps2 * late_s * late_s;
  s.omega_radps = data_.omega_radps - data_.alpha_radps2 * late_s;
  // Island scheme at a live factor, the advance past this boundary's time: the bodies and
  // contacts at the boundary itself, interpolated between the accepted steps around it.
  if (late_s > 0 && history_.stateAt(s.t_s, &boundary_)) {
    s.z = boundary_.z;
    s.u = boundary_.u;
    s.contacts = boundary_.contacts;
    ++counters_.interpolated_boundaries;
  } else {
    s.z = data_.z;
    s.u = data_.u;
    s.contacts = data_.contacts;
  }
  s.streams = streams;
  log_.fill(*model_, data_, &s);
  if (feed_) feed_->fill(&s);
  s.reset = std::exchange(pending_reset_, false);
  s.frames = std::exchange(frames_pending_, {});
  // Markers due only for a strike's frames leave out the chart and the status, as the frames
  // do, unless a strike ended (the chart changes) or the markers start over.
  s.frame = frame_only && s.strikes.empty() && !s.reset;
  // Back-pressure: at factor 0 the simulation waits for the publisher rather than drop.
  queue_.push(std::move(s), flags_.stop);
}

// A strike's frame: the markers of an interpolated state (StrikeFrames), stamped with its own
// time, kept for the boundary's snapshot (which the frames put on the marker stream). Only
// markers: impacts, strikes and commands go with the boundary as without frames.
void PhysicsLoop::takeFrame(const FrameState& f) {
  Snapshot s = runFields();
  s.t_s = f.t_s;
  s.stamp = ros::Time().fromNSec(f.t_ns);
  s.theta_rad = f.theta_rad;
  s.omega_radps = f.omega_radps;
  s.z = f.z;
  s.u = f.u;
  s.contacts = f.contacts;
  s.streams = kMarkerStream;
  s.frame = true;
  // A previous episode's peak arrow is hidden while its pair touches again (its live arrow
  // shows then), as at a boundary; the other peak arrows stay as the last full message drew
  // them (in a stream they were a third of the frames' bytes).
  for (const PeakContact& p : log_.peaks())
    for (const ContactInfo& c : f.contacts)
      if (c.pair == p.pair && c.state != ContactState::kSeparated) {
        s.peaks.push_back(p);
        s.peaks.back().last_closed_step = s.step;
      }
  frames_pending_.push_back(std::move(s));
}

void PhysicsLoop::publishCounters() {
  counters_.measured_rtf = pacer_.measuredRealTimeFactor();
  counters_.step_rate_hz = pacer_.stepRateHz();
  counters_.overruns = pacer_.overruns();
  counters_.resyncs = pacer_.resyncs();
  counters_.longest_step_s = step_meter_.longestSeconds();
  counters_.steps_since_command = step_meter_.steps();
  counters_.impacts = data_.stats.impacts;
  counters_.peak_force_N = data_.stats.peak_normal_force_N;
  counters_.recoveries = data_.stats.numerical_recoveries;
  counters_.max_deflection_ratio = data_.stats.max_tip_deflection_ratio;
  counters_.deflection_warning_s = data_.stats.deflection_warning_time_s;
}

}  // namespace threshing_sim
