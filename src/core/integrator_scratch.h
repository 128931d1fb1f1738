// The two global integrators' state and scratch memory, held by Workspace (internal.h) as
// `ed` (event-driven) and `ts` (time stepping), and the small types they keep: a state's
// remembered values, a free tooth's exact propagator, the right-hand side's memo.
// Not installed; nothing outside src/core includes it.
#pragma once

#include <Eigen/LU>
#include <cstdint>
#include <cstring>
#include <limits>
#include <utility>
#include <vector>

#include "threshing_sim/core/data.h"
#include "threshing_sim/core/model.h"

namespace threshing_sim {
namespace internal {

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

// One tooth's Lawson (integrating-factor) Dormand-Prince step (IntegratorParams::modal_split):
// its modal state y = [q; qdot] in the interaction picture of its free propagator, in modal
// amplitudes a = V^-1 y, where the propagator is diagonal (exp(lambda t)). Stage s is
// a_s = G(c_s) a_0 + h sum_j a_sj G(c_s - c_j) n_j with n_j = V^-1 [0; N_j], N_j the stage's
// acceleration minus the free tooth's (the contact force), G(x) = exp(lambda x h). Scratch, sized
// 2n on the first use and reused.
struct ModalSplitScratch {
  Eigen::VectorXcd a0;         // amplitudes of the step start [mixed]
  Eigen::VectorXcd n_k[7];     // V^-1 [0; N_j] of each stage [mixed / s]
  Eigen::VectorXcd growth[6];  // exp(lambda c_s h) of the nodes c_1..c_6 (growth[0]: c_1) [-]
  Eigen::VectorXcd decay[6];   // exp(-lambda c_s h) likewise [-]
  Eigen::VectorXcd shift;      // static shift a* of each mode (0: none) [mixed]
  Eigen::VectorXcd a;          // scratch amplitudes [mixed]
  // Real and imaginary parts of the propagator's V and of V^-1's velocity columns (real
  // matrix-vector products), built at the drum speed factors_omega_radps.
  double factors_omega_radps = std::numeric_limits<double>::quiet_NaN();  // [rad/s]
  MatX V_re, V_im;                                                        // 2n x 2n [mixed]
  MatX Vinv_u_re, Vinv_u_im;                                              // 2n x n [mixed]
  VecX a_re, a_im;    // scratch: amplitudes' parts, 2n [mixed]
  VecX N;             // scratch: contact modal acceleration, n [1/s^2 sqrt(kg) m]
  VecX nk_re, nk_im;  // scratch: V^-1 [0; N] parts, 2n [mixed / s]
};

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

}  // namespace internal

// The event-driven integrator's state carried across steps and its scratch
// (src/core/event_driven/); grows to the largest sizes seen, then is reused.
struct EventDrivenScratch {
  long trial_steps = 0;       // Dormand-Prince trial steps since construction, the work advanceTo()
                              // counts against its budget [-]
  VecX rk_k[7], rk_tmp;       // Runge-Kutta stage derivatives [z; u] and scratch
  double h = 0;               // last accepted step size [s]
  VecX fn, ft;                // contact forces per geom at the last rhs [N]
  VecX imp_n, imp_t;          // their integrals over the last trial step [N s]
  double torque_impulse = 0;  // integral of the drum contact torque [N m s]
  // Scratch, reused so that a step allocates nothing after warm-up.
  VecX z1, u1, zt, ut;                   // trial end states [m or -, m/s or -]
  VecX zz, uu, udot;                     // Runge-Kutta stage state and acceleration
  VecX udot_end, udot_ev;                // accelerations at the step end / event checks
  VecX imp_n_step, imp_t_step;           // impulses of the accepted step per geom [N s]
  std::vector<double> ev0, ev1, evm;     // event function values (see eventValues)
  std::vector<double> rate0, rate1;      // their rates at the step ends [unit / s]
  std::vector<std::uint8_t> arm;         // arming of each function over the step
  std::vector<double> ev_lo, ev_hi;      // event location: values at the bracket's ends
  VecX z_hi, u_hi;                       // and the state at its upper end
  VecX imp_n_hi, imp_t_hi;               // with the impulses up to it [N s]
  double torque_impulse_hi = 0;          // and the drum torque impulse [N m s]
  VecX imp_n_saved, imp_t_saved;         // impulses kept across a graze probe [N s]
  std::vector<int> forced_slip;          // geoms forced into slip by a stick-slip event
  std::vector<std::pair<int, int>> idx;  // constraint rows: (active contact, 0 N / 1 T)
  MatX A;                                // constraint matrix of those rows (grow-only)
  VecX rc, lam;                          // its right-hand side and solution
  std::vector<int> row_perm, col_perm;   // pivoting of the elimination
  // Exact propagation of free teeth (IntegratorParams::exact_free_teeth).
  std::vector<internal::ToothPropagator> prop;  // per tooth, keyed on the drum speed
  std::vector<std::uint8_t> tooth_exact;        // per tooth: exact over the current trial [-]
  std::vector<std::uint8_t> own_error;  // per dof: 0 out of the error estimate, 1 the Runge-Kutta
                                        // estimate, 2 the modal split's (err_split) [-]
  // Lawson split of the modal teeth in contact (IntegratorParams::modal_split).
  std::vector<std::uint8_t> tooth_split;           // per tooth: split over the current trial [-]
  std::vector<internal::ModalSplitScratch> split;  // per tooth
  VecX err_split;                                  // error estimate of split dofs [z; u]
  // Located force peaks: per geom, the compliant normal force [N] and its rate [N/s] at the
  // step start (f0, r0) and end (f1, r1), and whether the pair is in compliant contact there.
  std::vector<double> pk_f0, pk_r0, pk_f1, pk_r1;
  std::vector<std::uint8_t> pk_on, pk_on_end;
  // Accelerations at a peak probe [m/s^2 or modal 1/s^2].
  VecX pk_udot;
  // The candidates' narrow-phase warm starts (PairMemory::warm_*) before the probes, restored
  // after them: 5 values per candidate pair.
  std::vector<double> pk_warm;
  std::vector<int> cand_entry;       // pair-table index of each candidate (candidateMemory)
  internal::RhsMemo memo;            // the last right-hand side's inputs
  internal::StateValues end_values;  // momentum at the last step end (the energy slot unused)
};

// The contact phase's state carried across its steps and its scratch (src/core/contact_phase/);
// grows to the largest sizes seen, then is reused. Vectors over the dofs hold accelerations of
// the kicks (m/s^2, rad/s^2, modal 1/s^2 sqrt(kg) m) or velocities; per-candidate vectors are
// indexed like ws.candidates and ws.geoms.
struct ContactPhaseScratch {
  // The last step's end, reused as the next step's start while the state, the drum speed and
  // the candidate pairs are still those.
  bool end_valid = false;              // something is stored [-]
  double end_t_s = 0;                  // its time [s]
  double end_omega_radps = 0;          // its drum speed [rad/s]
  VecX end_z, end_u;                   // its state [m or -, m/s or -]
  std::vector<PairId> end_candidates;  // its candidates [-]
  // The candidate list kept from step to step (keepCandidates): a bound of the distance any
  // body can have moved since the list was built [m].
  double list_motion_m = 0.0;
  // This step.
  VecX a0, a1;                   // kick accelerations at the start and the end
  VecX u_drift;                  // velocity after the first half kick and the drift
  VecX u_pred;                   // predicted end velocity, at which the end forces are evaluated
  VecX u_end;                    // end velocity while the friction is solved, then the step's end
  VecX fn0, ft0, fn1, ft1;       // contact forces at the start and the end, per candidate [N]
  std::vector<double> gap0_m;    // gaps at the start, per candidate [m]
  std::vector<double> vt0_mps;   // slip velocities at the start, per candidate [m/s]
  std::vector<double> at0_mps2;  // their rates under the start's forces [m/s^2]
  std::vector<double> ft_trial;  // the last friction projection's force before the cone
                                 // (its stick force), per candidate [N]
  // The closed contacts in contact space (contact_space.cc): the solves of one kick work on
  // these scalars and the velocity vector is touched once, when the changes are applied.
  struct ContactSpace {
    std::vector<int> cand;           // per row: its candidate [-]
    std::vector<int> row_of;         // per candidate: its row, -1 if none [-]
    MatX W;                          // W(2j + d, 3i + e): the change of row j's normal (d = 0) or
                                     // slip (d = 1) velocity per unit generalised force of row i
                                     // along its normal (e = 0), tangent (1) or residual gradient
                                     // (2): w_d(j)^T M^-1 w_e(i) over the bodies they share
                                     // [1/kg; 1/(kg N) for e = 2]; grow-only
    std::vector<int> coupled_start;  // rows coupled to row i (sharing a body with it, itself
    std::vector<int> coupled;        // included): coupled[coupled_start[i] .. [i + 1]) [-]
    std::vector<double> vn, vt;      // per row: normal and slip velocity now [m/s]
    std::vector<double> dfn, dft, dfr;  // per row: changes not yet applied to the vectors
                                        // [N, N, N^2 / 2 (the residual factor)]
  } cs;
  std::vector<double> vt_target;        // slip velocity the start's friction aims at [m/s]
  std::vector<double> vt_half_mps;      // slip velocity after the first half kick [m/s]
  std::vector<double> drift_rate_mps2;  // the drift's change of it per second [m/s^2]
  std::vector<double> fs0_N;            // signed normal force at the start (compliant law) [N]
  std::vector<std::uint8_t> opened;     // per candidate: closed over this step [-]
  std::vector<std::uint8_t> released;   // per candidate: opened over this step [-]
  std::vector<double> t_open_s;         // the interpolated time of that transition [s]
  std::vector<double> v_in_mps;         // a closing pair's approach speed there [m/s]
  std::vector<double> vn0_mps;          // normal velocities at the start, per candidate [m/s]
  // The teeth's exact propagators over the fixed steps as real 2n x 2n matrices [q; qd] ->
  // [q; qd] (built from the event-driven integrator's ToothPropagator), kStepMatrices per tooth,
  // keyed on the step and the drum speed.
  struct StepMatrix {
    double h_s = -1;         // the step [s]
    double omega_radps = 0;  // the drum speed [rad/s]
    long built = 0;          // when it was built (matrices_built then) [-]
    MatX phi;                // the propagator [mixed]
  };
  static constexpr size_t kStepMatrices = 4;
  std::vector<std::vector<StepMatrix>> phi;  // per tooth
  long matrices_built = 0;                   // step matrices built since construction [-]
  VecX y0, y1;                               // scratch: one tooth's [q; qd], 2n
  VecX y_unit;                               // scratch: a unit state, 2n
  long steps = 0;                            // contact-phase steps since construction [-]
};

// The time-stepping integrator's state carried across steps and its scratch
// (src/core/time_stepping/).
struct TimeSteppingScratch {
  VecX z_mid, u_free;    // midpoint configuration, free velocity [m or -, m/s or -]
  VecX u_end_guess;      // end velocity under the compliant forces' predicted impulses [m/s or -]
  VecX compliant_ratio;  // per contact row: expected friction per unit normal impulse [-]
  VecX compliant_rate;   // per contact row: end gap rate per unit of its impulses, < 0: held
                         // by a rigid row (the law at the start rate) [m/(N s^2)]
  std::vector<MatX> iteration_inverse;        // (I + h theta D + h^2 theta^2 K)^-1
  internal::StateValues end_values;           // energy and momentum at the last end
  std::vector<int> candidate_memory;          // pair-table index of each candidate
  std::vector<int> in_contact;                // pairs in contact at the last step end
  long in_contact_step = -2;                  // Data::steps when that list was made
  std::vector<std::uint8_t> attached_before;  // pedicels before this step's breaks [-]
  std::vector<MatX> iteration_stiffness;      // K(Omega) of each tooth [1/s^2]
  std::vector<MatX> iteration_matrix;         // I + h theta D + h^2 theta^2 K [-]
  double iteration_omega = -1;                // drum speed the matrices above were built at [rad/s]
  double iteration_h = -1;                    // and the step [s]
  // A modal tooth's iteration matrix is A + Omega^2 B with A = I + h theta D + h^2 theta^2 Lambda
  // (diagonal) and B = h^2 theta^2 (K_G - I): with A^-1/2 B A^-1/2 = V diag(mu) V^T, its inverse
  // is C diag(1 / (1 + Omega^2 mu)) C^T, C = A^-1/2 V; a drum ramp then costs no factorisation.
  std::vector<MatX> iteration_basis;   // C of each tooth [-]
  std::vector<VecX> iteration_mu;      // mu of each tooth [s^2]
  std::vector<MatX> iteration_scaled;  // C diag(1 / (1 + Omega^2 mu)) (scratch) [-]
  double iteration_basis_h = -1;       // the step C and mu were built for [s]
};

}  // namespace threshing_sim
