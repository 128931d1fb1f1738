// Mode convergence (issue 12): the polyurethane knead of config/bench/ with the automatic mode
// count and the static correction gives the same knead force, normal force and exit speed to
// 1 % as the next finer level (ceil(1.5 n) modes, as scripts/convergence_table.py compares),
// where the modal tooth alone moved by 10 % between 10 and 12 modes; a tip strike's stick force
// converges with the shear-corrected sections; no impact gains energy. Full table:
// docs/convergence.md.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>
#include <utility>
#include <vector>

#include "threshing_sim/core/data.h"
#include "threshing_sim/core/large_deflection.h"
#include "threshing_sim/core/simulator.h"
#include "threshing_sim/scene/scene_loader.h"

namespace threshing_sim {
namespace {

const std::string kKnead =
    std::string(THRESHING_SIM_SOURCE_DIR) + "/config/bench/knead_polyurethane.yaml";

struct Result {
  int modes = 0;             // retained modes [-]
  double normal_N = 0;       // peak tooth normal force on the kernel [N]
  double tangential_N = 0;   // peak tooth tangential (knead) force [N]
  double exit_mps = 0;       // kernel speed at the end [m/s]
  double energy_gain_J = 0;  // largest energy gain at an impact [J]
  long impacts = 0;          // impacts and compliant episodes [-]
  long steps = 0;            // integrator steps [-]
  int nodes = 0;             // a rod's mass nodes (0: modal tooth) [-]
};

Result runKnead(const std::vector<std::string>& overrides, const std::string& scene = kKnead) {
  const Model m = loadScene(scene, overrides);
  Data d;
  resetData(m, &d);
  EXPECT_EQ(advanceTo(m, &d, m.duration_s), StepStatus::kOk);
  Result r;
  r.modes = m.teeth[0].n_modes;
  r.normal_N = d.stats.kernel_tooth_peaks[0].normal_force_N;
  r.tangential_N = d.stats.kernel_tooth_peaks[0].tangential_force_N;
  r.exit_mps = d.u.segment<2>(m.kernels[0].dof_offset).norm();
  r.energy_gain_J = d.stats.max_energy_gain_at_impact_J;
  r.impacts = d.stats.impacts;
  r.steps = d.steps;
  if (m.teeth[0].beam_model == ToothBeamModel::kLargeDeflection)
    r.nodes = static_cast<int>(m.teeth[0].ld_node_s_m.size());
  return r;
}

TEST(Convergence, PolyurethaneKneadIsConvergedAtTheAutomaticModeCount) {
  const Result chosen = runKnead({"teeth.*.modes=auto"});
  const int finer_modes = std::min(64, static_cast<int>(std::ceil(1.5 * chosen.modes)));
  ASSERT_GT(finer_modes, chosen.modes);
  const Result finer = runKnead({"teeth.*.modes=" + std::to_string(finer_modes)});
  RecordProperty("auto_modes", chosen.modes);
  RecordProperty("knead_force_auto_N", std::to_string(chosen.tangential_N));
  RecordProperty("knead_force_finer_N", std::to_string(finer.tangential_N));
  EXPECT_NEAR(finer.tangential_N, chosen.tangential_N, 0.01 * chosen.tangential_N);
  EXPECT_NEAR(finer.normal_N, chosen.normal_N, 0.01 * chosen.normal_N);
  EXPECT_NEAR(finer.exit_mps, chosen.exit_mps, 0.01 * chosen.exit_mps);
  EXPECT_EQ(chosen.energy_gain_J, 0.0);
  EXPECT_EQ(finer.energy_gain_J, 0.0);
  // The knead is a real one: a few newtons of tangential force.
  EXPECT_GT(chosen.tangential_N, 2.0);
}

// The nylon knead of config/scenes/knead.yaml with the large-deflection tooth (0.124 L of tip
// deflection, past the modal tooth's range): at 8 shape functions the closest-point secant on
// the bent rod used to run off to the root mid-squeeze, so the pair, 0.36 mm deep, read 59.5 mm
// apart, opened and closed every 1e-11 s and the run ran out of its work budget. Every level
// now completes with the same impacts, and 10 and 12 shape functions agree to 1 %.
TEST(Convergence, LargeDeflectionKneadCompletesAndConverges) {
  const std::string knead = std::string(THRESHING_SIM_SOURCE_DIR) + "/config/scenes/knead.yaml";
  std::vector<Result> levels;
  for (int n : {8, 10, 12}) {
    SCOPED_TRACE(n);
    levels.push_back(
        runKnead({"teeth.0.model=large_deflection", "teeth.0.modes=" + std::to_string(n)}, knead));
    EXPECT_EQ(levels.back().impacts, levels.front().impacts);
    EXPECT_EQ(levels.back().energy_gain_J, 0.0);
  }
  const Result &chosen = levels[1], &finer = levels[2];
  EXPECT_NEAR(finer.tangential_N, chosen.tangential_N, 0.01 * chosen.tangential_N);
  EXPECT_NEAR(finer.normal_N, chosen.normal_N, 0.01 * chosen.normal_N);
  EXPECT_NEAR(finer.exit_mps, chosen.exit_mps, 0.01 * chosen.exit_mps);
  // A real squeeze: well over the 139 N of plastic damage of docs/model.md §10.
  EXPECT_GT(chosen.normal_N, 150.0);
}

// The polyurethane knead with the large-deflection tooth (about 0.107 L of tip deflection, past
// the modal tooth's range): the rod has no static correction, and its forces moved by 15 % from
// 6 to 24 shape functions (41.3 against 35.3 N normal). `modes: auto` on a rod takes the modal
// count within [kLdAutoMinShapes, kLdAutoMaxShapes] (24 here), and the finer levels +4 and +8
// (as scripts/convergence_table.py compares) agree with it to 1 %, and with the converged modal
// tooth to 1 %.
// One line of docs/large_deflection.md's knead table (scripts/large_deflection_table.py).
void printKneadRow(const Result& r) {
  const std::string nodes = r.nodes > 0 ? std::to_string(r.nodes) : "modal";
  std::printf(
      "LD_KNEAD shapes %d nodes %s: normal %.2f N, tangential %.2f N, exit speed %.3f m/s, "
      "steps %ld\n",
      r.modes, nodes.c_str(), r.normal_N, r.tangential_N, r.exit_mps, r.steps);
}

Result runRodKnead(const std::string& modes) {
  return runKnead({"teeth.*.model=large_deflection", "teeth.*.modes=" + modes});
}

TEST(Convergence, LargeDeflectionPolyurethaneKneadIsConvergedAtTheAutomaticCount) {
  const Result coarse = runRodKnead("6"), before_auto = runRodKnead("20");
  const Result chosen = runRodKnead("auto");
  EXPECT_EQ(chosen.modes, kLdAutoMaxShapes);
  printKneadRow(coarse);
  printKneadRow(before_auto);
  printKneadRow(chosen);
  for (int n : {chosen.modes + 4, chosen.modes + 8}) {
    SCOPED_TRACE(n);
    const Result finer = runRodKnead(std::to_string(n));
    printKneadRow(finer);
    EXPECT_NEAR(finer.tangential_N, chosen.tangential_N, 0.01 * chosen.tangential_N);
    EXPECT_NEAR(finer.normal_N, chosen.normal_N, 0.01 * chosen.normal_N);
    EXPECT_NEAR(finer.exit_mps, chosen.exit_mps, 0.01 * chosen.exit_mps);
    EXPECT_EQ(finer.energy_gain_J, 0.0);
  }
  const Result modal = runKnead({"teeth.*.modes=auto"});
  printKneadRow(modal);
  EXPECT_NEAR(chosen.tangential_N, modal.tangential_N, 0.01 * modal.tangential_N);
  EXPECT_NEAR(chosen.normal_N, modal.normal_N, 0.01 * modal.normal_N);
  // The 6 shape functions of before are not converged: the test can fail.
  EXPECT_GT(std::abs(coarse.normal_N - chosen.normal_N), 0.05 * chosen.normal_N);
}

// A rod takes at most kLdMaxShapes shape functions, refused by name past it.
TEST(Convergence, LargeDeflectionRefusesMoreShapeFunctionsThanItResolves) {
  EXPECT_NO_THROW(loadScene(
      kKnead, {"teeth.0.model=large_deflection", "teeth.0.modes=" + std::to_string(kLdMaxShapes)}));
  try {
    loadScene(kKnead, {"teeth.0.model=large_deflection",
                       "teeth.0.modes=" + std::to_string(kLdMaxShapes + 1)});
    ADD_FAILURE() << "no error";
  } catch (const std::exception& e) {
    const std::string expected = "teeth.0.modes: must be <= " + std::to_string(kLdMaxShapes);
    EXPECT_NE(std::string(e.what()).find(expected), std::string::npos) << e.what();
  }
}

// `static_correction: off` is the modal tooth of before the correction: bit for bit the run of
// a model whose residual tables are zero (the series law with r = 0 is the plain Hertz law),
// under both integrators; with the correction on, the forces differ (the test can fail) and no
// impact gains energy.
TEST(Convergence, StaticCorrectionOffIsTheModalToothUnderBothIntegrators) {
  for (const char* integrator : {"event_driven", "time_stepping"}) {
    SCOPED_TRACE(integrator);
    const std::vector<std::string> base = {std::string("integrator.type=") + integrator,
                                           "teeth.*.modes=12"};
    std::vector<std::string> off = base, on = base;
    off.push_back("teeth.*.static_correction=off");
    Model m_off = loadScene(kKnead, off), m_zero = loadScene(kKnead, on),
          m_on = loadScene(kKnead, on);
    ASSERT_TRUE(m_zero.teeth[0].static_correction);
    ASSERT_GT(m_zero.teeth[0].residual_ww.maxCoeff(), 0.0);
    m_zero.teeth[0].residual_ww.setZero();
    m_zero.teeth[0].residual_wt.setZero();
    m_zero.teeth[0].residual_tt.setZero();
    Data d_off, d_zero, d_on;
    for (auto [m, d] :
         {std::pair<const Model*, Data*>{&m_off, &d_off}, {&m_zero, &d_zero}, {&m_on, &d_on}}) {
      resetData(*m, d);
      ASSERT_EQ(advanceTo(*m, d, m->duration_s), StepStatus::kOk);
    }
    EXPECT_EQ(d_off.stats.peak_normal_force_N, d_zero.stats.peak_normal_force_N);
    EXPECT_EQ(d_off.stats.peak_tangential_force_N, d_zero.stats.peak_tangential_force_N);
    EXPECT_EQ(d_off.stats.impacts, d_zero.stats.impacts);
    EXPECT_TRUE(d_off.z == d_zero.z && d_off.u == d_zero.u);
    EXPECT_NE(d_on.stats.peak_normal_force_N, d_off.stats.peak_normal_force_N);
    EXPECT_LE(d_on.stats.max_energy_gain_at_impact_J, 1e-9 * d_on.stats.energy_initial_J);
  }
}

}  // namespace
}  // namespace threshing_sim

namespace threshing_sim {
namespace {

// The tip strike of docs/convergence.md's section rotation study: peak tangential force at a
// mode count and section rotation, at a tolerance far below the differences.
double tipStrikeStickForce(int modes, const std::string& rotation,
                           const std::string& model = "modal") {
  const std::string dir = std::string(THRESHING_SIM_SOURCE_DIR) + "/config/scenes/";
  std::vector<std::string> overrides = overridesFromFile(dir + "teeth/nylon.yaml");
  for (const std::string& o : overridesFromFile(dir + "cases/tip_strike.yaml"))
    overrides.push_back(o);
  overrides.push_back("teeth.*.modes=" + std::to_string(modes));
  overrides.push_back("teeth.*.section_rotation=" + rotation);
  overrides.push_back("integrator.tolerance=1e-10");
  overrides.push_back("teeth.*.model=" + model);
  const Model m = loadScene(dir + "single_strike.yaml", overrides);
  Data d;
  resetData(m, &d);
  EXPECT_EQ(advanceTo(m, &d, m.duration_s), StepStatus::kOk);
  EXPECT_EQ(d.stats.max_energy_gain_at_impact_J, 0.0);
  return d.stats.kernel_tooth_peaks[0].tangential_force_N;
}

// With Euler-Bernoulli sections the friction couple reaches into every mode through its
// slope, and the tip strike's stick force moves by more than 1 % from 20 to 30 modes; with
// the shear-corrected sections (the default) it moves by less than 0.1 %.
TEST(Convergence, TipStrikeStickForceConvergesWithShearCorrectedSections) {
  const double shear20 = tipStrikeStickForce(20, "shear_corrected");
  const double shear30 = tipStrikeStickForce(30, "shear_corrected");
  const double eb20 = tipStrikeStickForce(20, "euler_bernoulli");
  const double eb30 = tipStrikeStickForce(30, "euler_bernoulli");
  RecordProperty("shear_corrected_N", std::to_string(shear20) + " " + std::to_string(shear30));
  RecordProperty("euler_bernoulli_N", std::to_string(eb20) + " " + std::to_string(eb30));
  EXPECT_NEAR(shear30, shear20, 1e-3 * shear20);
  EXPECT_GT(std::abs(eb30 - eb20), 0.01 * eb20);
  EXPECT_GT(shear20, 1.0);  // a real stick force, a few newtons
}

// The large-deflection rod's stick force on the same strike: with its sections turning as
// its centreline (Euler-Bernoulli) it moves by several percent between 10 and 12 shape
// functions; shear-corrected it moves by less than 1 % and agrees with the modal tooth to 1 %.
TEST(Convergence, RodTipStrikeStickForceConvergesWithShearCorrectedSections) {
  const double shear10 = tipStrikeStickForce(10, "shear_corrected", "large_deflection");
  const double shear12 = tipStrikeStickForce(12, "shear_corrected", "large_deflection");
  const double eb10 = tipStrikeStickForce(10, "euler_bernoulli", "large_deflection");
  const double eb12 = tipStrikeStickForce(12, "euler_bernoulli", "large_deflection");
  const double modal = tipStrikeStickForce(30, "shear_corrected");
  RecordProperty("rod_shear_corrected_N", std::to_string(shear10) + " " + std::to_string(shear12));
  RecordProperty("rod_euler_bernoulli_N", std::to_string(eb10) + " " + std::to_string(eb12));
  EXPECT_NEAR(shear12, shear10, 0.01 * shear10);
  EXPECT_GT(std::abs(eb12 - eb10), 0.03 * eb10);
  EXPECT_NEAR(shear12, modal, 0.01 * modal);
}

// Time stepping at a scene's own step (1e-6 s) against the event-driven integrator at
// tolerance 1e-8 (issue 23, item 4): the peak normal and tangential contact forces within 2 %.
// The tangential peak of a strike is the sliding force mu N at the instant the slip ends,
// inside a step; a step's mean friction (its impulse / h) was 48 % below it on the default
// strike, and the compliant force's damping taken at the step start's gap rate put the normal
// peak 3 % above (the knead squeeze over the steel bar: +64 %, the friction +56 %).
struct PeakForces {
  double normal_N = 0;      // peak normal contact force [N]
  double tangential_N = 0;  // peak tangential contact force [N]
};

PeakForces runPeaks(const std::string& scene, const std::vector<std::string>& overrides) {
  const Model m = loadScene(scene, overrides);
  Data d;
  resetData(m, &d);
  EXPECT_EQ(advanceTo(m, &d, m.duration_s), StepStatus::kOk);
  return {d.stats.peak_normal_force_N, d.stats.peak_tangential_force_N};
}

void expectTimeSteppingPeaksMatchEventDriven(const std::string& scene) {
  SCOPED_TRACE(scene);
  const PeakForces ed =
      runPeaks(scene, {"integrator.type=event_driven", "integrator.tolerance=1e-8"});
  const PeakForces ts = runPeaks(scene, {"integrator.type=time_stepping"});
  ::testing::Test::RecordProperty(
      "peaks_N", scene + ": time stepping " + std::to_string(ts.normal_N) + " " +
                     std::to_string(ts.tangential_N) + ", event-driven " +
                     std::to_string(ed.normal_N) + " " + std::to_string(ed.tangential_N));
  EXPECT_GT(ed.tangential_N, 1.0);  // a real friction force
  EXPECT_NEAR(ts.normal_N, ed.normal_N, 0.02 * ed.normal_N);
  EXPECT_NEAR(ts.tangential_N, ed.tangential_N, 0.02 * ed.tangential_N);
}

TEST(Convergence, TimeSteppingPeakForcesAtTheScenesStepMatchEventDriven) {
  const std::string dir = std::string(THRESHING_SIM_SOURCE_DIR) + "/config/";
  expectTimeSteppingPeaksMatchEventDriven(dir + "default_scene.yaml");
  expectTimeSteppingPeaksMatchEventDriven(dir + "bench/knead_polyurethane.yaml");
  expectTimeSteppingPeaksMatchEventDriven(dir + "scenes/knead.yaml");
  expectTimeSteppingPeaksMatchEventDriven(dir + "scenes/single_strike.yaml");
}

}  // namespace
}  // namespace threshing_sim
