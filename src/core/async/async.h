// threshing_sim core, asynchronous island-local scheduler: the private header of the stages in
// src/core/async/ (not installed; only the files of that folder and simulator.cc include it).
//
// Cost follows the events (see docs/architecture.md):
//   - every kernel keeps its own clock (KernelClock::t_s). A kernel that touches nothing is
//     "lazy": a free kernel flies its parabola in closed form, a kernel on its pedicel is
//     advanced by its own small adaptive integrator, and neither is touched until something can
//     reach it or the caller needs its state;
//   - a lazy kernel holds a bound circle that contains it until its wake time; the wake times
//     form the event calendar (a binary heap), and the circles sit in a uniform grid;
//   - bodies that can touch within a window form an island, integrated by the global
//     integrator (event-driven or time stepping) on a sub-system of just those bodies, with its
//     own clock, steps, events and contact problems; an event in one island never re-steps
//     another;
//   - the drum's motion is known in advance, so the sector a tooth sweeps over a window is
//     known: kernels whose bound circles it meets are woken into the tooth's island.
// Windows (short intervals, at most a broad-phase margin of tooth travel) order the islands'
// merges and splits: islands and teeth meet at window ends, lazy kernels do not.
#pragma once

#include <memory>
#include <type_traits>
#include <utility>
#include <vector>

#include "../internal.h"
#include "pedicel_propagator.h"
#include "threshing_sim/core/step_observer.h"

namespace threshing_sim {
namespace internal {

// An allocator whose construction without a value leaves a trivial element uninitialised: a
// vector resized only to be written whole at once (the grid's table and the calendar at set-up)
// is written once, not zeroed first.
template <typename T>
struct UninitAllocator : std::allocator<T> {
  template <typename U>
  struct rebind {
    using other = UninitAllocator<U>;
  };
  UninitAllocator() = default;
  template <typename U>
  UninitAllocator(const UninitAllocator<U>&) noexcept {}  // NOLINT: a converting allocator
  template <typename U>
  void construct(U* p) noexcept(std::is_nothrow_default_constructible<U>::value) {
    ::new (static_cast<void*>(p)) U;
  }
  template <typename U, typename... Args>
  void construct(U* p, Args&&... args) {
    ::new (static_cast<void*>(p)) U(std::forward<Args>(args)...);
  }
};
template <typename T>
using UninitVector = std::vector<T, UninitAllocator<T>>;

// Key of an empty slot of the grid's table.
constexpr std::int64_t kEmptyCellKey = std::numeric_limits<std::int64_t>::min();

// How a kernel moves while it touches nothing.
enum class KernelMotion : std::uint8_t {
  kFree = 0,     // no pedicel (or broken): parabola under gravity, constant spin, closed form
  kPedicel = 1,  // on its pedicel: the closed form about its hanging equilibrium where that is
                 // within tolerance, else its own adaptive Dormand-Prince clock over its 3 dofs
  kIsland = 2,   // member of an island: integrated with the island's bodies
};

// How a kernel in the grid (KernelClock::in_grid) sits in it. A cell's list holds the kernels
// listed since set-up first (each at the head when listed), then those listed at set-up and
// never removed since, by descending index (set-up listed in index order, each at the head).
enum class GridListing : std::uint8_t {
  kSince = 0,     // in its cell's list, listed after set-up (or not in the grid)
  kAtSetUp = 1,   // in its cell's list since set-up
  kUnlisted = 2,  // asleep since set-up and not in a cell's list yet: the sleeping field (see
                  // AsyncState::field_unlisted); its place is in the set-up part of its cell
};

// Per-kernel clock and calendar entry (the doubles first, then the small fields: 128 bytes).
struct KernelClock {
  Vec2 bound_c_W = Vec2::Zero();  // bound circle centre, world [m]
  double t_s = 0;                 // time the kernel's entries of Data::z, u refer to [s]
  double wake_s = 0;              // the kernel stays inside its bound circle until then [s]
  double bound_r_m = 0;           // bound circle radius [m]
  double speed_bound_mps = 0;     // speed bound of its points until wake_s [m/s]
  double h_s = 0;                 // pedicel clock: next step proposal [s]
  std::int64_t cell = 0;          // grid cell of bound_c_W while listed
  // At rest on its pedicel (atRest held at its prediction over the longest horizon) until
  // then: its clock jumps without another check; cleared when it leaves the calendar [s].
  double rest_until_s = -std::numeric_limits<double>::infinity();
  // Cached a-axis of the kernel at angle axis_psi_rad (see orientedKernel): the bounds need
  // cos psi and sin psi, which change only when the kernel's angle does.
  mutable double axis_psi_rad = std::numeric_limits<double>::quiet_NaN();  // [rad]
  mutable Vec2 axis_W = Vec2::UnitX();  // (cos, sin) of axis_psi_rad, world [-]
  int island = -1;                      // island slot while motion == kIsland
  int heap_pos = -1;                    // position in the calendar heap; -1 = not in it
  int cell_next = -1, cell_prev = -1;   // neighbours in the cell's list (-1 = none)
  // Its closed form in AsyncState::pedicel_classes; -1 none, -2 not looked up yet [-].
  int pedicel_class = -2;
  KernelMotion motion = KernelMotion::kFree;
  bool in_grid = false;                       // listed in the grid
  GridListing listing = GridListing::kSince;  // where in the grid, while in_grid
};

// An ellipse with its a-axis as a unit vector: the bounds below need no trigonometry.
struct OrientedEllipse {
  Vec2 center_W = Vec2::Zero();  // centre, world [m]
  Vec2 axis_W = Vec2::UnitX();   // unit a-axis (cos psi, sin psi), world [-]
  double a_m = 0;                // semi-major [m]
  double b_m = 0;                // semi-minor [m]
};

// The sub-system of an island: a Model of its bodies (plus every obstacle) and its Data. Kept
// in a pool (AsyncState::systems) and reused by the islands of its shape, the same teeth and as
// many kernels, so that its state and integrator workspace already have the sizes such an
// island needs: once a run has formed the islands of every shape it meets, as many at once,
// building one allocates nothing.
struct IslandSystem {
  std::vector<int> teeth;  // global tooth indices, ascending (the shape, with n_kernels)
  int n_kernels = 0;       // kernels of the shape [-]
  bool in_use = false;     // held by a live island
  // The model whose teeth, obstacles and constants the sub-model holds (nullptr: none yet, or
  // maybe another model's: a set-up forgets it): a build for that model copies only the
  // kernels. The teeth's free-tooth propagators are kept while the teeth stay alike.
  const Model* teeth_of = nullptr;
  Model model;  // the sub-model (compiled per-body data copied from the full model)
  Data data;    // the sub-system's state, clock and integrator workspace
  std::vector<ToothPropagator> kept_prop;  // the teeth's propagators across a reset of data
};

// One island: a sub-system of teeth and kernels (plus every obstacle) integrated together.
struct Island {
  bool alive = false;
  std::vector<int> teeth;       // global tooth indices, ascending (local order)
  std::vector<int> kernels;     // global kernel indices, ascending (local order)
  IslandSystem* sys = nullptr;  // its sub-system (one of AsyncState::systems) while alive
  Model& model() { return sys->model; }
  const Model& model() const { return sys->model; }
  Data& data() { return sys->data; }
  const Data& data() const { return sys->data; }
  // Additive statistics of data().stats already merged into the global statistics.
  long merged_impacts = 0, merged_episodes = 0, merged_recoveries = 0, merged_rejected = 0,
       merged_depth_corrections = 0, merged_steps = 0;
  double merged_impulse_Ns = 0, merged_drive_work_J = 0;  // [N s], [J]
  std::vector<long> merged_kernel_impacts;                // per local kernel
  size_t merged_warnings = 0;                             // warnings already copied
};

// Per tooth, what its deflection bound needs at one drum speed (rebuilt when the speed changes).
struct ToothBound {
  double omega_radps = std::numeric_limits<double>::quiet_NaN();  // built at [rad/s]
  MatX S;             // Lambda + Omega^2 (K_G - I) [1/s^2]
  double worst = -1;  // largest phi^T S^-1 phi over the stations [m^2 s^2/kg]; < 0 = none
};

// Reports an island's accepted steps to Data::observer in global numbers (island.cc): set as the
// island's StepHook while its window is observed.
struct AsyncState;
class IslandStepHook : public StepHook {
 public:
  void afterStep(const Data& island_data) const override;
  const Model* model = nullptr;      // the full model
  StepObserver* observer = nullptr;  // the caller's (Data::observer)
  AsyncState* as = nullptr;          // the scheduler (its island slots, its buffers)
  int island = -1;                   // the observed island's slot
  double t_window_end_s = 0;         // the window's end: reported times stop there [s]
};

// The scheduler's whole state (lives in Workspace::async).
struct AsyncState {
  bool ready = false;                // set up for the current model and reset
  std::vector<KernelClock> kernels;  // per kernel
  std::vector<int> tooth_island;     // per tooth: island slot, -1 = free (closed form)
  std::vector<Island> islands;       // island slots (dead ones are reused)
  // Sub-systems of islands, by shape (see IslandSystem): kept while the state lives.
  std::vector<std::unique_ptr<IslandSystem>> systems;
  PairTable stored_memory;  // pair memory (global keys) of pairs outside islands
  UninitVector<int> heap;   // calendar: kernels by wake time (binary min-heap)
  // Uniform grid of lazy kernels' bound circles: open-addressing table cell -> first kernel.
  double cell_m = 0;                            // cell size [m]
  double r_cap_m = 0;                           // largest bound radius a lazy kernel is given [m]
  double r_listed_m = 0;                        // radii listed since set-up are at most this [m]
  double max_horizon_s = 1.0;                   // longest horizon of a prediction [s]
  UninitVector<std::int64_t> cell_key;          // table keys (kEmptyCell = empty)
  UninitVector<int> cell_head;                  // first kernel of the cell, -1 = none
  size_t cells_used = 0;                        // keys in the table
  std::vector<ToothPropagator> prop;            // free teeth at constant drum speed
  mutable std::vector<ToothBound> tooth_bound;  // per tooth: its deflection bound's data

  // The sleeping field: the kernels listed asleep at set-up, while their cells are not written
  // (GridListing::kUnlisted; in_grid, in the calendar). Their clocks are the field's one clock
  // (field_t_s: a sync jumps it, not theirs). They are written into their cells' lists where
  // set-up would have put them, their clocks set to the field's (listField), before a query
  // whose cells may hold one of their centres (the field's ring), before one of them leaves the
  // grid and before the table could need rebuilding; a tooth's sweep whose annulus misses the
  // ring passes them over (each would be dropped by its circle). All or none are unlisted.
  int field_unlisted = 0;                         // its kernels not in a cell's list yet [-]
  double field_t_s = 0;                           // their clocks' time [s]
  double field_rho_lo_m = 0, field_rho_hi_m = 0;  // least and largest |centre| among them [m]

  // Per-window scratch (grow-only).
  std::vector<int> uf_parent;              // union-find over entity slots of this window
  std::vector<int> entities;               // entity ids: tooth k -> k, kernel i -> T + i
  std::vector<int> entity_slot;            // per entity id: slot in entities, or -1
  std::vector<std::pair<int, int>> joins;  // entity pairs that must share an island
  std::vector<int> found;                  // grid query results
  std::vector<int> found_copy;             // a query's results while the grid changes
  // Grid of island kernels over this window (same cells as the lazy grid; rebuilt per window):
  // (cell key of the kernel's centre, kernel), ascending.
  std::vector<std::pair<std::int64_t, int>> island_cells;
  double island_r_max_m = 0;  // largest listed circle (semi-axis a plus reach) this window [m]
  std::vector<int> comp_teeth, comp_kernels;     // one component's bodies
  std::vector<std::pair<int, int>> split_edges;  // an island's proximity graph (local numbers)
  std::vector<std::uint8_t> split_pinned;        // its bodies that must stay integrated
  std::vector<int> split_parent;                 // union-find over its bodies
  std::vector<int> split_teeth, split_kernels;   // the dissolved island's bodies (global)
  std::vector<ContactEvent> window_events;       // events of this window, before time ordering
  // Observed windows only (Data::observer): the hook and the island's contacts and events of
  // the step being reported, in global numbers.
  IslandStepHook observe_hook;
  std::vector<ContactInfo> observed_contacts;
  std::vector<ContactEvent> observed_events;
  SchedulerStats counters;  // work by kind (copied to RunStats::scheduler)
  // The work budget of the running call (advanceTo, advancePast, step, syncBodies; kBaseWork in
  // internal.h): windows, islands' steps and trial steps and lone kernels' own-clock steps.
  long work_used = 0;        // units the call has used [-]
  double work_allowed = 0;   // units it may use: its interval's and its lone clocks' spans' [-]
  double work_target_s = 0;  // the call's target time, reported with a failure [s]

  // Closed forms of idle pedicel kernels, per class, built on first need and kept across resets
  // (a class is its parameters: a new model finds its own).
  std::vector<PedicelPropagator> pedicel_classes;
  // Closed-form advances of pedicel kernels since the scheduler was created [-].
  long pedicel_closed_forms = 0;
  // Lazy kernels the teeth's sweeps looked at one by one since set-up (a grid cell wholly out of
  // a tooth's reach is skipped without them): a field out of reach costs nothing per window [-].
  long swept_kernels = 0;
  // The lazy kernels a sync (syncBodies, advanceTo, advancePast) brought to the caller's time, as
  // they were before it: put back before the next window (restoreSynced), so that a sync only
  // observes. Otherwise each sync would restart a kernel's closed form or cut its pedicel clock's
  // step at the caller's time, and the run would depend on when its caller looks (the node and
  // `simulate` look at different times).
  struct SyncedKernel {
    int kernel = -1;                 // kernel index
    KernelClock clock;               // its clock before the sync
    Eigen::Matrix<double, 6, 1> zu;  // its z (3) and u (3) before the sync
    std::uint8_t attached = 1;       // Data::kernel_attached before the sync
    double detach_s = -1;            // RunStats::kernel_detach_time_s before the sync [s]
  };
  std::vector<SyncedKernel> synced;
  bool field_synced = false;       // the last sync jumped the sleeping field's clock [-]
  double field_synced_from_s = 0;  // and field_t_s before it did [s]
};

constexpr std::int64_t kEmptyCell = kEmptyCellKey;

// --- async_step.cc: the call's work budget ---------------------------------------------------
// A call over span_s [s] to t_target_s [s] may use kBaseWork + kWorkPerSecond x span_s units.
void beginWork(AsyncState* as, double span_s, double t_target_s);
// Spends units of the call's budget; false once it is exceeded.
inline bool spendWork(AsyncState* as, long units) {
  as->work_used += units;
  return static_cast<double>(as->work_used) <= as->work_allowed;
}
// Records in d->stats.failure a failure of the call with cause, at the data's time, naming the
// part of the scheme (scope: a static string) and the call's work and budget.
void recordFailure(Data* d, const AsyncState& as, FailureCause cause, const char* scope);

// --- body_motion.cc: closed-form and own-clock motion of lone bodies -----------------------
// Brings lazy kernel i to time t_s (free: closed form; pedicel: the closed form about its
// hanging equilibrium within its validity, else its own integrator, which may break the pedicel
// and then continue in free flight). Returns false on a numerical failure or when its steps
// exceed the call's work budget (spent step by step; the clock's span adds kWorkPerSecond per
// second to it), with the cause recorded (recordFailure).
bool advanceLazyKernel(const Model& m, Data* d, AsyncState* as, int i, double t_s);
// Whether lazy kernel i, on its pedicel, is at rest over horizon_s (it moves by less than the
// error scale; see atRest in body_motion.cc).
bool lazyAtRest(const Model& m, const Data& d, int i, double horizon_s);
// The same with the cosine and sine of the kernel's angle given (the caller's: kernels of a
// field hanging at the same angle share one evaluation).
bool lazyAtRestAt(const Model& m, const Data& d, int i, double horizon_s, double cos_psi,
                  double sin_psi);
// Bound on the speed of any point of lazy kernel i over the next horizon_s [m/s].
double lazySpeedBound(const Model& m, const Data& d, const AsyncState& as, int i, double horizon_s);
// The parts of lazySpeedBound that do not depend on the horizon, computed once for a search
// over horizons (horizonFor): lazySpeedBoundAt(lazySpeedTerms(...), H) is lazySpeedBound(..., H)
// bit for bit.
struct LazySpeedTerms {
  bool pedicel = false;     // on its pedicel (else free flight)
  double g_mps2 = 0;        // |g| [m/s^2]
  double speed_mps = 0;     // free: centre speed |v| [m/s]
  double spin_mps = 0;      // free: |omega| a [m/s]
  double weight_N = 0;      // pedicel: m |g| [N]
  double kappa_pkg = 0;     // pedicel: 1/m + a^2/J [1/kg]
  double two_kappa_e0 = 0;  // pedicel: 2 kappa E0 [m^2/s^2]
  double v_long_mps = 0;    // pedicel: the bound from the stem's reach [m/s]
};
LazySpeedTerms lazySpeedTerms(const Model& m, const Data& d, const AsyncState& as, int i);
inline double lazySpeedBoundAt(const LazySpeedTerms& t, double horizon_s) {
  if (!t.pedicel) return t.speed_mps + t.g_mps2 * horizon_s + t.spin_mps;
  const double pull = t.weight_N * horizon_s * t.kappa_pkg;
  const double v_short = pull + std::sqrt(pull * pull + t.two_kappa_e0);
  return std::min(v_short, t.v_long_mps) + t.g_mps2 * horizon_s;
}
// Where lazy kernel i (on its pedicel, closed form valid from its state over horizon_s)
// stays until something reaches it: its ellipse now, grown by *growth_m [m], contains it at all
// later times. Returns false when the closed form does not hold. The kernel's class is built on
// its first need (allocates then).
bool pedicelEnvelope(const Model& m, const Data& d, AsyncState* as, int i, double horizon_s,
                     double* growth_m);
// Free tooth k over h_s at the data's (constant) drum speed: exact (as->prop[k] must be built).
void advanceFreeTooth(const Model& m, Data* d, AsyncState* as, int k, double h_s);
// Bound on |w| at the stations of tooth k while it moves freely at the data's drum speed [m]
// (a large-deflection rod: on its centreline's distance from its undeformed line).
double toothDeflectionBound(const Model& m, const Data& d, const AsyncState& as, int k);

// --- calendar.cc: the wake-time heap and the grid of bound circles ------------------------
// Cell coordinate floor(q) of q = x / cell (|q| < 2^62), as
// static_cast<std::int64_t>(std::floor(q)) without the library call.
inline std::int64_t cellFloor(double q) {
  const std::int64_t t = static_cast<std::int64_t>(q);
  return q < static_cast<double>(t) ? t - 1 : t;
}
// Table key of grid cell (cx, cy) (the lazy grid's and the island grid's cells): the row in the
// high 32 bits, the column in the low ones (in unsigned arithmetic: a negative row must not be
// shifted as a signed value).
inline std::int64_t gridCellKey(std::int64_t cx, std::int64_t cy) {
  return static_cast<std::int64_t>((static_cast<std::uint64_t>(cy) << 32) ^
                                   (static_cast<std::uint64_t>(cx) & 0xffffffffULL));
}
// Whether a kernel on its pedicel, with its state z (pose x, y, psi) and u (their rates) and the
// cosine and sine of psi given, is at rest over dt_s: lazyAtRestAt on the state arrays, with the
// arithmetic of pedicelRates and ratesAtRest (body_motion.cc) in the same order, so that it
// decides as they do bit for bit; inline, for set-up's loop over a whole field.
inline bool restsOnPedicel(const KernelModel& k, const Vec2& g, double tol, const double* z,
                           const double* u, double cos_psi, double sin_psi, double dt_s) {
  const PedicelModel& p = k.pedicel;
  const double rx = cos_psi * p.p_KP_K.x() - sin_psi * p.p_KP_K.y();
  const double ry = sin_psi * p.p_KP_K.x() + cos_psi * p.p_KP_K.y();
  const double dx = z[0] + rx - p.p_WA_W.x(), dy = z[1] + ry - p.p_WA_W.y();
  const double len = std::sqrt(dx * dx + dy * dy);
  double fx = 0.0, fy = 0.0, moment = 0.0;
  if (!(len <= 0.0)) {
    const double vx = u[0] + u[2] * -ry, vy = u[1] + u[2] * rx;
    const double ex = dx / len, ey = dy / len;
    const double tension =
        p.stiffness_Npm * (len - p.rest_length_m) + p.damping_Nspm * (ex * vx + ey * vy);
    fx = -tension * ex;
    fy = -tension * ey;
    moment = rx * fy - ry * fx;
  }
  const double ax = g.x() + fx / k.mass_kg, ay = g.y() + fy / k.mass_kg;
  const double alpha = moment / k.inertia_kgm2;
  const double a = k.semi_axis_a_m;
  const double v = std::sqrt(u[0] * u[0] + u[1] * u[1]) + a * std::abs(u[2]);
  const double acc = std::sqrt(ax * ax + ay * ay) + a * std::abs(alpha);
  return v * dt_s + 0.5 * acc * dt_s * dt_s <= tol * 1e-2 && acc * dt_s <= tol;
}

void heapPush(AsyncState* as, int i);
void heapRemove(AsyncState* as, int i);
int heapTop(const AsyncState& as);  // -1 if empty
void gridInsert(AsyncState* as, int i);
// Set-up's bulk listing, in index order (as->kernels rebuilt, the calendar emptied; the grid's
// cell size set from the largest semi-axis a, its table sized here for every kernel: no
// rebuild). A kernel at rest on its pedicel over the longest horizon is listed asleep at once, as
// predictKernel would list it (circle grown by the error scale, awake after that horizon), at the
// end of the calendar (all of them wake together: no sifting), in the sleeping field (its cell
// not written: AsyncState::field_unlisted). Any other gets a fresh clock, its motion and ungrown
// circle and is listed in its cell, at the head of the cell's list as gridInsert lists it.
// Kernels of a field share the cosine and sine of their angle with the kernel before. Returns
// the number of kernels not asleep (to be predicted).
int listKernelsAtSetUp(const Model& m, const Data& d, AsyncState* as);
void gridRemove(AsyncState* as, int i);
// Listed kernels whose circles may meet the box [lo, hi], into as->found (callers test exactly).
void gridQuery(AsyncState* as, const Vec2& lo, const Vec2& hi);
// The same, without the cells whose every circle (radius at most as->r_listed_m) lies beyond
// the annulus r_lo_m <= |p| <= r_hi_m about the drum axis (a whole cell out of a tooth's reach
// is skipped without looking at its kernels): as->found is gridQuery's list less kernels whose
// circles the annulus does not meet, in the same order. Counts the kernels it lists
// (AsyncState::swept_kernels).
void gridQueryAnnulus(AsyncState* as, const Vec2& lo, const Vec2& hi, double r_lo_m, double r_hi_m);
// Gives lazy kernel i (at time t_s) a new bound circle and wake time and lists it, or, when
// it cannot stay lazy past t_window_end_s, adds joins (with a neighbour, or itself alone).
// Its growth (bound radius minus a) is at most grow_cap_m. Returns true if it stays lazy.
bool predictKernel(const Model& m, const Data& d, AsyncState* as, int i, double t_s,
                   double t_window_end_s,
                   double grow_cap_m = std::numeric_limits<double>::infinity());
// Distance from point c to obstacle o's surface [m] (negative inside).
double obstacleClearance(const ObstacleModel& o, const Vec2& c);
// Supporting-line lower bound of the gap between two ellipses along their centres' line [m]:
// never above their signed distance; no trigonometry.
double ellipseGapBound(const OrientedEllipse& e1, const OrientedEllipse& e2);
// Whether two ellipses whose surfaces approach each other by at most reach_m [m] (over a
// window) may touch: bounding circles first, the ellipse bound only for pairs that pass.
bool pairMayTouch(const OrientedEllipse& e1, const OrientedEllipse& e2, double reach_m);
// Kernel i's ellipse at the pose z holds, with its axis from the cache in as (recomputed only
// when the angle changed since the last call).
OrientedEllipse orientedKernel(const Model& m, const VecX& z, const AsyncState& as, int i);

// --- wake.cc: what can touch what over a window --------------------------------------------
// Distance from p to the annular sector {rho e(phi): phi0 <= phi <= phi1, r_in <= rho <= r_out}.
double sectorDistance(const Vec2& p, double phi0, double phi1, double r_in, double r_out);
// The annular sector a tooth's centreline sweeps over a window, with its edges' directions.
struct SweptSector {
  double phi0_rad = 0, phi1_rad = 0;  // angular range, phi0 <= phi1 [rad]
  double r_in_m = 0, r_out_m = 0;     // radial range [m]
  Vec2 e0_W = Vec2::UnitX();          // unit radial direction at phi0, world [-]
  Vec2 e1_W = Vec2::UnitX();          // unit radial direction at phi1, world [-]
};
SweptSector sweptSector(double phi0_rad, double phi1_rad, double r_in_m, double r_out_m);
// Lower bound of the distance from ellipse e to the sector [m] (<= 0 where they may meet): the
// larger of the centre's distance less the semi-axis a and, for an ellipse beside the sweep,
// its separation from the lines of the sector's radial segments (a thin kernel lying along a
// radius is a semi-axis b, not a, from the tooth's path). No trigonometry per ellipse.
double sectorEllipseGapBound(const SweptSector& sec, const OrientedEllipse& e);
bool wakeDueKernels(const Model& m, Data* d, AsyncState* as, double t0, double t1);
void sweepTeeth(const Model& m, Data* d, AsyncState* as, double t0, double t1);
// Lists every island kernel in the island grid (circle: semi-axis a plus its window reach).
void listIslandKernels(const Model& m, const Data& d, AsyncState* as, double window_s);
// Island kernels of the island grid whose circles may meet the box [lo, hi], into as->found.
void islandGridQuery(AsyncState* as, const Vec2& lo, const Vec2& hi);
// Reach of island kernel i over a window: its speed bound times the window plus two margins
// (it may be struck mid-window) [m].
double islandReach(const Model& m, const Data& d, int i, double window_s);
// Bound on how far the surfaces of island kernels i and j approach each other over a window:
// their relative speed bound (centre velocity difference plus each spin times its semi-axis a)
// times the window plus each one's two margins [m].
double islandPairReach(const Model& m, const Data& d, int i, int j, double window_s);
void islandNeighbours(const Model& m, Data* d, AsyncState* as, double t0, double t1);
// The proximity graph of island s over the next window of length window_s, in local entity
// numbers (teeth 0..nT-1, kernels nT..): edges between bodies in contact or within reach;
// pinned: kernels in contact with or within reach of an obstacle.
void islandProximity(const Model& m, const Data& d, const AsyncState& as, int s, double window_s,
                     std::vector<std::pair<int, int>>* edges, std::vector<std::uint8_t>* pinned);

// --- island.cc: sub-systems -----------------------------------------------------------------
void buildIsland(const Model& m, Data* d, AsyncState* as, int s, const std::vector<int>& teeth,
                 const std::vector<int>& kernels);
void dissolveIsland(const Model& m, Data* d, AsyncState* as, int s);
void storeIslandState(const Model& m, Data* d, const AsyncState& as, int s);
void mergeIslandResults(const Model& m, Data* d, AsyncState* as, int s);
// Reports island s's steps up to t1 to d->observer (if set) during its next advance; stop with
// endIslandObservation.
void beginIslandObservation(const Model& m, Data* d, AsyncState* as, int s, double t1);
void endIslandObservation(AsyncState* as, int s);
bool islandInContact(AsyncState* as, int s);
void publishIslandContacts(const AsyncState& as, std::vector<ContactInfo>* out);

// --- async_step.cc ----------------------------------------------------------------------------
AsyncState& asyncState(const Model& m, Data* d);
StepStatus asyncWindow(const Model& m, Data* d, double t_end_s);

}  // namespace internal
}  // namespace threshing_sim
