// Zero heap allocations per step after warm-up (issue 4): both integrators, with contact, the
// complementarity solver, event location and the broad phase on the path.
//
// The test replaces the global operator new / delete and, underneath them, malloc and its
// relatives (Eigen allocates with malloc, not new), so that every heap allocation of this
// process goes through one counting hook. The hook counts only inside a window opened around
// the steps under test; on a non-zero count the call stacks of the first allocations in the window
// are printed (addresses resolve with addr2line or gdb).
#include <execinfo.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <new>
#include <string>
#include <vector>

#include "../../src/core/async/async.h"
#include "sim_test_util.h"
#include "threshing_sim/core/constants.h"
#include "threshing_sim/core/feed.h"
#include "threshing_sim/core/simulator.h"
#include "threshing_sim/scene/scene_loader.h"

// glibc's own allocator entry points, which the replacements below forward to.
extern "C" {
void* __libc_malloc(size_t size);
void __libc_free(void* ptr);
void* __libc_calloc(size_t count, size_t size);
void* __libc_realloc(void* ptr, size_t size);
void* __libc_memalign(size_t alignment, size_t size);
}

namespace {

// Counting state: only allocations inside an open window are counted.
bool g_window_open = false;  // counting enabled [-]
long g_allocations = 0;      // allocations counted in the window [-]
// Call stacks of the first kMaxTraces counted allocations (return addresses).
constexpr int kMaxTraces = 12;
constexpr int kTraceDepth = 48;
void* g_trace[kMaxTraces][kTraceDepth];
int g_trace_depth[kMaxTraces];  // entries used in each [-]
int g_traces = 0;               // stacks stored [-]
bool g_in_hook = false;         // re-entrancy guard (backtrace may allocate on first use)

void countAllocation() {
  if (!g_window_open || g_in_hook) return;
  ++g_allocations;
  if (g_traces < kMaxTraces) {
    g_in_hook = true;
    g_trace_depth[g_traces] = backtrace(g_trace[g_traces], kTraceDepth);
    ++g_traces;
    g_in_hook = false;
  }
}

void* allocateOrThrow(size_t size) {
  countAllocation();
  void* p = __libc_malloc(size == 0 ? 1 : size);
  if (p == nullptr) throw std::bad_alloc();
  return p;
}

void* allocateAlignedOrThrow(size_t size, std::align_val_t alignment) {
  countAllocation();
  void* p = __libc_memalign(static_cast<size_t>(alignment), size == 0 ? 1 : size);
  if (p == nullptr) throw std::bad_alloc();
  return p;
}

}  // namespace

// --- the C allocator (glibc supports replacing it in the executable) ---------------------------
extern "C" {
void* malloc(size_t size) {
  countAllocation();
  return __libc_malloc(size);
}
void free(void* ptr) { __libc_free(ptr); }
void* calloc(size_t count, size_t size) {
  countAllocation();
  return __libc_calloc(count, size);
}
void* realloc(void* ptr, size_t size) {
  countAllocation();
  return __libc_realloc(ptr, size);
}
void* memalign(size_t alignment, size_t size) {
  countAllocation();
  return __libc_memalign(alignment, size);
}
void* aligned_alloc(size_t alignment, size_t size) {
  countAllocation();
  return __libc_memalign(alignment, size);
}
int posix_memalign(void** out, size_t alignment, size_t size) {
  countAllocation();
  *out = __libc_memalign(alignment, size);
  return *out != nullptr ? 0 : ENOMEM;
}
}

// --- the C++ allocator ---------------------------------------------------------------------------
void* operator new(size_t size) { return allocateOrThrow(size); }
void* operator new[](size_t size) { return allocateOrThrow(size); }
void* operator new(size_t size, const std::nothrow_t&) noexcept {
  countAllocation();
  return __libc_malloc(size == 0 ? 1 : size);
}
void* operator new[](size_t size, const std::nothrow_t&) noexcept {
  countAllocation();
  return __libc_malloc(size == 0 ? 1 : size);
}
void* operator new(size_t size, std::align_val_t a) { return allocateAlignedOrThrow(size, a); }
void* operator new[](size_t size, std::align_val_t a) { return allocateAlignedOrThrow(size, a); }
void operator delete(void* p) noexcept { __libc_free(p); }
void operator delete[](void* p) noexcept { __libc_free(p); }
void operator delete(void* p, size_t) noexcept { __libc_free(p); }
void operator delete[](void* p, size_t) noexcept { __libc_free(p); }
void operator delete(void* p, std::align_val_t) noexcept { __libc_free(p); }
void operator delete[](void* p, std::align_val_t) noexcept { __libc_free(p); }
void operator delete(void* p, size_t, std::align_val_t) noexcept { __libc_free(p); }
void operator delete[](void* p, size_t, std::align_val_t) noexcept { __libc_free(p); }

namespace threshing_sim {
namespace {

// Opens the counting window; closing it returns the count.
void openWindow() {
  g_allocations = 0;
  g_traces = 0;
  g_window_open = true;
}
long closeWindow() {
  g_window_open = false;
  return g_allocations;
}

// Prints the stacks of the first allocations in the last window (at most kMaxTraces).
void printFirstAllocation() {
  for (int a = 0; a < g_traces; ++a) {
    std::fprintf(stderr, "allocation %d of %ld in the window, call stack:\n", a + 1, g_allocations);
    backtrace_symbols_fd(g_trace[a], g_trace_depth[a], STDERR_FILENO);
  }
}

// The global scheme (integrator.islands: false): the island scheme allocates when an island
// forms (its sub-model and workspace), which this test does not cover.
Model loadConfig(const std::string& relative, std::vector<std::string> overrides) {
  overrides.push_back("integrator.islands=false");
  return loadScene(std::string(THRESHING_SIM_SOURCE_DIR) + "/" + relative, overrides);
}

// Warm-up is one pass over the very steps that are then measured: the scene runs
// warm_steps + measured_steps steps, is reset (resetData keeps the workspace and its capacity),
// runs warm_steps steps again, and the allocations of the following measured_steps steps are
// counted. The rerun is bit-identical, so every scratch buffer has already grown to the sizes
// those steps need; any allocation counted is one the stepping makes per step.
struct CountedWindow {
  Data d;                           // the state after the counted steps
  long allocations = 0;             // allocations in the counted steps [-]
  size_t events_before = 0;         // d.events' length when counting began [-]
  SchedulerStats scheduler_before;  // the island scheme's counters when counting began
};

void countAfterWarmUp(const Model& m, int warm_steps, int measured_steps, CountedWindow* w) {
  Data& d = w->d;
  resetData(m, &d);
  for (int i = 0; i < warm_steps + measured_steps; ++i) {
    EXPECT_NE(step(m, &d), StepStatus::kFailed) << "warm-up step " << i;
  }
  const double t_end = d.t_s;
  resetData(m, &d);
  for (int i = 0; i < warm_steps; ++i) step(m, &d);
  // Warm the backtrace machinery outside the window (its first call loads libgcc).
  void* probe[2];
  backtrace(probe, 2);
  w->events_before = d.events.size();
  w->scheduler_before = d.stats.scheduler;
  openWindow();
  int failed = 0;
  for (int i = 0; i < measured_steps; ++i) failed += step(m, &d) == StepStatus::kFailed ? 1 : 0;
  w->allocations = closeWindow();
  EXPECT_EQ(failed, 0);
  EXPECT_EQ(d.t_s, t_end) << "the measured pass must repeat the warm-up pass";
  if (w->allocations != 0) printFirstAllocation();
}

// The measured steps must include contact: at least min_events contact events (impacts and
// state transitions) fall in the window.
long allocationsAfterWarmUp(const Model& m, int warm_steps, int measured_steps, int min_events) {
  CountedWindow w;
  countAfterWarmUp(m, warm_steps, measured_steps, &w);
  EXPECT_GE(w.d.events.size() - w.events_before, static_cast<size_t>(min_events))
      << "window [" << warm_steps << ", " << warm_steps + measured_steps
      << ") steps ends at t = " << w.d.t_s << " s";
  return w.allocations;
}

// Default scene: one tooth strikes one kernel at about 0.25-0.35 ms; the windows below cover
// the contact (impact, stick/slip) and the free flight after it.
TEST(Allocations, DefaultSceneEventDriven) {
  const Model m = loadConfig("config/default_scene.yaml", {"integrator.type=event_driven"});
  EXPECT_EQ(allocationsAfterWarmUp(m, 20, 600, 2), 0);
}

TEST(Allocations, DefaultSceneTimeStepping) {
  const Model m = loadConfig("config/default_scene.yaml",
                             {"integrator.type=time_stepping", "integrator.dt=1e-6"});
  EXPECT_EQ(allocationsAfterWarmUp(m, 50, 1000, 2), 0);
}

// Persistent contact: the knead scene presses a kernel between the tooth and a bar.
// The soft tooth of this scene bends past the small-deflection range once; the one-time
// validity warning (RunStats::warnings) allocates its text, which is not a per-step cost, so
// the threshold is raised out of the way here.
TEST(Allocations, KneadEventDriven) {
  const Model m = loadConfig("config/scenes/knead.yaml",
                             {"integrator.type=event_driven", "deflection_validity=1"});
  EXPECT_EQ(allocationsAfterWarmUp(m, 20, 800, 2), 0);
}

// The same with the Lawson split of the tooth in contact (its 20 modes: the split engages).
TEST(Allocations, KneadEventDrivenModalSplit) {
  const Model m = loadConfig(
      "config/scenes/knead.yaml",
      {"integrator.type=event_driven", "integrator.modal_split=exact", "deflection_validity=1"});
  EXPECT_EQ(allocationsAfterWarmUp(m, 20, 800, 2), 0);
}

TEST(Allocations, KneadTimeStepping) {
  const Model m =
      loadConfig("config/scenes/knead.yaml",
                 {"integrator.type=time_stepping", "integrator.dt=1e-6", "deflection_validity=1"});
  EXPECT_EQ(allocationsAfterWarmUp(m, 50, 1500, 2), 0);
}

// A multi-kernel stream: six teeth, kernels on pedicels, a grate of bars.
TEST(Allocations, StreamEventDriven) {
  const Model m = loadConfig("config/scenes/stream.yaml", {"integrator.type=event_driven"});
  EXPECT_EQ(allocationsAfterWarmUp(m, 20, 600, 2), 0);
}

TEST(Allocations, StreamTimeStepping) {
  const Model m = loadConfig("config/scenes/stream.yaml",
                             {"integrator.type=time_stepping", "integrator.dt=1e-6"});
  EXPECT_EQ(allocationsAfterWarmUp(m, 50, 2000, 2), 0);
}

// The contact phase (integrator.contact_steps): its fixed steps through the strike and the
// knead's pressed contacts (its propagator matrices, friction rows and end values warmed).
TEST(Allocations, DefaultSceneContactPhase) {
  const Model m = loadConfig("config/default_scene.yaml", {"integrator.contact_steps=40"});
  EXPECT_EQ(allocationsAfterWarmUp(m, 20, 600, 2), 0);
}

TEST(Allocations, KneadContactPhase) {
  const Model m = loadConfig("config/scenes/knead.yaml",
                             {"integrator.contact_steps=40", "deflection_validity=1"});
  EXPECT_EQ(allocationsAfterWarmUp(m, 20, 1500, 2), 0);
}

// --- The island scheme: islands forming and splitting ------------------------------------------
// The same pattern with integrator.islands: true, one scheduling window per step: the measured
// windows must build, merge and dissolve islands, so that the calendar, the tooth sweeps, the
// island grid and neighbour search, formation and splitting all run, and so must every island's
// sub-system: building it (its sub-model and the reset of its state, in a system of the pool
// that holds islands of its shape) and the global integrator stepping it (advanceTo). Nothing
// is left out of the count: once a first pass has warmed every buffer and filled the pool of
// sub-systems, none of it may allocate.
Model loadIslandConfig(const std::string& relative, std::vector<std::string> overrides) {
  overrides.push_back("integrator.islands=true");
  return loadScene(std::string(THRESHING_SIM_SOURCE_DIR) + "/" + relative, overrides);
}

// The counted windows must build and dissolve islands; with kernel_pairs, kernels touch each
// other in them (kernel-kernel contact events).
void expectIslandsWithoutAllocation(const Model& m, int warm_steps, int measured_steps,
                                    bool kernel_pairs = true) {
  CountedWindow w;
  countAfterWarmUp(m, warm_steps, measured_steps, &w);
  const SchedulerStats& s = w.d.stats.scheduler;
  long pairs = 0;
  for (size_t e = w.events_before; e < w.d.events.size(); ++e)
    pairs += w.d.events[e].pair.kind == PairKind::kKernelKernel ? 1 : 0;
  EXPECT_EQ(w.allocations, 0);
  EXPECT_GT(s.islands_built - w.scheduler_before.islands_built, 0);
  EXPECT_GT(s.islands_dissolved - w.scheduler_before.islands_dissolved, 0);
  if (kernel_pairs) {
    EXPECT_GT(pairs, 0);
  }
}

// The stream: six teeth, kernels on pedicels struck one after another and knocked into each
// other, a grate of bars. The counted windows build and dissolve islands (of several shapes),
// and kernels touch each other in them.
TEST(Allocations, IslandsFormAndSplitEventDriven) {
  expectIslandsWithoutAllocation(
      loadIslandConfig("config/scenes/stream.yaml", {"integrator.type=event_driven"}), 5, 60);
}

TEST(Allocations, IslandsFormAndSplitContactPhase) {
  expectIslandsWithoutAllocation(
      loadIslandConfig("config/scenes/stream.yaml",
                       {"integrator.type=event_driven", "integrator.contact_steps=40"}),
      5, 60);
}

TEST(Allocations, IslandsFormAndSplitTimeStepping) {
  expectIslandsWithoutAllocation(
      loadIslandConfig("config/scenes/stream.yaml",
                       {"integrator.type=time_stepping", "integrator.dt=1e-6"}),
      5, 60);
}

// The default strike with the large-deflection rod (4 shape functions): the rod has no exact
// free motion, so it steps in an island of its own; the kernel joins it in the first windows
// (the rod's sweep is padded by 0.1 L more than a free modal tooth's), is struck, and leaves:
// the counted windows (100, past the strike) dissolve the joint island and build the rod's own
// again. Neither the rod's islands nor its integrators allocate.
void expectRodIslandsWithoutAllocation(const Model& m, int warm_steps, int measured_steps) {
  ASSERT_EQ(m.teeth[0].beam_model, ToothBeamModel::kLargeDeflection);
  expectIslandsWithoutAllocation(m, warm_steps, measured_steps, false);
}

TEST(Allocations, RodIslandsEventDriven) {
  expectRodIslandsWithoutAllocation(
      loadIslandConfig("config/default_scene.yaml",
                       {"integrator.type=event_driven", "teeth.0.model=large_deflection"}),
      2, 100);
}

TEST(Allocations, RodIslandsTimeStepping) {
  expectRodIslandsWithoutAllocation(
      loadIslandConfig("config/default_scene.yaml",
                       {"integrator.type=time_stepping", "integrator.dt=1e-6",
                        "teeth.0.model=large_deflection"}),
      2, 100);
}

// A drum speed change during contact: the drum is commanded from 800 to 1200 rpm at the start
// (2e4 rad/s^2: a 2.1 ms ramp through the strike at ~0.3 ms) and the steps up to 3 ms, past the
// ramp's end, are counted. The residual flexibility is interpolated in Omega^2 from the compiled
// table, and the free tooth's exact propagator at the target speed is built by setDrumTarget,
// at the command: the ramp and its end cost the steps no factorisation and no allocation.
long allocationsThroughRamp(const Model& m, double target_radps, double t_end_s, int warm_steps) {
  Data d;
  auto run = [&](bool count) {
    resetData(m, &d);
    setDrumTarget(m, &d, target_radps);
    for (int i = 0; i < warm_steps; ++i) step(m, &d);
    const size_t events_before = d.events.size();
    const double omega_before = d.omega_radps;
    void* probe[2];
    backtrace(probe, 2);
    if (count) openWindow();
    int failed = 0;
    while (d.t_s < t_end_s) failed += step(m, &d) == StepStatus::kFailed ? 1 : 0;
    const long n = count ? closeWindow() : 0;
    EXPECT_EQ(failed, 0);
    EXPECT_GE(d.events.size() - events_before, 2u) << "no contact in the window";
    EXPECT_LT(omega_before, 0.5 * (omega_before + target_radps)) << "ramp before the window";
    EXPECT_EQ(d.omega_radps, target_radps) << "the ramp must end in the window";
    return n;
  };
  run(false);  // warm-up: the very same steps
  const long count = run(true);
  if (count != 0) printFirstAllocation();
  return count;
}

TEST(Allocations, DrumRampEventDriven) {
  const Model m = loadConfig("config/default_scene.yaml",
                             {"integrator.type=event_driven", "drum.max_acceleration=2e4"});
  EXPECT_EQ(allocationsThroughRamp(m, 1200 * 2 * kPi / 60, 3e-3, 3), 0);
}

TEST(Allocations, DrumRampTimeStepping) {
  const Model m = loadConfig(
      "config/default_scene.yaml",
      {"integrator.type=time_stepping", "integrator.dt=1e-6", "drum.max_acceleration=2e4"});
  EXPECT_EQ(allocationsThroughRamp(m, 1200 * 2 * kPi / 60, 3e-3, 20), 0);
}

// A soft tooth (the polyurethane knead tooth) whose residual flexibility moves with the speed.
TEST(Allocations, DrumRampSoftToothEventDriven) {
  const Model m = loadConfig(
      "config/scenes/knead.yaml",
      {"integrator.type=event_driven", "drum.max_acceleration=2e4", "deflection_validity=1"});
  EXPECT_EQ(allocationsThroughRamp(m, 1200 * 2 * kPi / 60, 3e-3, 3), 0);
}

// The island scheme with idle pedicel kernels only (no island forms, so nothing builds one):
// three near their hanging equilibrium advance by the closed form, one swinging wide by its own
// clock; step() brings every kernel up to date each window.
Model idlePedicelModel(IntegratorType type) {
  Model m = testutil::bareModel(type);
  m.integrator.islands = true;
  m.integrator.tolerance = 1e-6;
  for (int i = 0; i < 4; ++i) {
    KernelModel k = testutil::makeKernel(5e-3, 1.3e-3, Vec2::Zero());
    k.pedicel.present = true;
    k.pedicel.p_WA_W = Vec2(0.05 * i, 0.0);
    k.pedicel.p_KP_K = Vec2(5e-3, 0.0);
    k.pedicel.stiffness_Npm = 1600.0;
    k.pedicel.damping_Nspm = 0.002;
    k.pedicel.rest_length_m = 3e-3;
    k.inertia_kgm2 = k.mass_kg * (5e-3 * 5e-3 + 1.3e-3 * 1.3e-3) / 4.0;
    const internal::PedicelPropagator p = internal::buildPedicelPropagator(k, m.gravity_mps2);
    k.initial_position_m = k.pedicel.p_WA_W + p.p_AC_W + Vec2(i == 3 ? 3e-3 : 0.0, -1e-7 * i);
    k.initial_angle_rad = p.psi_eq_rad;
    m.kernels.push_back(k);
  }
  compileModel(&m);
  return m;
}

TEST(Allocations, IdlePedicelKernelsIslandScheme) {
  for (IntegratorType type : {IntegratorType::kEventDriven, IntegratorType::kTimeStepping}) {
    const Model m = idlePedicelModel(type);
    EXPECT_EQ(allocationsAfterWarmUp(m, 5, 50, 0), 0);
    Data d;
    resetData(m, &d);
    for (int i = 0; i < 20; ++i) ASSERT_NE(step(m, &d), StepStatus::kFailed);
    EXPECT_GT(d.ws->async->pedicel_closed_forms, 0);  // the closed form was exercised
    EXPECT_GT(d.stats.scheduler.pedicel_steps, 0);    // and so was the numerical clock
  }
}

}  // namespace
}  // namespace threshing_sim

// A continuous feed (core/feed.h, config/scenes/feed.yaml): kernels placed into pool slots and
// retired at the feed updates between steps, with the same warm-up-then-repeat rule as
// countAfterWarmUp (the Model is restored from its load-time copy before each pass).
namespace threshing_sim {
namespace {

// warm_steps + measured_steps steps from the start, each followed by a feed update; counts the
// allocations of the last measured_steps when count is true.
long feedPass(const Model& loaded, const FeedSpec& spec, int warm_steps, int measured_steps,
              bool count, Model* m, Data* d, FeedState* s) {
  *m = loaded;
  resetData(*m, d);
  startFeed(spec, *m, d, s);
  EXPECT_TRUE(updateFeed(spec, m, d, s));
  for (int i = 0; i < warm_steps + measured_steps; ++i) {
    if (count && i == warm_steps) openWindow();
    EXPECT_NE(step(*m, d), StepStatus::kFailed);
    EXPECT_TRUE(updateFeed(spec, m, d, s)) << s->error;
    s->retired.clear();
    d->events.clear();
  }
  return count ? closeWindow() : 0;
}

TEST(Allocations, FeedEventDriven) {
  FeedSpec spec;
  const Model loaded = loadScene(std::string(THRESHING_SIM_SOURCE_DIR) + "/config/scenes/feed.yaml",
                                 {}, nullptr, &spec);
  ASSERT_GT(spec.capacity, 0);
  Model m;
  Data d;
  FeedState s;
  void* probe[2];
  backtrace(probe, 2);
  feedPass(loaded, spec, 2000, 3000, false, &m, &d, &s);
  const long fed = s.counts.fed, left = s.counts.fed - s.counts.in_drum;
  const long allocations = feedPass(loaded, spec, 2000, 3000, true, &m, &d, &s);
  if (allocations != 0) printFirstAllocation();
  EXPECT_EQ(allocations, 0);
  EXPECT_EQ(s.counts.fed, fed);
  EXPECT_GT(fed, 10);  // kernels placed and retired in the window
  EXPECT_GT(left, 5);
}

}  // namespace
}  // namespace threshing_sim
