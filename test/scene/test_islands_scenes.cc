// The island-local scheme (integrator.islands: true) against the global one on every scene
// of config/ (hard cases, bench scenes, threshing scenes, the default scene), under both
// integrators.
//   - Scenes that are not chaotic: the same impacts in the same order (pair and kind), and
//     peak forces and kernel exit velocities within the global scheme's own error estimate
//     (its change when the knob is refined: tolerance / 100, or dt / 2).
//   - Chaotic scenes (the long run, whose landed kernels bounce on the floor): the per-kernel
//     outcomes a designer reads (tooth strikes, peak tooth forces, detachment) within the
//     spread the global scheme itself shows between tolerances 1e-6 and 1e-8.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "threshing_sim/core/simulator.h"
#include "threshing_sim/scene/scene_loader.h"

namespace threshing_sim {
namespace {

struct SceneRun {
  Model m;
  Data d;
  StepStatus status = StepStatus::kOk;
};

// A scene file (path below config/) with overrides, run to its duration (capped).
SceneRun runScene(const std::string& file, std::vector<std::string> overrides) {
  SceneRun r;
  r.m = loadScene(std::string(THRESHING_SIM_SOURCE_DIR) + "/config/" + file, overrides);
  resetData(r.m, &r.d);
  r.status = advanceTo(r.m, &r.d, r.m.duration_s);
  return r;
}

struct Case {
  const char* file;
  const char* duration;  // override ("" = the scene's)
};

// Every full scene file of config/ (override files such as config/scenes/teeth/ excluded).
const Case kCases[] = {
    {"hard/01_zeno.yaml", ""},
    {"hard/02_grazing.yaml", ""},
    {"hard/03_stick_slip.yaml", ""},
    {"hard/04_simultaneous.yaml", ""},
    {"hard/05_painleve.yaml", ""},
    {"hard/06_stiff_tooth.yaml", ""},
    {"hard/07_soft_tooth.yaml", ""},
    {"hard/08_wedged.yaml", ""},
    {"hard/09_drum_command.yaml", ""},
    {"bench/single_strike.yaml", ""},
    {"bench/single_strike_rigid.yaml", ""},
    {"bench/knead_polyurethane.yaml", ""},
    {"bench/stream.yaml", ""},
    {"default_scene.yaml", ""},
    {"scenes/single_strike.yaml", ""},
    {"scenes/knead.yaml", ""},
    {"scenes/stream.yaml", "0.004"},
};

std::vector<std::string> settings(const Case& c, const char* integrator, bool islands,
                                  const std::string& knob = "") {
  std::vector<std::string> o = {std::string("integrator.type=") + integrator,
                                std::string("integrator.islands=") + (islands ? "true" : "false")};
  if (*c.duration) o.push_back(std::string("duration=") + c.duration);
  if (!knob.empty()) o.push_back(knob);
  return o;
}

// The quantities compared: peak forces, then every kernel's final velocity (x, y, spin).
std::vector<double> outputs(const SceneRun& r) {
  std::vector<double> out = {r.d.stats.peak_normal_force_N, r.d.stats.peak_tangential_force_N};
  for (const KernelModel& k : r.m.kernels)
    for (int j = 0; j < 3; ++j) out.push_back(r.d.u[k.dof_offset + j]);
  return out;
}

// The refined knob of the global scheme's error estimate.
std::string refined(const SceneRun& g) {
  char text[64];
  if (g.m.integrator.type == IntegratorType::kEventDriven) {
    std::snprintf(text, sizeof(text), "integrator.tolerance=%.17g", g.m.integrator.tolerance / 100);
  } else {
    std::snprintf(text, sizeof(text), "integrator.dt=%.17g", g.m.integrator.dt_s / 2);
  }
  return text;
}

class IslandScenes : public ::testing::TestWithParam<const char*> {};

TEST_P(IslandScenes, SameImpactsAndOutputsWithinTheErrorEstimate) {
  for (const Case& c : kCases) {
    SCOPED_TRACE(std::string(c.file) + ", " + GetParam());
    const SceneRun g = runScene(c.file, settings(c, GetParam(), false));
    const SceneRun a = runScene(c.file, settings(c, GetParam(), true));
    const SceneRun f = runScene(c.file, settings(c, GetParam(), false, refined(g)));
    ASSERT_NE(g.status, StepStatus::kFailed);
    ASSERT_NE(a.status, StepStatus::kFailed);
    ASSERT_NE(f.status, StepStatus::kFailed);
    EXPECT_EQ(a.d.stats.impacts, g.d.stats.impacts);
    // The impacts in the same order.
    std::vector<PairId> ga, aa;
    for (const ContactEvent& e : g.d.events)
      if (e.is_impact || e.to == ContactState::kImpact) ga.push_back(e.pair);
    for (const ContactEvent& e : a.d.events)
      if (e.is_impact || e.to == ContactState::kImpact) aa.push_back(e.pair);
    EXPECT_TRUE(ga == aa) << ga.size() << " against " << aa.size() << " impact events";
    const std::vector<double> og = outputs(g), oa = outputs(a), of = outputs(f);
    for (size_t q = 0; q < og.size(); ++q) {
      // The error estimate (knob refined), or for the event-driven integrator ten times its
      // tolerance relative to the value, whichever is larger.
      const double estimate = std::abs(og[q] - of[q]);
      const double tol = g.m.integrator.type == IntegratorType::kEventDriven
                             ? 10.0 * g.m.integrator.tolerance * std::abs(og[q])
                             : 0.0;
      const double floor = 1e-9 * (std::abs(og[q]) + 1e-3);
      EXPECT_LE(std::abs(oa[q] - og[q]), std::max({3.0 * estimate, tol, floor}))
          << "output " << q << ": global " << og[q] << ", islands " << oa[q] << ", refined "
          << of[q];
    }
  }
}

// Per-kernel outcomes of a chaotic scene: tooth strikes, peak tooth force, detachment.
struct Outcomes {
  std::vector<double> peak_tooth_force_N;
  std::vector<long> strikes;
  std::vector<int> detached;
};

Outcomes outcomesOf(const SceneRun& r) {
  Outcomes o;
  const size_t K = r.m.kernels.size();
  o.peak_tooth_force_N.resize(K);
  o.strikes.assign(K, 0);
  o.detached.resize(K);
  for (size_t i = 0; i < K; ++i) {
    o.peak_tooth_force_N[i] = r.d.stats.kernel_tooth_peaks[i].normal_force_N;
    o.detached[i] = r.d.stats.kernel_detach_time_s[i] >= 0 ? 1 : 0;
  }
  for (const ContactEvent& e : r.d.events)
    if (e.is_impact && e.pair.kind == PairKind::kToothKernel) ++o.strikes[e.pair.b];
  return o;
}

// Per kernel, the island scheme's outcomes lie within the range the global scheme gives over
// tolerances 1e-6, 1e-7 and 1e-8: tooth strikes within that range (one more or fewer allowed,
// counts being integers), detachment as one of those runs has it, peak tooth force within the
// range widened by 5 %.
void expectWithinGlobalSpread(const Case& c) {
  std::vector<Outcomes> g;
  for (const char* tol : {"1e-6", "1e-7", "1e-8"})
    g.push_back(outcomesOf(runScene(
        c.file, settings(c, "event_driven", false, std::string("integrator.tolerance=") + tol))));
  const Outcomes a =
      outcomesOf(runScene(c.file, settings(c, "event_driven", true, "integrator.tolerance=1e-6")));
  for (size_t i = 0; i < a.strikes.size(); ++i) {
    SCOPED_TRACE(std::string(c.file) + ", kernel " + std::to_string(i));
    double f_lo = 1e300, f_hi = 0;
    bool detach_seen = false;
    for (const Outcomes& o : g) {
      f_lo = std::min(f_lo, o.peak_tooth_force_N[i]);
      f_hi = std::max(f_hi, o.peak_tooth_force_N[i]);
      detach_seen |= o.detached[i] == a.detached[i];
    }
    long g_lo = g[0].strikes[i], g_hi = g[0].strikes[i];
    for (const Outcomes& o : g)
      g_lo = std::min(g_lo, o.strikes[i]), g_hi = std::max(g_hi, o.strikes[i]);
    EXPECT_GE(a.strikes[i], g_lo - 1);
    EXPECT_LE(a.strikes[i], g_hi + 1);
    EXPECT_GE(a.peak_tooth_force_N[i], 0.95 * f_lo);
    EXPECT_LE(a.peak_tooth_force_N[i], 1.05 * f_hi);
    EXPECT_TRUE(detach_seen);
  }
}

TEST(IslandScenesChaotic, LongRunOutcomesWithinTheGlobalSchemesSpread) {
  expectWithinGlobalSpread({"hard/10_long_run.yaml", "0.2"});
}

TEST(IslandScenesChaotic, StreamOutcomesWithinTheGlobalSchemesSpread) {
  expectWithinGlobalSpread({"scenes/stream.yaml", "0.004"});
}

INSTANTIATE_TEST_SUITE_P(BothIntegrators, IslandScenes,
                         ::testing::Values("event_driven", "time_stepping"),
                         [](const ::testing::TestParamInfo<const char*>& info) {
                           return std::string(info.param) == "event_driven"
                                      ? std::string("EventDriven")
                                      : std::string("TimeStepping");
                         });

}  // namespace
}  // namespace threshing_sim
