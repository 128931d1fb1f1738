// The event-driven integrator's shared context (folder-private; docs/architecture.md lists the
// stages). The method is summarised at the top of step.cc; eventDrivenStep there calls the
// stages in order, each in the file named below, with the state carried in a StepPlan.
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <vector>

#include "../internal.h"

namespace threshing_sim {
namespace internal {
namespace event_driven {

constexpr double kInf = std::numeric_limits<double>::infinity();

// Per-step context: the data at the step start (drum state) and the candidate pairs.
struct Ctx {
  const Model& m;
  Data& d;
  Workspace& ws;
};

inline bool isActive(const PairMemory& mem) { return mem.state != ContactState::kSeparated; }

// Whether a rigid pair's contact, closed since before t, ended at time t [s] (its normal force
// released it, or an impact elsewhere made it bounce). At t its gap is the round-off of the
// constraint it held and its normal velocity that constraint's drift (integration error, of the
// order of the tolerance): neither is an approach, and which side of zero they land on differs
// between two runs that took different steps (the island scheme's sub-systems, another
// tolerance). Over the step from t the pair closes again only when its gap falls below minus
// the position error scale (eventValues), as a graze counts; it is not opened at t.
inline bool releasedAt(const PairMemory& mem, const ContactParams& p, double t) {
  return !isActive(mem) && p.law == ContactLaw::kRigid && mem.last_contact_end_s == t &&
         mem.episode_start_s < t;
}

// Drum state at absolute time t (the target is fixed within a step).
inline Drive driveAtTime(const Ctx& c, double t) { return driveAt(c.m, c.d, t - c.d.t_s); }

// Number of kernels still on their pedicels.
inline long attachedCount(const Data& d) {
  return std::count(d.kernel_attached.begin(), d.kernel_attached.end(), 1);
}

// How much of a separated pair evaluateAll computes.
enum class SeparatedPairs {
  kNear,  // exact unless surely beyond a quarter of the broad-phase margin (reported contacts;
          // kernel and obstacle pairs by the supporting-line bound)
  kSign,  // the sign of the gap: tooth pairs as kNear, other pairs exact only within reach
          // by the supporting-line bound (event functions; see evaluateAll)
  kNone,  // nothing (Runge-Kutta stages: separated pairs exert no force)
};

// Arming of one event function over a step: off, fires on reaching zero, or fires on falling
// below its value at the step start.
enum class Arm : std::uint8_t { kOff, kAtZero, kBelowStart };

// Whether an event function armed as `arm` has fired at value v (v0: its value at the step
// start), and its signed distance from firing (> 0 before, <= 0 once fired; kBelowStart:
// v - v0, which is 0 at the start itself).
inline bool armFires(Arm arm, double v, double v0) {
  return arm == Arm::kAtZero ? v <= 0 : arm == Arm::kBelowStart && v < v0;
}
inline double armValue(Arm arm, double v, double v0) { return arm == Arm::kAtZero ? v : v - v0; }

// What one event-driven step carries from stage to stage.
struct StepPlan {
  double t_end_s = 0;         // the advanceTo call's target time [s]
  double margin_m = 0;        // broad-phase margin: the step cannot outrun it [m]
  double h_s = 0;             // trial step length, then the accepted one [s]
  double h_wanted_s = 0;      // the step-size proposal before truncation at t_end [s]
  bool truncated = false;     // h_s was cut short to land on t_end_s
  bool rejected = false;      // some trial step was rejected
  double h_next_s = 0;        // the step-size law's proposal for the next step [s]
  bool peaks_on = false;      // compliant force peaks are located over this step
  bool event = false;         // an event function fired over the step
  double h_take_s = 0;        // the step taken: h_s, or the located event [s]
  double h_fired_s = 0;       // a step length at whose end an event is known to have fired [s]
  bool end_evaluated = true;  // the last rhs() call was at the step's end state
};

// --- evaluate.cc: the geometry of the candidate pairs at a state ----------------------------
void evaluateAll(const Ctx& c, const VecX& z, const VecX& u, const Drive& dr,
                 SeparatedPairs separated = SeparatedPairs::kNear, double horizon_s = 0.0);

// --- rhs_memo.cc, rhs.cc: the right-hand side under the current index sets ------------------
bool rhsMemoHit(const Ctx& c, const Drive& dr, const VecX& z, const VecX& u,
                SeparatedPairs separated, double horizon_s);
void rhsMemoStore(const Ctx& c, const Drive& dr, const VecX& z, const VecX& u,
                  SeparatedPairs separated, double horizon_s, const VecX& udot, double torque);
bool rhs(const Ctx& c, double t, const VecX& z, const VecX& u, VecX* udot, double* drum_torque,
         bool store_forces, SeparatedPairs separated = SeparatedPairs::kNear,
         double horizon_s = 0.0);

// --- dopri.cc: one Dormand-Prince trial step ------------------------------------------------
bool dopriStep(const Ctx& c, double t0, double h, const VecX& z0, const VecX& u0, VecX* z1,
               VecX* u1, double* err, double* torque1);

// --- modal_split.cc: the Lawson split of the modal teeth in contact (within dopriStep) -------
// Marks in ws.ed.tooth_split the teeth the trial step of length h from (z0, u0) splits: the
// option is on, the drum at its target speed, the tooth modal (not a rod) with a valid
// propagator and not advanced as a free tooth (ws.ed.tooth_exact); their start amplitudes and
// node factors. Returns the number marked.
int beginModalSplit(const Ctx& c, double h, const VecX& z0, const VecX& u0);
// Overwrites the split teeth's stage s state in ws.ed.zz, ws.ed.uu.
void modalSplitStageState(const Ctx& c, int s, double h);
// Their stage s contact term from ws.ed.udot at the stage state ws.ed.zz, ws.ed.uu.
void modalSplitStoreStage(const Ctx& c, int s, double omega_radps);
// Their error estimate into ws.ed.err_split, their dofs marked 2 in ws.ed.own_error.
void modalSplitError(const Ctx& c, double h);

// --- events.cc: event functions, arming, detection, location --------------------------------
void eventValues(const Ctx& c, double t, const VecX& z, const VecX& u, std::vector<double>* vals,
                 std::vector<double>* rates = nullptr, double horizon_s = 0.0);
double hermiteMinimum(double g0, double r0, double g1, double r1, double h, double* s_min);

// --- peaks.cc: located maxima of the compliant forces ---------------------------------------
bool compliantForceSnapshot(const Ctx& c, double t, const VecX& z, const VecX& u, const VecX& udot,
                            std::vector<double>* f, std::vector<double>* r,
                            std::vector<std::uint8_t>* on);
void locateForcePeaks(const Ctx& c, double t0, double h, const VecX& z0, const VecX& u0,
                      const VecX& z1, const VecX& u1, bool end_evaluated);

// --- impact.cc, modes.cc: impacts and contact modes -----------------------------------------
void solveImpact(const Ctx& c, double t, bool force_plastic);
bool updateModes(const Ctx& c, double t, const std::vector<int>& forced_slip);

// --- the step's stages, in the order eventDrivenStep (step.cc) calls them ------------------
// (motionBound, before them: step_size.cc)
double motionBound(const Ctx& c);
void prepareCandidates(const Ctx& c, StepPlan* plan);             // 1, step.cc
void openTouchingContacts(const Ctx& c);                          // 2, modes.cc
void planStep(const Ctx& c, double v_bound_mps, StepPlan* plan);  // 3, step_size.cc
void armEvents(const Ctx& c, StepPlan* plan);                     // 4, events.cc
bool integrateAdaptive(const Ctx& c, StepPlan* plan);             // 5, step_size.cc
void detectEvents(const Ctx& c, StepPlan* plan);                  // 6, events.cc
void locateFirstEvent(const Ctx& c, StepPlan* plan);              // 7, events.cc
// (then locateForcePeaks, peaks.cc)
void acceptStep(const Ctx& c, const StepPlan& plan);                        // 8, accept.cc
void recordStepForces(const Ctx& c);                                        // 9, accept.cc
void switchModes(const Ctx& c, const StepPlan& plan);                       // 10, modes.cc
void finishStep(const Ctx& c, const StepPlan& plan, long attached_before);  // 11, accept.cc

}  // namespace event_driven
}  // namespace internal
}  // namespace threshing_sim
