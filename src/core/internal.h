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

#include "drive.h"
#include "integrator_scratch.h"
#include "threshing_sim/core/beam.h"
#include "threshing_sim/core/data.h"
#include "threshing_sim/core/geometry.h"
#include "threshing_sim/core/large_deflection.h"
#include "threshing_sim/core/lcp.h"
#include "threshing_sim/core/model.h"
#include "threshing_sim/core/simulator.h"

namespace threshing_sim {
namespace internal {

// A short vector that never touches the heap (a tooth has at most kMaxModes = 64 modes,
// a kernel 3 dofs).
using SmallVec = Eigen::Matrix<double, Eigen::Dynamic, 1, 0, kMaxModes, 1>;

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
int bodyDofOffset(const Model& m, int body);
int bodyDofCount(const Model& m, int body);

// One body's share of a contact's Jacobians: dg/dt = w_n . u_body (+ the other body + rheonomic).
struct BodyJac {
  int body = -1;  // body index, -1 = fixed
  SmallVec w_n;   // d(dg_N/dt)/d(u_body)
  SmallVec w_t;   // d(dg_T/dt)/d(u_body)
};

// Everything known about one contact pair at one configuration.
struct ContactGeom {
  PairId pair;
  double gap_m = 0;        // signed gap [m]
  Vec2 n = Vec2::UnitY();  // unit normal towards the kernel (body 1) [-]
  Vec2 t = Vec2::UnitX();  // unit tangent J n [-]
  Vec2 p0 = Vec2::Zero();  // contact point on body 0's surface [m]
  Vec2 p1 = Vec2::Zero();  // contact point on body 1's (the kernel's) surface [m]
  double tooth_x_m = 0;    // tooth contacts: material coordinate [m]
  BodyJac side[2];         // side 0: tooth / kernel a / fixed; side 1: the kernel b
  double wtilde_n = 0;     // rheonomic part of dg_N/dt [m/s]
  double wtilde_t = 0;     // rheonomic part of dg_T/dt [m/s]
  double vn = 0;           // dg_N/dt [m/s]
  double vt = 0;           // dg_T/dt [m/s]
  double hertz_K = 0;      // Hertz constant K in F = K delta^{3/2} [N/m^{3/2}]
  // Radii of curvature of the two surfaces at p0 and p1 (inf: flat; a tooth pair's rho0 is
  // unused, its drift follows the deformed centreline) [m].
  double rho0_m = std::numeric_limits<double>::infinity();
  double rho1_m = std::numeric_limits<double>::infinity();
  double residual_mpN = 0;  // tooth contacts: residual flexibility of the truncated modes along
                            // n at the contact point, in series with the Hertz law [m/N]
  const ContactParams* params = nullptr;
  bool far = false;  // only a lower bound of the gap was computed (no Jacobians)
};

// Per-pair memory carried across steps (state, episode bookkeeping for events and stats).
struct PairMemory {
  ContactState state = ContactState::kSeparated;
  bool closed = false;           // rigid law: normal constraint active
  int slip_sign = 0;             // slip direction while sliding (sign of dg_T/dt)
  double v_in_mps = 0;           // compliant: approach speed at first touch [m/s]
  double hertz_K = 0;            // compliant: Hertz constant frozen at first touch, so that the
                                 // force of one episode derives from a potential [N/m^{3/2}]
  double ts_depth_m = 0;         // time stepping, rigid law: penetration the closed contact
                                 // may keep (its impact step's, at least h x zeno_velocity) [m]
  double episode_start_s = -1;   // time of first touch of the current episode [s]
  double episode_peak_N = 0;     // peak normal force within the episode [N]
  double episode_impulse_n = 0;  // normal impulse within the episode [N s]
  double episode_impulse_t = 0;  // tangential impulse within the episode [N s]
  double vn_before = 0, vt_before = 0;  // velocities at the start of the episode [m/s]
  double energy_before_J = 0;           // energy minus drive work at the start of the episode [J]
  double last_contact_end_s = -1;       // end of the previous episode [s]
  double warm_x_m = -1;       // tooth pairs: material coordinate of the last closest point (the
                              // narrow phase's warm start while in contact; -1 none) [m]
  double warm_t_s = 0;        // the time it was found at [s]
  double warm_x_prev_m = -1;  // the closest point before it (-1 none) [m]
  double warm_t_prev_s = 0;   // and its time [s]
  int macro_index = -1;       // macro-collision counter of this pair
  int sub_index = -1;         // sub-collision index within the macro-collision
  double normal_force_N = 0;  // last force values (for ContactInfo) [N]
  double tangential_force_N = 0;
  double impulse_n_acc = 0;  // running sums of the impulses since reset [N s]
  double impulse_t_acc = 0;
  bool seen = false;  // touched by the broad phase in the current step
};

std::uint64_t pairKey(const PairId& p);

// Pair memory by pair key: open addressing over a dense array of entries. Lookups and inserts
// allocate nothing while the reserved capacity holds (reserve() at reset sizes it from the
// model); entries are never removed except by clear(). Iteration visits entries in insertion
// order, so it is deterministic.
class PairTable {
 public:
  using Entry = std::pair<std::uint64_t, PairMemory>;
  // Room for n entries without allocating.
  void reserve(size_t n);
  // The memory of a pair, default-constructed on first use.
  PairMemory& operator[](std::uint64_t key);
  // The memory of a pair if it has an entry, else nullptr (nothing is inserted).
  const PairMemory* find(std::uint64_t key) const;
  // Index of the entry of key in the dense array (inserting it if new).
  int indexOf(std::uint64_t key);
  Entry& entry(int index) { return entries_[index]; }
  void clear();
  size_t size() const { return entries_.size(); }
  std::vector<Entry>::iterator begin() { return entries_.begin(); }
  std::vector<Entry>::iterator end() { return entries_.end(); }

 private:
  void rehash(size_t n_slots);
  std::vector<Entry> entries_;  // dense, insertion order
  std::vector<int> slots_;      // hash table of indices into entries_ (-1 = empty), 2^k long
};

// A tooth's residual flexibility table at a drum speed outside the window of the one compiled
// into its ToothModel (see residualTableAt in contact.cc).
struct ResidualCache {
  double omega_radps = std::numeric_limits<double>::quiet_NaN();  // drum speed built at [rad/s]
  StationFlexibility table;  // residualFlexibility at that speed [m/N, 1/N, 1/(N m)]
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

struct AsyncState;  // the island-local scheduler (src/core/async/async.h)

}  // namespace internal

// Integrator scratch memory; grows to the largest sizes seen, then is reused.
struct Workspace {
  Workspace();
  ~Workspace();  // out of line (simulator.cc), where AsyncState is complete
  // The asynchronous island-local scheduler's state (integrator.islands); built on first use.
  std::unique_ptr<internal::AsyncState> async;
  std::vector<PairId> candidates;            // broad-phase survivors
  std::vector<internal::ContactGeom> geoms;  // narrow-phase results for candidates
  internal::PairTable memory;
  std::vector<int> sort_index;          // sweep-and-prune order of the kernels (kept across steps)
  std::vector<double> sort_xmin_m;      // their bounding circles' lower x, in that order [m]
  std::vector<int> grid_order;          // kernels by grid cell (kernel pairs; kept across steps)
  std::vector<std::int64_t> grid_key;   // their cells (row * 2^32 + column), in that order
  std::vector<std::int64_t> grid_cell;  // cell of each kernel, by kernel index
  std::vector<int> obstacle_order;      // bars and plates (not planes) by increasing xmin
  std::vector<double> obstacle_sorted_xmin_m;            // their xmin in that order [m]
  std::vector<double> obstacle_xmin_m, obstacle_xmax_m;  // x extent per obstacle [m]
  double obstacle_max_width_m = 0;   // largest xmax - xmin of a bar or plate [m]
  std::vector<int> obstacle_planes;  // planes (unbounded: tested against every kernel)
  std::vector<internal::ResidualCache> tooth_residual;  // per tooth (drum speed changed)
  std::vector<internal::SmallVec> tooth_phi_max;  // per tooth, max_s |phi_i(x_s)| [1/sqrt(kg)]
  std::vector<double> tooth_H_max;                // per tooth, max_s |H(x_s)|_F [1/(kg m)]
  std::vector<Vec2> stations_W;                   // deformed tooth centrelines, all teeth [m]
  std::vector<int> station_offset;                // first station of each tooth in stations_W
  std::vector<double> station_wc_m;               // foreshortening w_c at each station [m]
  MatX station_Hq;                                // H(x_s) q, one column per station [1/sqrt(kg)]
  VecX forces;                                    // generalised forces [N or sqrt(kg) m/s^2]
  VecX u_old, du;         // velocities before an impulse, accelerations [m/s or -, m/s^2 or 1/s^2]
  VecX guard_z, guard_u;  // last good state for the non-finite guard
  TimeSteppingScratch
      ts;  // the time-stepping integrator's state and scratch (integrator_scratch.h)
  std::vector<int> island_of_body, island_contacts, island_start, island_parent;
  MatX G_island;
  VecX b_island, lambda_island, y_island;
  std::vector<ContactRow> rows_island;
  std::vector<int> active;  // indices into geoms of contacts in the problem
  MatX G;                   // Delassus matrix of one island
  VecX b, lambda, y;
  VecX b_offset;  // restitution target e dg_N- folded into b [m/s]
  std::vector<ContactRow> rows;
  LcpWorkspace lcp;
  VecX scratch_phi, scratch_dphi, scratch_ddphi;
  MatX scratch_H;
  EventDrivenScratch ed;  // the event-driven integrator's state and scratch (integrator_scratch.h)
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

// --- kinematics ----------------------------------------------------------------------------
// Deformed centreline of every tooth at its stations, in world, for configuration z (with the
// stations' foreshortening and H q, which the narrow phase interpolates).
void updateStations(const Model& m, const VecX& z, double theta_rad, Workspace* ws);
// Sizes the station arrays for the model (updateStations does it too).
void layoutStations(const Model& m, Workspace* ws);
// The same for one tooth only; the arrays must be laid out.
void updateToothStations(const Model& m, const VecX& z, double theta_rad, int tooth, Workspace* ws);
// Kernel as a geometric ellipse.
Ellipse kernelEllipse(const Model& m, const VecX& z, int i);
// Largest speed of any point of kernel i at velocities u: centre speed plus spin times the long
// semi-axis [m/s].
inline double kernelSpeedBound(const Model& m, const VecX& u, int i) {
  const KernelModel& k = m.kernels[i];
  return u.segment<2>(k.dof_offset).norm() + std::abs(u[k.dof_offset + 2]) * k.semi_axis_a_m;
}

// Broad phase: pairs whose bounding shapes are within margin_m; fills ws->candidates, sorted.
// Requires updateStations for z first. Kernel pairs through a uniform grid, teeth against
// kernels by bisection in the kernels' x order, kernels against obstacles by bisection in the
// obstacles' x order; the kernels' orders are kept from the previous call and repaired by
// insertion sort (O(K) while kernels move little). The cost per call is O(K + candidates +
// pairs in neighbouring cells), not O(K^2) nor O(K x obstacles).
// With stations_theta_rad, the tooth stations are not required first: broadPhase lays them
// out and computes them (at that drum angle) only for the teeth that can have a candidate;
// the other teeth's stations are left stale.
void broadPhase(const Model& m, const VecX& z, double margin_m, Workspace* ws,
                const double* stations_theta_rad = nullptr);
// The same candidates by testing every pair (O(K^2 + K x obstacles)); the reference of the
// broad phase's tests.
void broadPhaseBruteForce(const Model& m, const VecX& z, double margin_m, Workspace* ws);
// Per-model set-up of the broad phase (obstacles' x order, a fresh kernel order); resetData
// calls it, and broadPhase when the obstacle count changed.
void prepareBroadPhase(const Model& m, Workspace* ws);

// Narrow phase for one pair: gap, normal, Jacobians, relative velocities, Hertz constant.
// Requires updateStations for z first. If a cheap lower bound of the gap exceeds far_m, only
// that bound is stored (g->far = true): enough for the sign of a separated pair's gap. The
// bound is that of the bounding circles (which pairs count as near, and are reported in
// Data::contacts, follows from it), or with tight_bound, for pairs of exact shapes (kernels,
// obstacles), the supporting-line gap along the line of centres, a far better bound for
// elongated kernels; tooth pairs always use the bounding circles (the polyline of stations only
// approximates the deformed tooth, and the margin covers the difference). Both integrators
// pass tight_bound for separated pairs, so kernel-kernel and kernel-obstacle pairs count as
// near (and are reported) when their supporting-line gap is within a quarter margin.
// warm_x_m (tooth pairs, optional): where >= 0 and far_m is infinite, the closest point's
// material coordinate of an earlier evaluation, from which the refinement on the deformed
// centreline starts instead of the polyline search (that search remains the fallback should
// the refinement not converge); receives the closest point found (left alone when far).
void evaluateContact(const Model& m, const VecX& z, const VecX& u, const Drive& drive,
                     const PairId& pair, Workspace* ws, ContactGeom* g,
                     double far_m = std::numeric_limits<double>::infinity(),
                     bool tight_bound = false, double* warm_x_m = nullptr);

// Velocity drift of a contact's rows, analytically: the time derivative of (dg_N/dt, dg_T/dt)
// along the motion z' = u with u frozen and the drum at its speed and acceleration, i.e.
// (d/dt W)^T u + d(wtilde)/dt for the normal (0) and tangential (1) rows, including the
// motion of the contact points over the surfaces. g must come from evaluateContact at
// (z, u, drive) (not far).
Vec2 contactVelocityDrift(const Model& m, const VecX& z, const VecX& u, const Drive& drive,
                          const ContactGeom& g, Workspace* ws);

// Adds w * scale to the generalised vector f for each side of the contact.
void addGeneralised(const Model& m, const ContactGeom& g, double fn, double ft, VecX* f);

// Generalised inverse mass per body: teeth use tooth_minv[k] if given (time stepping's
// iteration matrix inverse) or the identity (mass-normalised modes); kernels diag(1/m,1/m,1/J).
// out += Minv_body * v for the body's block.
void applyInverseMass(const Model& m, const std::vector<MatX>* tooth_minv, int body,
                      const SmallVec& v, double scale, VecX* out);

// The free accelerations a = Minv f of the whole system (mass-normalised tooth modes: the
// identity; a large-deflection tooth: its tooth_minv block; kernels diag(1/m, 1/m, 1/J)),
// computed as applyInverseMass on a zero vector would, so that the two agree bit for bit.
void freeAcceleration(const Model& m, const std::vector<MatX>* tooth_minv, const VecX& f, VecX* a);
// w1^T Minv_body w2 for two Jacobian rows of the same body (Minv as in applyInverseMass).
double weightedDot(const Model& m, const std::vector<MatX>* tooth_minv, int body,
                   const SmallVec& w1, const SmallVec& w2);

// Solves one frictional contact problem per island (bodies coupled through contacts) for the
// contacts ws->active (indices into ws->geoms), with ws->rows and ws->b (2 per active contact,
// [N, T]) already filled. Fills ws->lambda and ws->y (same layout). Returns false if any
// island's LCP failed (its lambda is then zero).
bool solveContactIslands(const Model& m, const std::vector<MatX>* tooth_minv, Workspace* ws);

// Compliant normal force (Hertz constant K with Hunt-Crossley damping), >= 0 [N]. For tooth
// contacts the residual flexibility r = g.residual_mpN is a spring in series: the Hertz law sees
// the indentation delta_e = delta - r F and its rate delta_e' = delta' / (1 + r dF_e/d delta_e)
// (the quasi-static split of the approach between the two springs, F_e = K delta_e^{3/2}):
//   F = K delta_e^{3/2} (1 + chi delta_e'),  solved for delta_e by a bracketed Newton iteration.
double compliantNormalForce(const ContactGeom& g, double K, double v_in_mps, double v_floor_mps);
// The same force before the no-adhesion clamp: negative where the damping would pull (the
// event function of a compliant contact's release) [N].
double compliantNormalForceSigned(const ContactGeom& g, double K, double v_in_mps,
                                  double v_floor_mps);
// Its time derivative [N/s] given the normal relative acceleration g_N'' [m/s^2] (implicit
// differentiation of the relation above).
double compliantNormalForceRate(const ContactGeom& g, double K, double v_in_mps, double v_floor_mps,
                                double acc_n_mps2);

// Smooth generalised forces without contacts: tooth damping, stiffness and drum-acceleration
// load; kernel gravity and pedicels.
void smoothForces(const Model& m, const Data& d, const VecX& z, const VecX& u, const Drive& drive,
                  VecX* f);
// Pedicel spring-damper force on kernel i (world, at its attachment point) [N] and that point.
Vec2 pedicelForce(const Model& m, const VecX& z, const VecX& u, int i, Vec2* p_WP);

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
