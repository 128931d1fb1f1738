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
#include <cstdio>
#include <string>
#include <utility>
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
  const char* duration;    // override ("" = the scene's)
  const char* extra = "";  // one more override ("" = none)
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
    // The polyurethane knead without and with the static correction (with it, the island
    // scheme's peaks once ran about 1 us behind the global one: the peak locator's force rate
    // held the residual fixed; docs/architecture.md).
    {"bench/knead_polyurethane.yaml", "", "teeth.*.static_correction=off"},
    {"bench/knead_polyurethane.yaml", ""},
    {"bench/stream.yaml", ""},
    {"default_scene.yaml", ""},
    {"scenes/single_strike.yaml", ""},
    {"scenes/knead.yaml", ""},
};

std::vector<std::string> settings(const Case& c, const char* integrator, bool islands,
                                  const std::string& knob = "") {
  std::vector<std::string> o = {std::string("integrator.type=") + integrator,
                                std::string("integrator.islands=") + (islands ? "true" : "false")};
  if (*c.duration) o.push_back(std::string("duration=") + c.duration);
  if (*c.extra) o.push_back(c.extra);
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

// The impacts of a run, in order (pair and kind).
std::vector<PairId> impactsOf(const SceneRun& r) {
  std::vector<PairId> out;
  for (const ContactEvent& e : r.d.events)
    if (e.is_impact || e.to == ContactState::kImpact) out.push_back(e.pair);
  return out;
}

// The global scheme (g) and the island scheme (a), each also run with the knob refined (f,
// af): the same impacts in the same order, and every output within the two schemes' error
// estimates (knob refined) together: each takes its own steps, so at one knob either may be
// the more accurate; or for the event-driven integrator ten times its tolerance relative to
// the value, whichever is larger. Schemes that converged to different answers fail it: their
// refined runs then differ as much as they do. With a tag, each output is printed.
void expectSchemesAgree(const SceneRun& g, const SceneRun& a, const SceneRun& f, const SceneRun& af,
                        std::vector<double> (*outputs_of)(const SceneRun&),
                        const char* tag = nullptr) {
  for (const SceneRun* r : {&g, &a, &f, &af}) ASSERT_NE(r->status, StepStatus::kFailed);
  EXPECT_EQ(a.d.stats.impacts, g.d.stats.impacts);
  const std::vector<PairId> ga = impactsOf(g), aa = impactsOf(a);
  EXPECT_TRUE(ga == aa) << ga.size() << " against " << aa.size() << " impact events";
  const std::vector<double> og = outputs_of(g), oa = outputs_of(a), of = outputs_of(f),
                            oaf = outputs_of(af);
  for (size_t q = 0; q < og.size(); ++q) {
    const double estimate = std::abs(og[q] - of[q]) + std::abs(oa[q] - oaf[q]);
    const double tol = g.m.integrator.type == IntegratorType::kEventDriven
                           ? 10.0 * g.m.integrator.tolerance * std::abs(og[q])
                           : 0.0;
    const double floor = 1e-9 * (std::abs(og[q]) + 1e-3);
    const double bound = std::max({3.0 * estimate, tol, floor});
    if (tag != nullptr)
      std::printf("%s output %zu: global %.9g islands %.9g (rel %+.2e, bound %.2e)\n", tag, q,
                  og[q], oa[q], (oa[q] - og[q]) / (std::abs(og[q]) + 1e-300), bound);
    EXPECT_LE(std::abs(oa[q] - og[q]), bound)
        << "output " << q << ": global " << og[q] << ", islands " << oa[q] << ", refined " << of[q]
        << " and " << oaf[q];
  }
}

TEST_P(IslandScenes, SameImpactsAndOutputsWithinTheErrorEstimate) {
  for (const Case& c : kCases) {
    SCOPED_TRACE(std::string(c.file) + ", " + GetParam());
    const SceneRun g = runScene(c.file, settings(c, GetParam(), false));
    const SceneRun a = runScene(c.file, settings(c, GetParam(), true));
    const SceneRun f = runScene(c.file, settings(c, GetParam(), false, refined(g)));
    const SceneRun af = runScene(c.file, settings(c, GetParam(), true, refined(g)));
    expectSchemesAgree(g, a, f, af, outputs);
  }
}

// The scenes with a large-deflection rod (teeth.*.model: large_deflection, as
// config/scenes/cases/large_deflection.yaml sets it): the island scheme refused them; it
// integrates a rod in an island of its own. The rod scenes of scripts/compare_teeth.py (the
// knead with the nylon and the polyurethane tooth), the default strike and the tooth hard cases
// (stiff, wedged kernel), at 6 shape functions (the least `modes: auto` gives a rod; the count
// is not what is compared, and the stiff rods' automatic counts cost minutes). The same impacts
// in the same order, and the peak forces, the largest tip deflection, every kernel's final
// velocity and the energy (final mechanical energy, drive work) within the error estimate of
// the test above. Not the soft tooth (hard/07): at 6 shape functions its contact's end costs
// the global scheme 1e4-2e4 steps at tolerance 1e-8 (a minute), and at the scene's 1e-6 the
// global scheme's late tangential peak (3.09 N) is 23 % above its converged 2.50 N, which the
// island scheme gives already; test_hard_cases runs it under both schemes.
const Case kRodCases[] = {
    {"default_scene.yaml", ""},
    {"scenes/knead.yaml", ""},
    {"bench/knead_polyurethane.yaml", ""},
    {"hard/06_stiff_tooth.yaml", ""},
    {"hard/08_wedged.yaml", ""},
};

// outputs() with the tip deflection and the energy.
std::vector<double> rodOutputs(const SceneRun& r) {
  std::vector<double> out = outputs(r);
  out.push_back(r.d.stats.max_tip_deflection_ratio);
  out.push_back(mechanicalEnergy(r.m, r.d));
  out.push_back(r.d.stats.drive_work_J);
  return out;
}

TEST_P(IslandScenes, RodScenesSameImpactsAndOutputsWithinTheErrorEstimate) {
  const std::string rod = "teeth.*.model=large_deflection", shapes = "teeth.*.modes=6";
  auto run = [&](const Case& c, bool islands, const std::string& knob) {
    std::vector<std::string> o = settings(c, GetParam(), islands, knob);
    o.push_back(rod);
    o.push_back(shapes);
    return runScene(c.file, o);
  };
  for (const Case& c : kRodCases) {
    SCOPED_TRACE(std::string(c.file) + ", rod, " + GetParam());
    const SceneRun g = run(c, false, "");
    const SceneRun a = run(c, true, "");
    const SceneRun f = run(c, false, refined(g));
    const SceneRun af = run(c, true, refined(g));
    ASSERT_EQ(a.m.teeth[0].beam_model, ToothBeamModel::kLargeDeflection);
    EXPECT_GT(a.d.stats.scheduler.islands_built, 0);
    EXPECT_GE(g.d.stats.impacts, 1);
    const std::string tag = std::string("ROD_ISLANDS ") + c.file + " " + GetParam();
    expectSchemesAgree(g, a, f, af, rodOutputs, tag.c_str());
  }
}

// The polyurethane knead with the static correction and the Euler-Bernoulli sections the
// old defect was found with (the island scheme's peak 3e-4 below the global one at tolerance
// 1e-6, 5.7e-5 at 1e-7 after the energy-consistent correction: the located peaks' force rate
// held the residual R fixed, so the located peak followed the step sequence). With R' in the
// rate: the peak forces and the exit velocity within 1e-5 (relative) of the global scheme's
// at the scene's tolerance and 1e-6 at 1e-7 (measured 8e-8 and 1e-8: peak F_N 31.901024 /
// 31.901027 N at 1e-6, 31.9017699 / 31.9017702 N at 1e-7), the same impacts.
TEST_P(IslandScenes, PolyurethaneKneadWithTheStaticCorrectionWithinAKnownBound) {
  for (const auto& [tolerance, bound] :
       {std::pair<const char*, double>{"", 1e-5}, std::pair<const char*, double>{"1e-7", 1e-6}}) {
    SCOPED_TRACE(std::string("tolerance ") + tolerance);
    const Case c{"bench/knead_polyurethane.yaml", "",
                 *tolerance ? "integrator.tolerance=1e-7" : ""};
    const std::string euler_bernoulli = "teeth.*.section_rotation=euler_bernoulli";
    const SceneRun g = runScene(c.file, settings(c, GetParam(), false, euler_bernoulli));
    const SceneRun a = runScene(c.file, settings(c, GetParam(), true, euler_bernoulli));
    ASSERT_NE(g.status, StepStatus::kFailed);
    ASSERT_NE(a.status, StepStatus::kFailed);
    EXPECT_TRUE(g.m.teeth[0].static_correction);
    EXPECT_EQ(a.d.stats.impacts, g.d.stats.impacts);
    const std::vector<double> og = outputs(g), oa = outputs(a);
    for (size_t q = 0; q < og.size(); ++q)
      EXPECT_LE(std::abs(oa[q] - og[q]), bound * std::abs(og[q]) + 1e-9)
          << "output " << q << ": global " << og[q] << ", islands " << oa[q];
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

// A chaotic scene's outcomes over all kernels (which kernel bounces into which differs from run
// to run, so per-kernel counts scatter) are samples: a change in the last digits early on (a
// step boundary, a tolerance) leads to other collisions later. So the two schemes are compared
// as samples, each run at twelve tolerances from 3e-6 to 1e-8: the island scheme's mean total
// of tooth strikes lies within three standard errors of the difference of the means (at least
// one strike) of the global scheme's, and each island run's strikes, detached kernels and
// largest peak tooth force lie within the global scheme's range widened by the scatter of a
// count (2, or a fifth of it) and 5 % of a force. Measured on the long run (0.2 s): the global
// scheme gives 11 to 19 strikes over these tolerances (mean 13.5), the island scheme 11 to 19
// (mean 13.3). A single island run against three global ones (the test before) sat at the edge
// of that range plus its slack and flipped with changes that only move step boundaries.
struct Totals {
  long strikes = 0;
  int detached = 0;
  double peak_N = 0;
};

Totals totalsOf(const Outcomes& o) {
  Totals t;
  for (size_t i = 0; i < o.strikes.size(); ++i) {
    t.strikes += o.strikes[i];
    t.detached += o.detached[i];
    t.peak_N = std::max(t.peak_N, o.peak_tooth_force_N[i]);
  }
  return t;
}

// Mean and variance of the mean of the strike counts.
std::pair<double, double> meanAndVarianceOfMean(const std::vector<Totals>& runs) {
  double sum = 0.0, sum2 = 0.0;
  for (const Totals& r : runs) sum += static_cast<double>(r.strikes);
  const double n = static_cast<double>(runs.size()), mean = sum / n;
  for (const Totals& r : runs) sum2 += (r.strikes - mean) * (r.strikes - mean);
  return {mean, sum2 / (n - 1) / n};
}

void expectWithinGlobalSpread(const Case& c) {
  SCOPED_TRACE(c.file);
  const char* const kTolerances[] = {"3e-6", "2e-6", "1e-6", "5e-7", "3e-7",   "2e-7",
                                     "1e-7", "5e-8", "3e-8", "2e-8", "1.5e-8", "1e-8"};
  std::vector<Totals> global, islands;
  for (const char* tol : kTolerances) {
    const std::string key = std::string("integrator.tolerance=") + tol;
    global.push_back(
        totalsOf(outcomesOf(runScene(c.file, settings(c, "event_driven", false, key)))));
    islands.push_back(
        totalsOf(outcomesOf(runScene(c.file, settings(c, "event_driven", true, key)))));
  }
  Totals lo = global[0], hi = global[0];
  for (const Totals& g : global) {
    lo.strikes = std::min(lo.strikes, g.strikes);
    hi.strikes = std::max(hi.strikes, g.strikes);
    lo.detached = std::min(lo.detached, g.detached);
    hi.detached = std::max(hi.detached, g.detached);
    lo.peak_N = std::min(lo.peak_N, g.peak_N);
    hi.peak_N = std::max(hi.peak_N, g.peak_N);
  }
  const auto [mean_g, var_g] = meanAndVarianceOfMean(global);
  const auto [mean_a, var_a] = meanAndVarianceOfMean(islands);
  EXPECT_LE(std::abs(mean_a - mean_g), std::max(1.0, 3.0 * std::sqrt(var_g + var_a)))
      << "mean strikes: global " << mean_g << ", islands " << mean_a;
  const long slack = std::max(2L, hi.strikes / 5);
  for (size_t q = 0; q < islands.size(); ++q) {
    const Totals& a = islands[q];
    SCOPED_TRACE(kTolerances[q]);
    EXPECT_GE(a.strikes, lo.strikes - slack);
    EXPECT_LE(a.strikes, hi.strikes + slack);
    EXPECT_GE(a.detached, lo.detached - 1);
    EXPECT_LE(a.detached, hi.detached + 1);
    EXPECT_GE(a.peak_N, 0.95 * lo.peak_N);
    EXPECT_LE(a.peak_N, 1.05 * hi.peak_N);
  }
}

TEST(IslandScenesChaotic, LongRunOutcomesWithinTheGlobalSchemesSpread) {
  expectWithinGlobalSpread({"hard/10_long_run.yaml", "0.2"});
}

TEST(IslandScenesChaotic, StreamOutcomesWithinTheGlobalSchemesSpread) {
  expectWithinGlobalSpread({"scenes/stream.yaml", "0.004"});
}

// An episode that begins in one island and ends in another (the island is split or merged
// while the contact lasts) reports the energy lost over the whole episode: its start energy is
// carried from island to island relative to each one's net energy. It was compared with the
// later island's energy, of other bodies and another drive-work origin, so that impacts of the
// threshing stream reported gains of 0.03 J (a struck kernel carries about 4e-3 J). The stream's
// compliant micro-bounces of a kernel resting on a tooth report gains of up to 8e-5 J under
// either scheme (Hunt-Crossley at approach speeds below 1 mm/s, a separate matter); 1e-3 J
// separates the two.
TEST(IslandScenesChaotic, StreamImpactEnergiesAcrossIslandRebuilds) {
  for (const char* seed : {"1", "2", "3"}) {
    SCOPED_TRACE(std::string("seed ") + seed);
    const Case c{"scenes/stream.yaml", "0.004", ""};
    for (const bool islands : {false, true}) {
      const SceneRun r = runScene(
          c.file, settings(c, "event_driven", islands, std::string("stream.seed=") + seed));
      ASSERT_NE(r.status, StepStatus::kFailed);
      if (islands) {
        EXPECT_GT(r.d.stats.scheduler.islands_built, 1);
      }
      EXPECT_LT(r.d.stats.max_energy_gain_at_impact_J, 1e-3) << (islands ? "islands" : "global");
      for (const ContactEvent& e : r.d.events) {
        if (e.is_impact) {
          EXPECT_GT(e.energy_lost_J, -1e-3) << "impact at " << e.t_s;
        }
      }
    }
  }
}

// The stream scene to its end (8 ms) under the global scheme, advanced as simulate advances it
// (advancePast to every 0.1 ms, each call on the work budget of its 0.1 ms), with no slip begun
// from stick that turns back to stick within 1e-10 s. Such a slip starts from zero slip velocity
// at the friction limit; its reversal counts only past the integrator's velocity error scale
// (slipReversalScale: tolerance x 1 m/s, 1e-6 m/s here). Compared with zero, kernel 5 pressed on
// grate bar 8 by a pile of kernels (with the evcost changes: t = 7.16 ms; the pile's
// Hunt-Crossley contacts made its stick force jitter by 2 % from step to step) went stick ->
// slip -> stick every 1.3e-8 s, its slip velocity turning back at 1e-14 m/s within a picosecond:
// 1124 of the run's 1245 slips from stick lasted under 1e-11 s, and the budget (32,000 units
// per 0.1 ms) ran out at 7.18 ms. With the scale: 355 slips from stick, the shortest 3.6e-9 s;
// 67,921 steps.
TEST(StreamScene, NoStickSlipChatterUnderTheGlobalScheme) {
  const Case c{"scenes/stream.yaml", "", ""};
  SceneRun r;
  r.m = loadScene(std::string(THRESHING_SIM_SOURCE_DIR) + "/config/" + c.file,
                  settings(c, "event_driven", false));
  resetData(r.m, &r.d);
  for (double t_s = 1e-4; r.d.t_s < r.m.duration_s; t_s += 1e-4) {
    r.status = advancePast(r.m, &r.d, std::min(t_s, r.m.duration_s), r.m.duration_s);
    ASSERT_NE(r.status, StepStatus::kFailed)
        << toString(r.d.stats.failure.cause) << " at t = " << r.d.t_s << " s";
  }
  EXPECT_EQ(r.d.t_s, r.m.duration_s);
  long slips = 0, short_slips = 0;
  std::vector<std::pair<PairId, double>> slip_start;  // pairs slipping since stick, and when
  for (const ContactEvent& e : r.d.events) {
    const auto same = [&](const std::pair<PairId, double>& s) {
      return s.first.kind == e.pair.kind && s.first.a == e.pair.a && s.first.b == e.pair.b;
    };
    const auto it = std::find_if(slip_start.begin(), slip_start.end(), same);
    if (e.from == ContactState::kStick && e.to == ContactState::kSlip) {
      if (it == slip_start.end())
        slip_start.push_back({e.pair, e.t_s});
      else
        it->second = e.t_s;
    } else if (it != slip_start.end()) {
      if (e.from == ContactState::kSlip && e.to == ContactState::kStick) {
        ++slips;
        if (e.t_s - it->second < 1e-10) ++short_slips;
      }
      slip_start.erase(it);
    }
  }
  RecordProperty("slip_phases", std::to_string(slips));
  RecordProperty("steps", std::to_string(r.d.steps));
  EXPECT_GT(slips, 10);
  EXPECT_EQ(short_slips, 0) << "of " << slips << " slip phases";
}

INSTANTIATE_TEST_SUITE_P(BothIntegrators, IslandScenes,
                         ::testing::Values("event_driven", "time_stepping"),
                         [](const ::testing::TestParamInfo<const char*>& info) {
                           return std::string(info.param) == "event_driven"
                                      ? std::string("EventDriven")
                                      : std::string("TimeStepping");
                         });

// The contact phase on the stream scene (kernels on pedicels pressed against the grate and each
// other, six teeth): a pressed contact whose damped force clamps at a step end stays closed
// while the bodies overlap. (It used to open there and close again at the next step: 415
// impacts at 20 steps per contact over 20 ms, 3 566 at 160, each flicker counted as an impact.)
// The impact count must not grow with the step count.
TEST(ContactPhaseScenes, ImpactsDoNotGrowWithTheStepCountOnTheStream) {
  long impacts[2] = {0, 0};
  const int counts[2] = {20, 160};
  for (int k = 0; k < 2; ++k) {
    const SceneRun r =
        runScene("scenes/stream.yaml",
                 {"duration=0.02", "integrator.contact_steps=" + std::to_string(counts[k])});
    ASSERT_EQ(r.status, StepStatus::kOk) << counts[k];
    impacts[k] = r.d.stats.impacts;
    RecordProperty("impacts_" + std::to_string(counts[k]), std::to_string(impacts[k]));
  }
  EXPECT_GT(impacts[0], 50);
  EXPECT_LE(impacts[1], 1.5 * impacts[0]) << impacts[0] << " -> " << impacts[1];
}

}  // namespace
}  // namespace threshing_sim
