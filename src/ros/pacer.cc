#include "threshing_sim/ros/pacer.h"

#include <time.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <stdexcept>
#include <string>

namespace threshing_sim {

double freeFlightPace(double requested_rtf, double free_flight_rtf) {
  if (requested_rtf == 0 || free_flight_rtf <= 0) return requested_rtf;
  return std::max(requested_rtf, free_flight_rtf);
}

double MonotonicClock::nowSeconds() const {
  using Seconds = std::chrono::duration<double>;
  return std::chrono::duration_cast<Seconds>(std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

double ThreadCpuClock::nowSeconds() const {
  timespec now{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &now);
  return static_cast<double>(now.tv_sec) + 1e-9 * static_cast<double>(now.tv_nsec);
}

void StepMeter::end() {
  longest_s_ = std::max(longest_s_, clock_.nowSeconds() - began_s_);
  ++steps_;
}

void StepMeter::mark() {
  longest_s_ = 0;
  steps_ = 0;
}

namespace {

void require(bool ok, const std::string& what) {
  if (!ok) throw std::invalid_argument("Pacer: " + what);
}

}  // namespace

Pacer::Pacer(const SteadyClock& clock, const PacerOptions& options)
    : clock_(clock), options_(options) {
  require(std::isfinite(options.step_s) && options.step_s > 0, "step_s must be > 0");
  require(std::isfinite(options.tick_s) && options.tick_s > 0, "tick_s must be > 0");
  require(std::isfinite(options.catch_up_factor) && options.catch_up_factor >= 1,
          "catch_up_factor must be >= 1");
  require(std::isfinite(options.max_lag_s) && options.max_lag_s > 0, "max_lag_s must be > 0");
  require(std::isfinite(options.overrun_lag_s) && options.overrun_lag_s > 0 &&
              options.overrun_lag_s <= options.max_lag_s,
          "overrun_lag_s must be in (0, max_lag_s]");
  require(options.fast_batch_steps >= 1, "fast_batch_steps must be >= 1");
  require(std::isfinite(options.rate_window_s) && options.rate_window_s > 0,
          "rate_window_s must be > 0");
  setRealTimeFactor(options.real_time_factor);
}

void Pacer::setRealTimeFactor(double real_time_factor) {
  require(std::isfinite(real_time_factor) && real_time_factor >= 0,
          "real_time_factor must be >= 0");
  options_.real_time_factor = real_time_factor;
  // The catch-up bound: catch_up_factor ticks' worth of steps, at least one (fixed batches at
  // factor 0).
  if (real_time_factor == 0) {
    max_batch_steps_ = options_.fast_batch_steps;
  } else {
    const double steps_per_tick = options_.tick_s * real_time_factor / options_.step_s;
    max_batch_steps_ =
        std::max(1, static_cast<int>(std::ceil(options_.catch_up_factor * steps_per_tick - 1e-9)));
  }
  restart();
}

void Pacer::restart() {
  last_s_ = clock_.nowSeconds();
  owed_s_ = 0;
  window_start_s_ = last_s_;
  window_steps_ = 0;
  previous_batch_ = 0;
  lagging_ = false;
}

int Pacer::nextBatch() {
  const double now_s = clock_.nowSeconds();
  const double rtf = options_.real_time_factor;
  int steps = options_.fast_batch_steps;
  if (rtf > 0) {
    // Accumulate the simulated time owed since the previous call.
    owed_s_ += (now_s - last_s_) * rtf;
    const double lag_s = owed_s_ / rtf;  // the backlog in wall time [s]
    // The pace is lost: an overrun, counted once until the backlog is caught up.
    if (lag_s > options_.overrun_lag_s && !lagging_) {
      lagging_ = true;
      ++overruns_;
    }
    // Far behind: drop the backlog, keep one full batch.
    if (lag_s > options_.max_lag_s) {
      owed_s_ = max_batch_steps_ * options_.step_s;
      ++resyncs_;
    }
    // Whole steps due (the epsilon absorbs rounding in owed_s_), at most one batch; the rest is
    // owed to the next call, which is due at once.
    steps = static_cast<int>(std::floor(owed_s_ / options_.step_s + 1e-9));
    if (steps > max_batch_steps_) {
      steps = max_batch_steps_;
      ++capped_batches_;
    } else {
      lagging_ = false;  // caught up: all that is owed fits in this batch
    }
    owed_s_ -= steps * options_.step_s;
  }
  // The previous batch has run by now: count it in the measured rates.
  updateRates(now_s, previous_batch_);
  previous_batch_ = steps;
  last_s_ = now_s;
  return steps;
}

double Pacer::secondsUntilDue() const {
  const double rtf = options_.real_time_factor;
  if (rtf == 0 || owed_s_ + 1e-9 * options_.step_s >= options_.step_s) return 0;
  return std::max(options_.tick_s, (options_.step_s - owed_s_) / rtf);
}

void Pacer::updateRates(double now_s, int steps) {
  window_steps_ += steps;
  const double elapsed_s = now_s - window_start_s_;
  if (elapsed_s <= 0) return;
  // Running values until a first window completes, then one value per complete window.
  const bool window_done = elapsed_s >= options_.rate_window_s;
  if (window_done || !have_window_) {
    step_rate_hz_ = window_steps_ / elapsed_s;
    measured_rtf_ = step_rate_hz_ * options_.step_s;
  }
  if (window_done) {
    have_window_ = true;
    window_start_s_ = now_s;
    window_steps_ = 0;
  }
}

}  // namespace threshing_sim
