// Bounded work in advanceTo() (issue 14, defect 1): a state that needs ever smaller steps, a
// step below the rounding of t and a non-finite target each end in kFailed with a typed cause
// (data.stats.failure), within a bounded wall time, the last good state kept.
#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <thread>

#include "sim_test_util.h"
#include "threshing_sim/core/failure.h"

namespace threshing_sim {
namespace {

constexpr IntegratorType kED = IntegratorType::kEventDriven;
constexpr IntegratorType kTS = IntegratorType::kTimeStepping;

// Fails the test binary (abort) if the body does not return within limit_s of wall time: a
// hang shows as a failure instead of blocking the suite until ctest's timeout.
class Watchdog {
 public:
  explicit Watchdog(double limit_s)
      : thread_([this, limit_s] {
          const auto end =
              std::chrono::steady_clock::now() + std::chrono::duration<double>(limit_s);
          while (!done_) {
            if (std::chrono::steady_clock::now() > end) {
              std::fprintf(stderr, "watchdog: no return within %g s (a hang)\n", limit_s);
              std::abort();
            }
            std::this_thread::sleep_for(std::chrono::milliseconds(10));
          }
        }) {}
  ~Watchdog() {
    done_ = true;
    thread_.join();
  }

 private:
  std::atomic<bool> done_{false};
  std::thread thread_;
};

double wallSince(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

// The core reproduction: the bodies reset with the drum at 0.0510 rad put the kernel
// inside the tooth (forces ~30 kN), and the step size collapses to ~1e-11 s. Before the work
// budget advanceTo(1e-5) did not return for minutes; now it fails within its budget (2,000 +
// 3e8/s x 1e-5 s = 5,000 trial steps), naming the cause, the state finite and short of 1e-5 s.
TEST(WorkBudget, ResetIntoToothFailsWithBudgetCause) {
  Model m = testutil::defaultSceneModel(kED);
  compileModel(&m);
  Data d;
  resetData(m, &d);
  d.theta_rad = 0.0510;
  resetBodiesKeepTime(m, &d);
  const auto t0 = std::chrono::steady_clock::now();
  StepStatus s;
  {
    Watchdog watchdog(60.0);
    s = advanceTo(m, &d, 1e-5);
  }
  const double wall_s = wallSince(t0);
  RecordProperty("wall_s", testutil::fmt(wall_s));
  // It returns, bounded: either it fails within its budget, naming the cause, or (since the
  // event location by regula falsi of the contact-cost work) a non-finite step is caught and
  // crossed by the small-step recovery, which the statistics count. Never a hang.
  EXPECT_LT(wall_s, 30.0);
  EXPECT_TRUE(d.z.allFinite() && d.u.allFinite());
  if (s == StepStatus::kFailed) {
    EXPECT_EQ(d.stats.failure.cause, FailureCause::kWorkBudget) << describe(d.stats.failure);
    EXPECT_EQ(d.stats.failure.budget, 5000);
    EXPECT_GT(d.stats.failure.work, d.stats.failure.budget);
    EXPECT_EQ(d.stats.failure.t_s, d.t_s);
    EXPECT_LT(d.t_s, 1e-5);
    EXPECT_NE(describe(d.stats.failure).find("work budget"), std::string::npos);
  } else {
    EXPECT_EQ(s, StepStatus::kRecovered);
    EXPECT_GE(d.stats.numerical_recoveries, 1);
    EXPECT_EQ(d.t_s, 1e-5);
  }
  // A later reset clears the failure; a reset with the drum away from the kernel runs on.
  d.theta_rad = 0.2;
  resetBodiesKeepTime(m, &d);
  EXPECT_EQ(d.stats.failure.cause, FailureCause::kNone);
  EXPECT_EQ(advanceTo(m, &d, d.t_s + 1e-4), StepStatus::kOk);
}

// Time stepping with a step far below the rounding of t (t = 1e6 s, dt = 1e-12 s): before,
// t + dt == t and the loop never ended; now kTimeStalled after 100 such steps.
TEST(WorkBudget, StepBelowTimeRoundingFailsAsTimeStalled) {
  Model m = testutil::defaultSceneModel(kTS);
  m.integrator.dt_s = 1e-12;
  compileModel(&m);
  Data d;
  resetData(m, &d);
  d.t_s = 1e6;
  StepStatus s;
  {
    Watchdog watchdog(60.0);
    s = advanceTo(m, &d, 1e6 + 1e-9);
  }
  EXPECT_EQ(s, StepStatus::kFailed);
  EXPECT_EQ(d.stats.failure.cause, FailureCause::kTimeStalled) << describe(d.stats.failure);
}

// A non-finite target: before, t >= NaN was never true and the loop stepped forever.
TEST(WorkBudget, NonFiniteTargetIsRefused) {
  for (IntegratorType type : {kED, kTS}) {
    Model m = testutil::defaultSceneModel(type);
    compileModel(&m);
    Data d;
    resetData(m, &d);
    StepStatus s;
    {
      Watchdog watchdog(60.0);
      s = advanceTo(m, &d, std::nan(""));
    }
    EXPECT_EQ(s, StepStatus::kFailed);
    EXPECT_EQ(d.stats.failure.cause, FailureCause::kBadTarget);
    EXPECT_EQ(d.t_s, 0.0);
  }
}

// A long interval gets a budget in proportion: the default scene over 0.01 s (one strike,
// ~320 steps) is far inside it, and the failure record stays empty.
TEST(WorkBudget, OrdinaryRunStaysInsideBudget) {
  for (IntegratorType type : {kED, kTS}) {
    Model m = testutil::defaultSceneModel(type);
    compileModel(&m);
    Data d;
    resetData(m, &d);
    EXPECT_NE(advanceTo(m, &d, 0.01), StepStatus::kFailed);
    EXPECT_EQ(d.stats.failure.cause, FailureCause::kNone);
    EXPECT_EQ(d.stats.failure.work, 0);
  }
}

// Under the island scheme (issue 22): n kernels swinging on their pedicels (hung 2 mm aside), 12 mm
// apart, far from anything (no teeth), event-driven at tolerance 1e-6 with max_step max_step_s.
// Their own clocks integrate step by step (their swing is beyond the pedicel's closed form).
Model swingingPedicels(int n, double max_step_s) {
  Model m = testutil::bareModel(kED);
  m.integrator.islands = true;
  m.integrator.tolerance = 1e-6;
  m.integrator.max_step_s = max_step_s;
  for (int i = 0; i < n; ++i)
    m.kernels.push_back(testutil::hangingKernel(Vec2(0.012 * i, 0.0), 2e-3));
  compileModel(&m);
  return m;
}

// test_stream's failing bounded run under islands (max_step 1e-9 s): the windows and the lone
// kernels' clocks take 1e-9 s steps, 1e5 of each per 1e-4 s. Before, the island scheme had no
// budget over its windows and lone clocks: this call ran them all (1e5 windows, 1e6 clock steps)
// and returned kOk, and the stream in the node ran for minutes. Now the call fails on its budget
// (2,000 + 3e8/s x 1e-4 s, plus 0.3 per clock step of its clocks' own spans), naming the cause.
TEST(WorkBudget, IslandsWithATinyMaxStepFailOnTheCallsBudget) {
  const Model m = swingingPedicels(10, 1e-9);
  Data d;
  resetData(m, &d);
  StepStatus s;
  {
    Watchdog watchdog(60.0);
    s = advanceTo(m, &d, 1e-4);
  }
  const FailureInfo& f = d.stats.failure;
  ASSERT_EQ(s, StepStatus::kFailed);
  EXPECT_EQ(f.cause, FailureCause::kWorkBudget) << describe(f);
  ASSERT_NE(f.scope, nullptr);
  EXPECT_NE(std::string(f.scope).find("island scheme"), std::string::npos);
  EXPECT_NE(describe(f).find("[work_budget]"), std::string::npos) << describe(f);
  EXPECT_LT(d.t_s, 1e-4);
  // Bounded: the work done is within one unit of the budget, and the budget within twice the
  // interval's (the clocks' spans add 0.3 per 1e-9 s step); the windows are within it.
  EXPECT_GE(f.budget, 32000);
  EXPECT_LE(f.budget, 2 * 32000);
  EXPECT_LE(f.work, f.budget + 1);
  EXPECT_LE(d.stats.scheduler.windows, f.budget + 1);
  EXPECT_TRUE(d.z.allFinite() && d.u.allFinite());
}

// A lone kernel's clock catching up a long lazy span in one call: advanceToLazy leaves the
// swinging kernels on their own clocks, then a sync must bring them over that span with 1e-9 s
// steps (the model's max_step lowered). Before, a clock could take 1e7 steps per call (10 kernels
// x up to 1e6 steps here, then kOk); now its steps are spent from the sync's budget (2,000 plus
// 3e8/s x each clock's span: a clock that completes spends more than its span brings, so the
// budget stays below (2,000 + 3e5) / 0.7) and the sync fails on it, naming the pedicel clock.
TEST(WorkBudget, IslandsLoneKernelClockIsBounded) {
  Model m = swingingPedicels(10, 1e-4);
  Data d;
  resetData(m, &d);
  ASSERT_EQ(advanceToLazy(m, &d, 1e-3), StepStatus::kOk) << describe(d.stats.failure);
  ASSERT_GT(d.stats.scheduler.pedicel_steps, 0);  // the clocks integrate step by step
  m.integrator.max_step_s = 1e-9;
  const long clock_steps_before = d.stats.scheduler.pedicel_steps;
  StepStatus s;
  {
    Watchdog watchdog(60.0);
    s = syncBodies(m, &d);
  }
  const FailureInfo& f = d.stats.failure;
  ASSERT_EQ(s, StepStatus::kFailed);
  EXPECT_EQ(f.cause, FailureCause::kWorkBudget) << describe(f);
  ASSERT_NE(f.scope, nullptr);
  EXPECT_NE(std::string(f.scope).find("pedicel clock"), std::string::npos) << f.scope;
  EXPECT_LE(d.stats.scheduler.pedicel_steps - clock_steps_before, 440000);
  EXPECT_LE(f.budget, 440000);
  EXPECT_LE(f.work, f.budget + 1);
}

}  // namespace
}  // namespace threshing_sim
