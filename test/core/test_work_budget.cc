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

}  // namespace
}  // namespace threshing_sim
