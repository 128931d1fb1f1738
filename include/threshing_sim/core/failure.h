// threshing_sim core: why advanceTo() returned StepStatus::kFailed.
//
// Every iterative routine of the core has an iteration limit, and advanceTo() has a work
// budget (integrator steps, rejected trial steps and located events per interval of simulated
// time). When a limit is reached the call stops, keeps the last good state, returns kFailed and
// records a FailureInfo in data.stats.failure naming where it stalled, so that a caller (the
// node's /diagnostics, simulate's status) can say why.
#pragma once

#include <cstdint>
#include <string>

namespace threshing_sim {

enum class FailureCause : std::uint8_t {
  kNone = 0,           // the last advanceTo() did not fail
  kNonFinite = 1,      // a step gave NaN or inf and the small-step recovery failed too
  kStepSizeLimit = 2,  // event-driven step-size loop: step below its floor or too many
                       // rejections of one step
  kWorkBudget = 3,     // advanceTo() used more steps, rejected steps and events than its budget
                       // for the interval (a stiff or chattering state needing ever smaller
                       // steps)
  kTimeStalled = 4,    // accepted steps too short to change the time t_s (below its rounding)
  kBadTarget = 5,      // the target time is not finite
};

// A failure of advanceTo(): its cause, where, and the work counted against the budget.
struct FailureInfo {
  FailureCause cause = FailureCause::kNone;
  double t_s = 0;         // simulation time of the last good state, kept in Data [s]
  double t_target_s = 0;  // the target time of the failed call [s]
  long work = 0;          // work units used by the call (steps + rejected steps + weighted
                          // events) [-]
  long budget = 0;        // the call's budget of work units [-]
  // What ran out or stalled, a static string naming the scheme's part, e.g. "island scheme: a
  // lone kernel's pedicel clock"; nullptr: the global scheme's step loop.
  const char* scope = nullptr;
};

// "work_budget", "non_finite", ... (stable names, for logs and diagnostics).
const char* toString(FailureCause cause);

// One line for a person: cause, time and work, e.g. "work budget exceeded at t = 0.0375 s
// (30012 of 30000 work units for 1e-05 s: steps, rejected steps and events)".
std::string describe(const FailureInfo& failure);

}  // namespace threshing_sim
