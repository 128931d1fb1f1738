// Unit tests of the Pacer with a fake clock (no ROS master, no sleeping).
#include <gtest/gtest.h>

#include <chrono>
#include <stdexcept>
#include <thread>

#include "threshing_sim/ros/pacer.h"

namespace threshing_sim {
namespace {

class FakeClock : public SteadyClock {
 public:
  double nowSeconds() const override { return now_s; }
  double now_s = 100.0;  // arbitrary origin [s]
};

PacerOptions options(double real_time_factor) {
  PacerOptions o;
  o.step_s = 1e-5;
  o.real_time_factor = real_time_factor;
  o.tick_s = 1e-3;
  o.catch_up_factor = 2.0;
  o.overrun_lag_s = 0.02;
  o.max_lag_s = 0.1;
  o.fast_batch_steps = 500;
  o.rate_window_s = 1.0;
  return o;
}

// Runs the pacer for wall_s seconds with the clock advancing tick_s per call; returns the steps.
long run(FakeClock* clock, Pacer* pacer, double wall_s, double tick_s) {
  long steps = 0;
  const int calls = static_cast<int>(wall_s / tick_s + 0.5);
  for (int i = 0; i < calls; ++i) {
    clock->now_s += tick_s;
    steps += pacer->nextBatch();
  }
  return steps;
}

// At factor 1 the steps handed out over 1 s of wall time cover 1 s of simulated time
// (to within the one step left in the accumulator).
TEST(Pacer, RealTimeKeepsPace) {
  FakeClock clock;
  Pacer pacer(clock, options(1.0));
  const long steps = run(&clock, &pacer, 1.0, 1e-3);
  EXPECT_NEAR(steps, 100000, 1);
  EXPECT_EQ(pacer.overruns(), 0);
  EXPECT_EQ(pacer.resyncs(), 0);
}

// Slow motion: 1 s of wall time at factor 0.001 is 1 ms of simulated time, 100 steps.
TEST(Pacer, SlowMotion) {
  FakeClock clock;
  Pacer pacer(clock, options(0.001));
  EXPECT_EQ(pacer.maxBatchSteps(), 1);
  EXPECT_NEAR(run(&clock, &pacer, 1.0, 1e-3), 100, 1);
  // Between steps the caller may sleep until the next one is due (at most one step: 10 ms).
  EXPECT_GT(pacer.secondsUntilDue(), 1e-3 - 1e-12);
  EXPECT_LE(pacer.secondsUntilDue(), 1e-2 + 1e-12);
}

// Factor 0: fixed batches, no sleeping, whatever the clock does.
TEST(Pacer, AsFastAsPossible) {
  FakeClock clock;
  Pacer pacer(clock, options(0.0));
  EXPECT_EQ(pacer.nextBatch(), 500);
  EXPECT_EQ(pacer.nextBatch(), 500);
  EXPECT_EQ(pacer.secondsUntilDue(), 0.0);
}

// A late call is caught up in bounded batches (two ticks' worth = 200 steps) back to back; a
// capped batch is counted but is no overrun (5 ms behind is within overrun_lag_s); nothing is
// lost below the re-sync threshold.
TEST(Pacer, BoundedCatchUp) {
  FakeClock clock;
  Pacer pacer(clock, options(1.0));
  EXPECT_EQ(pacer.maxBatchSteps(), 200);
  clock.now_s += 5e-3;  // 500 steps due
  EXPECT_EQ(pacer.nextBatch(), 200);
  EXPECT_EQ(pacer.secondsUntilDue(), 0.0);
  EXPECT_EQ(pacer.nextBatch(), 200);
  EXPECT_EQ(pacer.nextBatch(), 100);
  EXPECT_EQ(pacer.nextBatch(), 0);
  EXPECT_EQ(pacer.cappedBatches(), 2);
  EXPECT_EQ(pacer.overruns(), 0);
  EXPECT_EQ(pacer.resyncs(), 0);
  // With nothing owed the caller sleeps at least one tick.
  EXPECT_GE(pacer.secondsUntilDue(), 1e-3);
}

// A sleeping loop that wakes up to 15 ms late now and then (a busy machine's scheduler), with
// steps ten times faster than real time, catches up by back-to-back batches: it keeps real
// time, with capped batches and without an overrun.
TEST(Pacer, LateWakeUpsAreCaughtUpWithoutOverruns) {
  FakeClock clock;
  Pacer pacer(clock, options(1.0));
  long steps = 0;
  const double start_s = clock.now_s;
  for (int i = 0; i < 3000; ++i) {
    const int n = pacer.nextBatch();
    steps += n;
    clock.now_s += n * 1e-6;  // each step costs 1 us of wall time
    // The sleep asked for, plus a late wake-up of 15 ms every 100th sleep and 1.5 ms else.
    const double sleep_s = pacer.secondsUntilDue();
    if (sleep_s > 0) clock.now_s += sleep_s + (i % 100 == 0 ? 15e-3 : 1.5e-3);
  }
  const double simulated_s = steps * 1e-5, wall_s = clock.now_s - start_s;
  EXPECT_GT(pacer.cappedBatches(), 30);
  EXPECT_EQ(pacer.overruns(), 0);
  EXPECT_EQ(pacer.resyncs(), 0);
  EXPECT_GT(simulated_s / wall_s, 0.99);
  EXPECT_LE(simulated_s, wall_s + 1e-12);
}

// A stall longer than overrun_lag_s loses the pace: one overrun for the episode (however many
// batches the catch-up takes), and another for the next stall once caught up.
TEST(Pacer, AStallPastTheLagBoundIsOneOverrun) {
  FakeClock clock;
  Pacer pacer(clock, options(1.0));
  for (int stall = 0; stall < 2; ++stall) {
    clock.now_s += 0.05;  // 50 ms without CPU: 5000 steps owed
    int batches = 0;
    while (pacer.nextBatch() > 0 && batches < 100) ++batches;
    EXPECT_EQ(batches, 25);  // 5000 steps in batches of 200
    EXPECT_EQ(pacer.overruns(), stall + 1);
  }
  EXPECT_EQ(pacer.resyncs(), 0);
}

// Far behind (1 s > max_lag 0.1 s): the backlog is dropped, one full batch runs, then none.
TEST(Pacer, ResynchronisesWhenFarBehind) {
  FakeClock clock;
  Pacer pacer(clock, options(1.0));
  clock.now_s += 1.0;
  EXPECT_EQ(pacer.nextBatch(), 200);
  EXPECT_EQ(pacer.resyncs(), 1);
  EXPECT_EQ(pacer.nextBatch(), 0);
}

// A caller whose steps cost twice their simulated time runs at half real time: the measured
// factor says so, the lost pace shows as overruns, and the pacer keeps re-synchronising
// instead of spiralling.
TEST(Pacer, MeasuresTheAchievedFactor) {
  FakeClock clock;
  Pacer pacer(clock, options(1.0));
  long steps = 0;
  for (int i = 0; i < 2000; ++i) {
    const int n = pacer.nextBatch();
    steps += n;
    clock.now_s += n > 0 ? n * 2e-5 : 1e-3;  // each step costs 20 us of wall time
  }
  EXPECT_NEAR(pacer.measuredRealTimeFactor(), 0.5, 0.01);
  EXPECT_NEAR(pacer.stepRateHz(), 50000, 500);
  EXPECT_GT(pacer.overruns(), 0);
  EXPECT_GT(pacer.resyncs(), 0);
  EXPECT_GT(steps, 0);
}

// The measured factor at real time is 1, and it is a running value before the first window.
TEST(Pacer, MeasuredFactorAtRealTime) {
  FakeClock clock;
  Pacer pacer(clock, options(1.0));
  run(&clock, &pacer, 0.5, 1e-3);
  EXPECT_NEAR(pacer.measuredRealTimeFactor(), 1.0, 0.01);
  run(&clock, &pacer, 2.0, 1e-3);
  EXPECT_NEAR(pacer.measuredRealTimeFactor(), 1.0, 0.01);
}

// restart() forgets the time spent paused.
TEST(Pacer, RestartDropsTheBacklog) {
  FakeClock clock;
  Pacer pacer(clock, options(1.0));
  clock.now_s += 0.05;  // paused for 50 ms
  pacer.restart();
  EXPECT_EQ(pacer.nextBatch(), 0);
  clock.now_s += 1e-3;
  EXPECT_EQ(pacer.nextBatch(), 100);
}

// Changing the factor re-derives the catch-up bound and starts afresh.
TEST(Pacer, ChangesFactor) {
  FakeClock clock;
  Pacer pacer(clock, options(1.0));
  pacer.setRealTimeFactor(0.5);
  EXPECT_EQ(pacer.maxBatchSteps(), 100);
  EXPECT_EQ(pacer.realTimeFactor(), 0.5);
  clock.now_s += 1e-3;
  EXPECT_EQ(pacer.nextBatch(), 50);
}

TEST(Pacer, RejectsBadOptions) {
  FakeClock clock;
  PacerOptions o = options(1.0);
  o.step_s = 0;
  EXPECT_THROW(Pacer(clock, o), std::invalid_argument);
  EXPECT_THROW(Pacer(clock, options(-1.0)), std::invalid_argument);
  o = options(1.0);
  o.overrun_lag_s = 0.5;  // past max_lag_s: never an overrun before a re-sync
  EXPECT_THROW(Pacer(clock, o), std::invalid_argument);
  Pacer pacer(clock, options(1.0));
  EXPECT_THROW(pacer.setRealTimeFactor(std::numeric_limits<double>::quiet_NaN()),
               std::invalid_argument);
}

// The step meter keeps the longest step since its mark, and a mark starts a new window.
TEST(StepMeter, LongestStepSinceTheMark) {
  FakeClock clock;
  clock.now_s = 0.0;  // exact sums of the costs below
  StepMeter meter(clock);
  const double costs_s[] = {1e-6, 5e-3, 2e-6};
  for (double cost_s : costs_s) {
    meter.begin();
    clock.now_s += cost_s;
    meter.end();
  }
  EXPECT_NEAR(meter.longestSeconds(), 5e-3, 1e-15);
  EXPECT_EQ(meter.steps(), 3);
  meter.mark();
  EXPECT_EQ(meter.longestSeconds(), 0.0);
  EXPECT_EQ(meter.steps(), 0);
  meter.begin();
  clock.now_s += 3e-6;
  meter.end();
  EXPECT_NEAR(meter.longestSeconds(), 3e-6, 1e-15);
}

// The thread CPU clock advances with work done and not with time spent asleep.
TEST(ThreadCpuClock, CountsWorkNotSleep) {
  ThreadCpuClock cpu;
  const double t0_s = cpu.nowSeconds();
  std::this_thread::sleep_for(std::chrono::milliseconds(50));
  const double slept_s = cpu.nowSeconds() - t0_s;
  EXPECT_LT(slept_s, 0.02);
  volatile double sink = 0;
  const double t1_s = cpu.nowSeconds();
  for (int i = 0; i < 20000000; ++i) sink = sink + 1e-9 * i;
  EXPECT_GT(cpu.nowSeconds() - t1_s, 0.0);
}

// Issue 24 item 3: demo.launch real_time_factor:=1 ran free flight at free_flight_factor 0.02
// (0.42 s of simulated time in 20.1 s of wall time). The free-flight factor only ever speeds
// the run up.
TEST(FreeFlightPace, NeverSlowerThanRequested) {
  EXPECT_EQ(freeFlightPace(1.0, 0.02), 1.0);     // demo at real time
  EXPECT_EQ(freeFlightPace(0.001, 0.02), 0.02);  // demo in slow motion
  EXPECT_EQ(freeFlightPace(0.0, 0.02), 0.0);     // as fast as possible wins
  EXPECT_EQ(freeFlightPace(0.5, 0.0), 0.5);      // no free-flight factor
}

// The pacer at the pace of the demo's free flight with real_time_factor 1 keeps real time
// between strikes: simulated / wall time >= 0.98 (fake clock: every batch run at once).
TEST(FreeFlightPace, DemoAtRealTimeKeepsRealTimeBetweenStrikes) {
  FakeClock clock;
  PacerOptions o;
  o.step_s = 1e-5;
  o.real_time_factor = freeFlightPace(1.0, 0.02);
  Pacer pacer(clock, o);
  long steps = 0;
  for (int i = 0; i < 5000; ++i) {  // 5 s of wall time in 1 ms ticks
    clock.now_s += 1e-3;
    steps += pacer.nextBatch();
  }
  const double simulated_s = steps * o.step_s;
  EXPECT_GE(simulated_s / 5.0, 0.98);
  EXPECT_GE(pacer.measuredRealTimeFactor(), 0.98);
}

}  // namespace
}  // namespace threshing_sim
