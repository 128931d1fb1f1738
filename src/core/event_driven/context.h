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

// The pair memory of candidate i (ws.candidates[i], the pair of ws.geoms[i]) by the pair-table
// index prepareCandidates cached for it (a hash lookup per use cost 9 % of a stream's
// instructions); by the lookup where the cache does not hold the pair.
inline PairMemory& candidateMemory(Workspace& ws, size_t i) {
  const std::uint64_t key = pairKey(ws.candidates[i]);
  if (i < ws.ed.cand_entry.size()) {
    const int index = ws.ed.cand_entry[i];
    if (index >= 0 && static_cast<size_t>(index) < ws.memory.size()) {
      PairTable::Entry& e = ws.memory.entry(index);
      if (e.first == key) return e.second;
    }
  }
  return ws.memory[key];
}

// How far the slip velocity of a slip begun from stick (PairMemory::slip_from_stick) must go
// past zero, against its slip sign, before its reversal counts [m/s]: the integrator's velocity
// error scale, tolerance x 1 m/s (the absolute floor of the error norm, as tolerance x 1e-2 m is
// the position one that a graze must dip below). Such a slip starts from zero slip velocity at
// the friction limit; one whose slip velocity turns back before it passes this scale is below
// what the step resolves, and compared with zero it cost two located events for nothing: in the
// stream scene (global scheme, the evcost changes, t = 7.16 ms) a kernel pressed on a grate bar
// by a pile of kernels, whose Hunt-Crossley contacts made its stick force jitter by 2 % from
// step to step (1.3e-8 s), reached the limit nearly every step, slipped, and its slip velocity
// turned back at 1e-14 m/s within a picosecond: 1124 slips under 1e-11 s, until simulate's work
// budget ran out at 7.18 ms. A slip begun otherwise (from an impact, or where a slip velocity
// reached zero at the limit: hard case 9) and one whose slip velocity passed the scale once
// reverse at zero itself.
inline double slipReversalScale(const IntegratorParams& integrator) {
  return integrator.tolerance * 1.0;
}

// Drum state at absolute time t (the target is fixed within a step).
inline Drive driveAtTime(const Ctx& c, double t) { return driveAt(c.m, c.d, t - c.d.t_s); }

// Number of kernels still on their pedicels.
inline long attachedCount(const Data& d) {
  return std::count(d.kernel_attached.begin(), d.kernel_attached.end(), 1);
}

// How much of a separated pair evaluateAll computes.
enum class SeparatedPairs {
  kNear,     // exact unless surely beyond a quarter of the broad-phase margin (reported contacts;
             // kernel and obstacle pairs by the supporting-line bound)
  kSign,     // the sign of the gap: tooth pairs as kNear, other pairs exact only within reach
             // by the supporting-line bound (event functions; see evaluateAll)
  kNone,     // nothing (Runge-Kutta stages: separated pairs exert no force)
  kReach,    // every separated pair, tooth pairs too, exact only within what its bodies can
             // cover in horizon_s at their present speeds (a tooth point: the drum's turn of
             // the tip and the modes' rate), else a bound, and not evaluated at all while its
             // last evaluation's gap over its speed bound says it stays apart (conservative
             // advancement): the contact phase's step ends, where only a gap's sign over the
             // next step matters (contact_phase/forces.cc)
  kStepEnd,  // a step's end: kSign over the horizon and kNear together (every other pair exact
             // within the larger of the two reaches); its results serve the statistics and the
             // published contacts (kNear) and the next step's event functions (kSign over any
             // horizon up to this one), so that the state between two steps is evaluated once
};

// Horizon [s] of the step-end evaluations (kStepEnd): the longest step the next one can take,
// so that its event functions at the start find the end's results (planStep takes at most the
// step-size proposal ws.ed.h, or the initial 1e-6 s before there is one).
inline double stepEndHorizon(const Workspace& ws, double h_s) {
  return std::max({h_s, ws.ed.h, ws.ed.h > 0 ? 0.0 : 1e-6});
}

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
                 std::vector<double>* rates = nullptr, double horizon_s = 0.0,
                 SeparatedPairs separated = SeparatedPairs::kSign);
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
