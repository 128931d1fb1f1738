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

// Energy and angular momentum of one state, remembered with a copy of the state so that the
// next step can reuse them only if the state is bit for bit the same (nothing moved it).
class StateValues {
 public:
  void store(const Data& d, double energy_J, double momentum_kgm2ps) {
    z_ = d.z;
    u_ = d.u;
    attached_ = d.kernel_attached;
    omega_radps_ = d.omega_radps;
    energy_J_ = energy_J;
    momentum_kgm2ps_ = momentum_kgm2ps;
    valid_ = true;
  }
  void invalidate() { valid_ = false; }
  bool lookup(const Data& d, double* energy_J, double* momentum_kgm2ps) const {
    if (!valid_ || d.omega_radps != omega_radps_ || d.z.size() != z_.size() ||
        d.u.size() != u_.size() || d.kernel_attached != attached_ ||
        (z_.size() > 0 &&  // empty vectors have no storage: no memcmp on a null pointer
         (std::memcmp(d.z.data(), z_.data(), sizeof(double) * z_.size()) != 0 ||
          std::memcmp(d.u.data(), u_.data(), sizeof(double) * u_.size()) != 0)))
      return false;
    *energy_J = energy_J_;
    *momentum_kgm2ps = momentum_kgm2ps_;
    return true;
  }

 private:
  VecX z_, u_;                          // the state [m or -, m/s or -]
  std::vector<std::uint8_t> attached_;  // its pedicels [-]
  double omega_radps_ = 0;              // its drum speed [rad/s]
  double energy_J_ = 0;                 // mechanical energy [J]
  double momentum_kgm2ps_ = 0;          // teeth's angular momentum [kg m^2/s]
  bool valid_ = false;                  // something is stored
};

// Exact propagator of one tooth's free linear modal equations at a constant drum speed:
// y = [q; qdot] obeys y' = A y with A = [0 I; -S -D], S = Lambda + Omega^2 (K_G - I) and
// D = diag(2 zeta omega_i), so y(t + h) = V diag(exp(lambda_i h)) V^-1 y(t) (decomposed in
// balanced coordinates, see buildToothPropagator). Built once per drum speed; propagating is O(n^2)
// and allocates nothing. q is in sqrt(kg) m, qdot in sqrt(kg) m/s, so V and V^-1 mix those units.
struct ToothPropagator {
  double omega_radps = std::numeric_limits<double>::quiet_NaN();  // drum speed built at [rad/s]
  int n_modes = -1;         // n of the tooth it was built for [-]
  bool valid = false;       // the eigendecomposition reproduces A (else: Dormand-Prince) [-]
  Eigen::VectorXcd lambda;  // eigenvalues of A, 2n [1/s]
  Eigen::MatrixXcd V;       // right eigenvectors of A as columns, 2n x 2n [mixed]
  Eigen::MatrixXcd V_inv;   // V^-1, 2n x 2n [mixed]
  Eigen::VectorXcd c;       // scratch: modal amplitudes V^-1 y, then scaled, 2n [mixed]
};

// Builds (or keeps, if already built at this drum speed) the propagator of tooth `tooth` at drum
// speed omega_radps. Returns prop->valid: false for a rigid tooth or an eigendecomposition that
// does not reproduce (the balanced) A to 1e-9 relative (defective or ill-conditioned), where the
// caller must integrate the tooth instead. Allocates only when it (re)builds.
bool buildToothPropagator(const Model& m, int tooth, double omega_radps, ToothPropagator* prop);

// Free motion of a tooth over h [s] from (q0, qd0) to (q1, qd1) by a valid propagator (its
// scratch is used); the outputs must not alias the inputs.
void propagateTooth(ToothPropagator* prop, double h_s, const Eigen::Ref<const VecX>& q0,
                    const Eigen::Ref<const VecX>& qd0, Eigen::Ref<VecX> q1, Eigen::Ref<VecX> qd1);

// The inputs of the event-driven integrator's last right-hand side evaluation, so that a call
// with the same inputs (the step end, evaluated again as the next step's start, by the event
// functions and the statistics) reuses its results, which stay in the workspace until any
// other evaluation clears `valid`.
struct RhsMemo {
  // What the right-hand side reads of one candidate's pair memory.
  struct PairState {
    int state = 0;        // ContactState [-]
    bool closed = false;  // rigid normal closed [-]
    int slip_sign = 0;    // slip direction [-]
    double v_in_mps = 0;  // compliant approach speed [m/s]
    double hertz_K = 0;   // compliant Hertz constant [N/m^{3/2}]
  };
  bool valid = false;                  // the workspace holds that evaluation's results [-]
  const Model* model = nullptr;        // model it was made for
  double t_s = 0, theta_rad = 0;       // time [s] and drum angle [rad]
  double omega_radps = 0;              // drum speed [rad/s]
  double alpha_radps2 = 0;             // drum acceleration [rad/s^2]
  VecX z, u;                           // state [m or -, m/s or -]
  std::vector<std::uint8_t> attached;  // pedicels [-]
  std::vector<PairId> candidates;      // candidate pairs [-]
  std::vector<PairState> pairs;        // their memory, in that order
  int n_separated = 0;                 // separated candidates among them [-]
  int n_separated_other = 0;           // of which not tooth pairs [-]
  int separated = 0;                   // how separated pairs were evaluated (SeparatedPairs) [-]
  double horizon_s = 0;                // the event functions' horizon [s]
  VecX udot;                           // accelerations [m/s^2 or modal 1/s^2]
  double torque = 0;                   // contact torque on the drum [N m]
};

struct AsyncState;  // the island-local scheduler (src/core/async/async.h)

}  // namespace internal

// Integrator scratch memory; grows to the largest sizes seen, then is reused.
struct Workspace {
  Workspace();
  ~Workspace();  // out of line (simulator.cc), where AsyncState is complete
  // The asynchronous island-local scheduler's state (integrator.islands); built on first use.
  std::unique_ptr<internal::AsyncState> async;
  long trial_steps = 0;  // event-driven: Dormand-Prince trial steps since construction, the
                         // work advanceTo() counts against its budget [-]
  std::vector<PairId> candidates;            // broad-phase survivors
  std::vector<internal::ContactGeom> geoms;  // narrow-phase results for candidates
  internal::PairTable memory;
  // The contact stages' scratch (src/core/contact/): the broad phase's orders and bounds, the
  // tooth stations and mode values, the narrow phase's residual flexibility tables.
  internal::BroadPhaseScratch broad;
  internal::CentrelineScratch centreline;
  internal::NarrowPhaseScratch narrow;
  VecX forces;  // generalised forces [N or sqrt(kg) m/s^2]
  VecX u_free, z_mid, u_old, z_old, du;
  VecX guard_z, guard_u;                 // last good state for the non-finite guard
  std::vector<MatX> iteration_inverse;   // time stepping: (I + h theta D + h^2 theta^2 K)^-1
  internal::StateValues ts_end_values;   // time stepping: energy and momentum at the last end
  std::vector<int> ts_candidate_memory;  // time stepping: pair-table index of each candidate
  std::vector<int> ts_in_contact;        // time stepping: pairs in contact at the last step end
  long ts_in_contact_step = -2;          // time stepping: Data::steps when that list was made
  std::vector<std::uint8_t> ts_attached_before;  // time stepping: pedicels before this step's
                                                 // breaks [-]
  std::vector<MatX> iteration_stiffness;         // time stepping: K(Omega) of each tooth [1/s^2]
  std::vector<MatX> iteration_matrix;            // time stepping: I + h theta D + h^2 theta^2 K [-]
  std::vector<Eigen::PartialPivLU<MatX>> iteration_lu;  // and its factorisation
  double iteration_omega = -1;  // drum speed the matrices above were built at [rad/s]
  double iteration_h = -1;      // and the step [s]

  // The contact solve (src/core/contact/contact_solve.h): its islands' scratch, then its problem.
  internal::ContactSolveScratch solve;
  std::vector<int> active;  // indices into geoms of contacts in the problem
  VecX b, lambda, y;
  VecX b_offset;  // restitution target e dg_N- folded into b [m/s]
  std::vector<ContactRow> rows;
  // Event-driven integrator state.
  VecX rk_k[7], rk_y0, rk_y1, rk_err, rk_tmp, dense_a, dense_b;
  double ed_h = 0;               // last accepted step size [s]
  VecX ed_fn, ed_ft;             // contact forces per geom at the last rhs [N]
  VecX ed_imp_n, ed_imp_t;       // their integrals over the last trial step [N s]
  double ed_torque_impulse = 0;  // integral of the drum contact torque [N m s]
  // Event-driven scratch, reused so that a step allocates nothing after warm-up.
  VecX ed_z1, ed_u1, ed_zt, ed_ut;             // trial end states [m or -, m/s or -]
  VecX ed_zz, ed_uu, ed_udot;                  // Runge-Kutta stage state and acceleration
  VecX ed_udot_end, ed_udot_ev;                // accelerations at the step end / event checks
  VecX ed_imp_n_step, ed_imp_t_step;           // impulses of the accepted step per geom [N s]
  std::vector<double> ed_ev0, ed_ev1, ed_evm;  // event function values (see eventValues)
  std::vector<double> ed_rate0, ed_rate1;      // their rates at the step ends [unit / s]
  std::vector<std::uint8_t> ed_arm;            // arming of each function over the step
  std::vector<double> ed_ev_lo, ed_ev_hi;      // event location: values at the bracket's ends
  VecX ed_z_hi, ed_u_hi;                       // and the state at its upper end
  VecX ed_imp_n_hi, ed_imp_t_hi;               // with the impulses up to it [N s]
  double ed_torque_impulse_hi = 0;             // and the drum torque impulse [N m s]
  VecX ed_imp_n_saved, ed_imp_t_saved;         // impulses kept across a graze probe [N s]
  std::vector<int> ed_forced_slip;             // geoms forced into slip by a stick-slip event
  std::vector<std::pair<int, int>> ed_idx;     // constraint rows: (active contact, 0 N / 1 T)
  MatX ed_A;                                   // constraint matrix of those rows (grow-only)
  VecX ed_rc, ed_lam;                          // its right-hand side and solution
  std::vector<int> ed_row_perm, ed_col_perm;   // pivoting of the elimination
  // Event-driven exact propagation of free teeth (IntegratorParams::exact_free_teeth).
  std::vector<internal::ToothPropagator> ed_prop;  // per tooth, keyed on the drum speed
  std::vector<std::uint8_t> ed_tooth_exact;        // per tooth: exact over the current trial [-]
  std::vector<std::uint8_t> ed_own_error;          // per dof: counted in the error estimate [-]
  // Located force peaks: per geom, the compliant normal force [N] and its rate [N/s] at the
  // step start (f0, r0) and end (f1, r1), and whether the pair is in compliant contact there.
  std::vector<double> ed_pk_f0, ed_pk_r0, ed_pk_f1, ed_pk_r1;
  std::vector<std::uint8_t> ed_pk_on, ed_pk_on_end;
  // Accelerations at a peak probe [m/s^2 or modal 1/s^2].
  VecX ed_pk_udot;
  internal::RhsMemo ed_memo;            // the last event-driven right-hand side's inputs
  internal::StateValues ed_end_values;  // event-driven: momentum at the last step end (the
                                        // energy slot unused)
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
// large-deflection tooth at the midpoint z_mid, into ws->iteration_inverse.
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
// Tracks the largest tip deflection over L and warns once when it leaves the model's range.
void checkToothDeflection(const Model& m, Data* d);
// Records peak force statistics for one contact at time t.
void recordForce(const Model& m, Data* d, const ContactGeom& g, double fn, double ft, double t);
// Opens / closes contact episodes and emits ContactEvents.
void beginEpisode(const Model& m, Data* d, PairMemory* mem, const ContactGeom& g, double t,
                  double energy_net);
void endEpisode(const Model& m, Data* d, PairMemory* mem, const ContactGeom& g, double t,
                double energy_net);
void emitTransition(Data* d, const PairId& pair, ContactState from, ContactState to, double t,
                    const ContactGeom& g);
// Fills data.contacts from the current geoms and memory.
void publishContacts(Data* d, Workspace* ws);
// Detaches pedicels whose force passed the threshold.
void updatePedicels(const Model& m, Data* d);

// --- the integrators -------------------------------------------------------------------------
StepStatus timeSteppingStep(const Model& m, Data* d, double h_s);
StepStatus eventDrivenStep(const Model& m, Data* d, double t_end_s);
// The asynchronous island-local scheme (integrator.islands: true; src/core/async/).
StepStatus asyncAdvanceTo(const Model& m, Data* d, double t_end_s, bool sync = true);
StepStatus asyncSync(const Model& m, Data* d);
StepStatus asyncStep(const Model& m, Data* d);
// Forgets the scheduler's state (a reset of the bodies).
void resetAsync(Data* d);

}  // namespace internal
}  // namespace threshing_sim
