// threshing_sim ROS layer: paces fixed physics steps against a steady (monotonic) clock.
//
// A fixed-step accumulator: every call to nextBatch() adds the wall time elapsed since the
// previous call, times the real-time factor, to the simulated time owed, and hands out the
// whole steps that fit. A batch holds at most catch_up_factor ticks' worth of steps, so that the
// caller comes back between batches (to apply commands and publish); the rest of the backlog is
// carried over, and secondsUntilDue() is 0 while a step is owed, so a loop that woke late
// catches up by batches back to back. Waking late is therefore not a failure: a capped batch is
// only counted (cappedBatches()). The pace is lost when the backlog passes overrun_lag_s of wall
// time (the steps cost more than real time, or the thread got no CPU for that long): that
// starts an overrun, counted once until the backlog is back within one batch. Past max_lag_s
// the pacer re-synchronises: it drops the backlog instead of fast-forwarding through it.
// At real_time_factor 0 it hands out fixed batches as fast as the caller runs them.
//
// The clock is injected so that tests drive the pacer with a fake one.
#pragma once

namespace threshing_sim {

// Monotonic time source [s]; the origin is arbitrary.
class SteadyClock {
 public:
  virtual ~SteadyClock() = default;
  virtual double nowSeconds() const = 0;
};

// std::chrono::steady_clock.
class MonotonicClock : public SteadyClock {
 public:
  double nowSeconds() const override;
};

// CPU time of the calling thread (CLOCK_THREAD_CPUTIME_ID): what a step itself costs, which a
// preemption by another process on a shared machine does not inflate.
class ThreadCpuClock : public SteadyClock {
 public:
  double nowSeconds() const override;
};

// The longest single physics step since the last mark, on the clock it is given (the node
// gives it the physics thread's CPU clock). The node marks it at every drum command, so a
// speed change that stalls a step (a factorisation inside the step) shows as one long step.
class StepMeter {
 public:
  explicit StepMeter(const SteadyClock& clock) : clock_(clock) {}
  void begin() { began_s_ = clock_.nowSeconds(); }  // before a step
  void end();                                       // after it
  void mark();                                      // starts a new window
  double longestSeconds() const { return longest_s_; }
  long steps() const { return steps_; }

 private:
  const SteadyClock& clock_;
  double began_s_ = 0;    // clock reading at the running step's begin() [s]
  double longest_s_ = 0;  // longest step since the mark [s]
  long steps_ = 0;        // steps ended since the mark [-]
};

// The pace away from strikes: ~free_flight_factor fast-forwards free flight, and never slows
// the run below the factor the user asked for (0 = as fast as possible wins over any factor;
// free_flight_factor 0 = the requested factor throughout) [-].
double freeFlightPace(double requested_rtf, double free_flight_rtf);

struct PacerOptions {
  double step_s = 1e-5;           // simulated time per physics step [s]
  double real_time_factor = 1.0;  // simulated seconds per wall second; 0 = as fast as possible [-]
  double tick_s = 1e-3;           // shortest wall time the caller sleeps between batches [s]
  double catch_up_factor = 2.0;   // a batch holds at most this many ticks' worth of steps [-]
  double overrun_lag_s = 0.02;    // wall backlog beyond which the pace is lost (an overrun) [s]
  double max_lag_s = 0.1;         // wall backlog beyond which the pacer re-synchronises [s]
  int fast_batch_steps = 1000;    // batch size at real_time_factor 0 [-]
  double rate_window_s = 1.0;     // averaging window of the measured rates [s]
};

class Pacer {
 public:
  // Validates the options (throws std::invalid_argument) and starts pacing now.
  Pacer(const SteadyClock& clock, const PacerOptions& options);

  // Forgets the backlog and starts pacing from now (after a pause or a factor change).
  void restart();
  void setRealTimeFactor(double real_time_factor);
  double realTimeFactor() const { return options_.real_time_factor; }
  double tickSeconds() const { return options_.tick_s; }  // the physics loop's period [s]

  // Number of steps the caller must run now (0 when none is due). The measured rates assume
  // the previous batch has been run by the time of the next call.
  int nextBatch();
  // Wall time the caller may sleep before calling nextBatch() again [s].
  double secondsUntilDue() const;

  // Simulated seconds per wall second over the last complete window (running value before) [-].
  double measuredRealTimeFactor() const { return measured_rtf_; }
  // Steps per wall second over the same window [Hz].
  double stepRateHz() const { return step_rate_hz_; }
  // Times the backlog passed overrun_lag_s of wall time (each counted once, until the pacer
  // has caught up to within one batch): the pace was lost [-].
  long overruns() const { return overruns_; }
  long resyncs() const { return resyncs_; }  // backlogs dropped (past max_lag_s) [-]
  // Batches cut to maxBatchSteps() with steps still owed: catching up, not an overrun [-].
  long cappedBatches() const { return capped_batches_; }
  int maxBatchSteps() const { return max_batch_steps_; }

 private:
  void updateRates(double now_s, int steps);

  const SteadyClock& clock_;
  PacerOptions options_;
  int max_batch_steps_ = 1;    // catch-up bound per batch [-]
  double last_s_ = 0;          // wall time of the previous nextBatch() [s]
  double owed_s_ = 0;          // simulated time owed to the caller [s]
  int previous_batch_ = 0;     // steps handed out by the previous call [-]
  double window_start_s_ = 0;  // wall time the current rate window began [s]
  long window_steps_ = 0;      // steps run in the current rate window [-]
  bool have_window_ = false;   // a rate window has completed
  double measured_rtf_ = 0;
  double step_rate_hz_ = 0;
  bool lagging_ = false;       // in an overrun (backlog passed overrun_lag_s, not caught up)
  long overruns_ = 0;
  long resyncs_ = 0;
  long capped_batches_ = 0;
};

}  // namespace threshing_sim
