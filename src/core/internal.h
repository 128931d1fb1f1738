// threshing_sim core internals shared by the contact code and the two integrators.
// Not installed; nothing outside src/core includes it.
#pragma once

#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <complex>
#include <cstdint>
#include <cstring>
#include <limits>
#include <memory>
#include <utility>
#include <vector>

#include "contact/broad_phase.h"
#include "contact/contact_forces.h"
#include "contact/contact_solve.h"
#include "contact/narrow_phase.h"
#include "contact/pair_table.h"
#include "contact/smooth_forces.h"
#include "contact/stations.h"
#include "drive.h"
#include "episodes.h"
#include "integrator_scratch.h"
#include "small_vec.h"
#include "threshing_sim/core/beam.h"
#include "threshing_sim/core/data.h"
#include "threshing_sim/core/geometry.h"
#include "threshing_sim/core/large_deflection.h"
#include "threshing_sim/core/lcp.h"
#include "threshing_sim/core/model.h"
#include "threshing_sim/core/simulator.h"

namespace threshing_sim {
namespace internal {

// Dormand-Prince 5(4) tableau: nodes kC, stages kA (row 7 is the 5th-order solution, FSAL),
// error weights kE. Shared by the event-driven integrator and the kernels' own clocks.
inline constexpr double kC[7] = {0, 1. / 5, 3. / 10, 4. / 5, 8. / 9, 1, 1};
inline constexpr double kA[7][6] = {
    {0},
    {1. / 5},
    {3. / 40, 9. / 40},
    {44. / 45, -56. / 15, 32. / 9},
    {19372. / 6561, -25360. / 2187, 64448. / 6561, -212. / 729},
    {9017. / 3168, -355. / 33, 46732. / 5247, 49. / 176, -5103. / 18656},
    {35. / 384, 0, 500. / 1113, 125. / 192, -2187. / 6784, 11. / 84}};
inline constexpr double kE[7] = {71. / 57600,      0,         -71. / 16695, 71. / 1920,
                                 -17253. / 339200, 22. / 525, -1. / 40};

// Work budget of one advanceTo() call, in work units: kBaseWork plus kWorkPerSecond per second
// of simulated time the call covers. A unit is one integrator step (time stepping) or one
// Dormand-Prince trial step (event-driven: accepted, rejected, or one of an event's bisection).
// The scenes of config/ average 1e4-1e6 per simulated second (simulate's steps +
// rejected_steps), but the threshing streams of scripts/compare_teeth.py (600-1500 rpm, every
// tooth) have stretches of 1e-4 s that need 5e7 per second: kernels sliding on each other or on
// a tooth at 2-18 m/s while they bounce at mm/s, a contact event every 0.1 us (issue 12). The
// rate allows six times that, an average trial step of 3.3 ns; a call whose steps collapse (a
// body inside another: ~1e-11 s, 1e11 per second) still fails, on its 2,000 units however short
// it is (a trial step near a contact costs ~1e6 instructions: about a second of wall time).
constexpr double kBaseWork = 2e3;
constexpr double kWorkPerSecond = 3e8;
// The island scheme (src/core/async/) counts a scheduling window, an island's step or trial step
// and a lone kernel's own-clock step (accepted or rejected) as one unit each, and gives each lone
// kernel's clock kWorkPerSecond per second of its own time integrated step by step (a clock's
// catch-up over a long lazy span is paid for by that span, not by the call's interval).

// Grow-only sizing of scratch storage: the size rises to the largest request seen and stays,
// so that steady stepping allocates nothing; callers use the leading n entries (head, block).
inline void growTo(VecX* v, Eigen::Index n) {
  if (v->size() < n) v->resize(n);
}
inline void growTo(MatX* m, Eigen::Index rows, Eigen::Index cols) {
  if (m->rows() < rows || m->cols() < cols)
    m->resize(std::max(m->rows(), rows), std::max(m->cols(), cols));
}

// Bodies are numbered teeth first (0..T-1), then kernels (T..T+K-1); -1 is the fixed world.
inline int toothBody(int k) { return k; }
inline int kernelBody(const Model& m, int i) { return static_cast<int>(m.teeth.size()) + i; }
inline int numBodies(const Model& m) { return static_cast<int>(m.teeth.size() + m.kernels.size()); }
inline int bodyDofOffset(const Model& m, int body) {
  const int T = static_cast<int>(m.teeth.size());
  return body < T ? m.teeth[body].dof_offset : m.kernels[body - T].dof_offset;
}
inline int bodyDofCount(const Model& m, int body) {
  const int T = static_cast<int>(m.teeth.size());
  return body < T ? m.teeth[body].n_modes : 3;
}

// Builds (or keeps, if already built at this drum speed) the propagator of tooth `tooth` at drum
// speed omega_radps. Returns prop->valid: false for a rigid tooth or an eigendecomposition that
// does not reproduce (the balanced) A to 1e-9 relative (defective or ill-conditioned), where the
// caller must integrate the tooth instead. Allocates only when it (re)builds.
bool buildToothPropagator(const Model& m, int tooth, double omega_radps, ToothPropagator* prop);

// Free motion of a tooth over h [s] from (q0, qd0) to (q1, qd1) by a valid propagator (its
// scratch is used); the outputs must not alias the inputs.
void propagateTooth(ToothPropagator* prop, double h_s, const Eigen::Ref<const VecX>& q0,
                    const Eigen::Ref<const VecX>& qd0, Eigen::Ref<VecX> q1, Eigen::Ref<VecX> qd1);

struct AsyncState;  // the island-local scheduler (src/core/async/async.h)

// Called by the global scheme's advance after every accepted step of the data it advances (an
// island's sub-system, while its window is observed: Data::observer). Only reads.
class StepHook {
 public:
  virtual ~StepHook() = default;
  virtual void afterStep(const Data& d) const = 0;
};

}  // namespace internal

// Integrator scratch memory; grows to the largest sizes seen, then is reused.
struct Workspace {
  Workspace();
  ~Workspace();  // out of line (simulator.cc), where AsyncState is complete
  // The asynchronous island-local scheduler's state (integrator.islands); built on first use.
  std::unique_ptr<internal::AsyncState> async;
  // Not owned; set by the island scheme around an observed island's advance (else nullptr).
  const internal::StepHook* step_hook = nullptr;
  std::vector<PairId> candidates;            // broad-phase survivors
  std::vector<internal::ContactGeom> geoms;  // narrow-phase results for candidates
  internal::PairTable memory;
  // The contact stages' scratch (src/core/contact/): the broad phase's orders and bounds, the
  // tooth stations and mode values, the narrow phase's residual flexibility tables.
  internal::BroadPhaseScratch broad;
  internal::CentrelineScratch centreline;
  internal::NarrowPhaseScratch narrow;
  VecX forces;            // generalised forces [N or sqrt(kg) m/s^2]
  VecX u_old, du;         // velocities before an impulse, accelerations [m/s or -, m/s^2 or 1/s^2]
  VecX guard_z, guard_u;  // last good state for the non-finite guard
  TimeSteppingScratch
      ts;  // the time-stepping integrator's state and scratch (integrator_scratch.h)

  // The contact solve (src/core/contact/contact_solve.h): its islands' scratch, then its problem.
  internal::ContactSolveScratch solve;
  std::vector<int> active;  // indices into geoms of contacts in the problem
  VecX b, lambda, y;
  VecX b_offset;  // restitution target e dg_N- folded into b [m/s]
  std::vector<ContactRow> rows;
  EventDrivenScratch ed;  // the event-driven integrator's state and scratch (integrator_scratch.h)
  ContactPhaseScratch cp;  // the contact phase's (integrator_scratch.h)
  // Pair-table indices of the candidates of the previous step that were in contact.
  std::vector<int> prev_active;
  // Large-deflection teeth: the configuration of each at the q it was last computed for, and
  // every tooth's inverse mass at the state ld_minv_z (identity for modal teeth).
  std::vector<LdConfig> ld_cfg;  // per tooth
  std::vector<VecX> ld_cfg_q;    // the q of each [rad]
  std::vector<MatX> ld_minv;     // per tooth, M^-1 [1/(kg m^2)] or identity
  VecX ld_minv_z;                // the state ld_minv holds for
  bool ld_minv_valid = false;    // ld_minv is that of ld_minv_z
};

namespace internal {

// --- large-deflection teeth (large_deflection.cc) -----------------------------------------
// The configuration of large-deflection tooth k at z (recomputed only when its q changed).
const LdConfig& ldConfigOf(const Model& m, int tooth, const VecX& z, Workspace* ws);
// Every tooth's inverse mass at z for applyInverseMass / weightedDot: nullptr (the identity
// of the mass-normalised modes) when the model has no large-deflection tooth.
const std::vector<MatX>* toothInverseMass(const Model& m, const VecX& z, Workspace* ws);
// Time stepping: the iteration matrix M(q) + h theta D + h^2 theta^2 K of every
// large-deflection tooth at the midpoint z_mid, into ws->ts.iteration_inverse.
void updateLdIterationMatrices(const Model& m, const VecX& z_mid, double h_s, Workspace* ws);

// --- the contact pipeline -------------------------------------------------------------------
// Declared by its stages' headers in src/core/contact/ (included above): pair_table.h (pair
// memory), stations.h (tooth stations, centreline kinematics, kernel ellipses), broad_phase.h,
// narrow_phase.h (ContactGeom, evaluateContact), contact_forces.h (compliant normal law,
// generalised forces, velocity drift), contact_solve.h (inverse mass, island LCP) and
// smooth_forces.h (the forces without contacts).

// --- bookkeeping ---------------------------------------------------------------------------
// Mechanical energy of a configuration (see simulator.h) and the teeth's angular momentum.
double energyOf(const Model& m, const Data& d, const VecX& z, const VecX& u, double omega);
double angularMomentumOf(const Model& m, const VecX& z, const VecX& u, double omega);
// One tooth's angular momentum about the drum axis [kg m^2/s].
double toothAngularMomentum(const ToothModel& tm, const Eigen::Ref<const VecX>& q,
                            const Eigen::Ref<const VecX>& qd, double omega);
// Episodes, events, force statistics, pedicels, the deflection check: episodes.h.

// --- the integrators -------------------------------------------------------------------------
StepStatus timeSteppingStep(const Model& m, Data* d, double h_s);
StepStatus eventDrivenStep(const Model& m, Data* d, double t_end_s);
// The asynchronous island-local scheme (integrator.islands: true; src/core/async/).
StepStatus asyncAdvanceTo(const Model& m, Data* d, double t_end_s, bool sync = true,
                          double t_stop_s = std::numeric_limits<double>::quiet_NaN());
StepStatus asyncSync(const Model& m, Data* d);
StepStatus asyncStep(const Model& m, Data* d);
// Forgets the scheduler's state (a reset of the bodies).
void resetAsync(Data* d);

}  // namespace internal
}  // namespace threshing_sim
