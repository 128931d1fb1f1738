// Tests of the scene loader (YAML -> Model, overrides, refusals) and of the result writers.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <iomanip>
#include <sstream>
#include <string>
#include <vector>

#include "threshing_sim/core/simulator.h"
#include "threshing_sim/scene/report.h"
#include "threshing_sim/scene/scene_loader.h"

namespace threshing_sim {
namespace {

// A small valid scene: one tooth along +X at theta = 0, one kernel above it, a floor.
const char kBaseScene[] = R"(
drum: {radius: 0.20, speed: 83.78}
teeth: [{mount_angle: 0.0, length: 0.06}]
kernels: [{position: [0.0, 0.245]}]
obstacles: [{type: plane, point: [0.0, -0.5], normal: [0.0, 1.0]}]
)";

// The SceneError message of modelFromYaml, or "" if the scene was accepted.
std::string refusal(const YAML::Node& root) {
  try {
    modelFromYaml(root);
  } catch (const SceneError& e) {
    return e.what();
  }
  return "";
}

// The message after applying one override to the base scene, or "" if both steps passed.
std::string refusalWithOverride(const std::string& assignment) {
  YAML::Node root = YAML::Load(kBaseScene);
  try {
    applyOverride(&root, assignment);
  } catch (const SceneError& e) {
    return e.what();
  }
  return refusal(root);
}

Model baseWith(const std::vector<std::string>& assignments) {
  YAML::Node root = YAML::Load(kBaseScene);
  for (const std::string& a : assignments) applyOverride(&root, a);
  return modelFromYaml(root);
}

// A refusal case: the scene change and the fragments its message must contain.
struct Refusal {
  std::string change;
  std::vector<std::string> fragments;
};

void expectRefused(const std::string& message, const Refusal& c) {
  ASSERT_FALSE(message.empty()) << "accepted: " << c.change;
  for (const std::string& fragment : c.fragments) {
    EXPECT_NE(message.find(fragment), std::string::npos)
        << "'" << c.change << "' gave \"" << message << "\", missing \"" << fragment << "\"";
  }
}

// ---------------------------------------------------------------------------------------------
// Valid scenes.

TEST(SceneLoader, BaseSceneLoadsWithDefaults) {
  const Model m = modelFromYaml(YAML::Load(kBaseScene));
  ASSERT_TRUE(m.compiled);
  ASSERT_EQ(m.teeth.size(), 1u);
  ASSERT_EQ(m.kernels.size(), 1u);
  ASSERT_EQ(m.obstacles.size(), 1u);
  // modes: auto by default; the count follows from the contact time (static_correction.cc).
  EXPECT_TRUE(m.teeth[0].modes_auto);
  EXPECT_GE(m.teeth[0].n_modes, 2);
  EXPECT_EQ(m.n_dof, m.teeth[0].n_modes + 3);
  EXPECT_TRUE(m.teeth[0].static_correction);

  // Struct defaults where the scene is silent.
  EXPECT_DOUBLE_EQ(m.drum.max_acceleration_radps2, 200.0);
  EXPECT_DOUBLE_EQ(m.teeth[0].diameter_m, 0.010);
  EXPECT_DOUBLE_EQ(m.teeth[0].youngs_modulus_Pa, 3e9);
  EXPECT_EQ(m.teeth[0].n_stations, 9);
  EXPECT_DOUBLE_EQ(m.kernels[0].mass_kg, 2.8e-5);
  EXPECT_DOUBLE_EQ(m.kernels[0].semi_axis_a_m, 5.0e-3);
  EXPECT_DOUBLE_EQ(m.kernels[0].semi_axis_b_m, 1.3e-3);
  EXPECT_FALSE(m.kernels[0].pedicel.present);
  EXPECT_EQ(m.gravity_mps2, Vec2(0.0, -9.81));
  EXPECT_EQ(m.integrator.type, IntegratorType::kEventDriven);
  EXPECT_DOUBLE_EQ(m.integrator.tolerance, 1e-9);
  EXPECT_DOUBLE_EQ(m.duration_s, 0.03);
  EXPECT_DOUBLE_EQ(m.broadphase_margin_m, 2e-3);
  EXPECT_DOUBLE_EQ(m.deflection_validity_fraction, 0.1);

  // Contact defaults from docs/model.md §10.
  const ContactParams& tk = m.contact[static_cast<int>(PairKind::kToothKernel)];
  const ContactParams& kk = m.contact[static_cast<int>(PairKind::kKernelKernel)];
  const ContactParams& ko = m.contact[static_cast<int>(PairKind::kKernelObstacle)];
  EXPECT_EQ(tk.law, ContactLaw::kCompliant);
  EXPECT_DOUBLE_EQ(tk.restitution, 0.48);
  EXPECT_DOUBLE_EQ(tk.friction, 0.53);
  EXPECT_EQ(kk.law, ContactLaw::kRigid);
  EXPECT_DOUBLE_EQ(kk.restitution, 0.34);
  EXPECT_DOUBLE_EQ(kk.friction, 0.66);
  EXPECT_EQ(ko.law, ContactLaw::kRigid);
  EXPECT_DOUBLE_EQ(ko.restitution, 0.47);
  EXPECT_DOUBLE_EQ(ko.friction, 0.50);
}

TEST(SceneLoader, EveryKeyIsRead) {
  const Model m = modelFromYaml(YAML::Load(R"(
drum: {radius: 0.25, speed: 100.0, max_acceleration: 50.0, angle: 0.1}
teeth:
  - {mount_angle: 1.0, length: 0.05, diameter: 0.008, youngs_modulus: 2.0e9, density: 1100.0,
     modes: 3, damping_ratio: 0.05, poisson_ratio: 0.4, stations: 5}
kernels:
  - position: [0.0, 0.5]
    angle: 0.3
    velocity: [1.0, -2.0]
    angular_velocity: 4.0
    semi_axes: [4.0e-3, 1.0e-3]
    mass: 2.0e-5
    youngs_modulus: 1.0e8
    poisson_ratio: 0.25
    pedicel: {anchor: [0.0, 0.51], attach_point: [1.0e-3, 0.0], stiffness: 150.0,
              damping: 0.001, rest_length: 0.009, detachment_force: 2.0}
obstacles:
  - {type: plane, point: [0.0, -0.5], normal: [0.0, 2.0], youngs_modulus: 1.0e11,
     poisson_ratio: 0.28}
  - {type: circle, center: [0.0, -0.3], radius: 0.006}
  - {type: segment, point: [-0.1, -0.4], point_b: [0.1, -0.4], radius: 0.001}
contact:
  tooth_kernel: {law: rigid, restitution: 0.4, friction: 0.3}
  kernel_kernel: {law: compliant}
  kernel_obstacle: {friction: 0.2}
  hc_min_impact_speed: 0.05
gravity: [0.0, -9.8]
integrator: {type: time_stepping, tolerance: 1.0e-8, dt: 2.0e-6, theta: 0.6,
             zeno_velocity: 2.0e-3, max_step: 5.0e-5}
duration: 0.01
broadphase_margin: 0.003
)"));
  EXPECT_DOUBLE_EQ(m.drum.radius_m, 0.25);
  EXPECT_DOUBLE_EQ(m.drum.initial_speed_radps, 100.0);
  EXPECT_DOUBLE_EQ(m.drum.max_acceleration_radps2, 50.0);
  EXPECT_DOUBLE_EQ(m.drum.initial_angle_rad, 0.1);

  const ToothModel& t = m.teeth.at(0);
  EXPECT_DOUBLE_EQ(t.mount_angle_rad, 1.0);
  EXPECT_DOUBLE_EQ(t.length_m, 0.05);
  EXPECT_DOUBLE_EQ(t.diameter_m, 0.008);
  EXPECT_DOUBLE_EQ(t.youngs_modulus_Pa, 2.0e9);
  EXPECT_DOUBLE_EQ(t.density_kgpm3, 1100.0);
  EXPECT_EQ(t.n_modes, 3);
  EXPECT_DOUBLE_EQ(t.damping_ratio, 0.05);
  EXPECT_DOUBLE_EQ(t.poisson_ratio, 0.4);
  EXPECT_EQ(t.n_stations, 5);

  const KernelModel& k = m.kernels.at(0);
  EXPECT_EQ(k.initial_position_m, Vec2(0.0, 0.5));
  EXPECT_DOUBLE_EQ(k.initial_angle_rad, 0.3);
  EXPECT_EQ(k.initial_velocity_mps, Vec2(1.0, -2.0));
  EXPECT_DOUBLE_EQ(k.initial_angular_velocity_radps, 4.0);
  EXPECT_DOUBLE_EQ(k.semi_axis_a_m, 4.0e-3);
  EXPECT_DOUBLE_EQ(k.semi_axis_b_m, 1.0e-3);
  EXPECT_DOUBLE_EQ(k.mass_kg, 2.0e-5);
  EXPECT_DOUBLE_EQ(k.youngs_modulus_Pa, 1.0e8);
  EXPECT_DOUBLE_EQ(k.poisson_ratio, 0.25);
  EXPECT_TRUE(k.pedicel.present);
  EXPECT_EQ(k.pedicel.p_WA_W, Vec2(0.0, 0.51));
  EXPECT_EQ(k.pedicel.p_KP_K, Vec2(1.0e-3, 0.0));
  EXPECT_DOUBLE_EQ(k.pedicel.stiffness_Npm, 150.0);
  EXPECT_DOUBLE_EQ(k.pedicel.damping_Nspm, 0.001);
  EXPECT_DOUBLE_EQ(k.pedicel.rest_length_m, 0.009);
  EXPECT_DOUBLE_EQ(k.pedicel.detachment_force_N, 2.0);

  ASSERT_EQ(m.obstacles.size(), 3u);
  EXPECT_EQ(m.obstacles[0].type, ObstacleType::kPlane);
  EXPECT_TRUE(m.obstacles[0].normal.isApprox(Vec2(0.0, 1.0)));  // normalised
  EXPECT_DOUBLE_EQ(m.obstacles[0].youngs_modulus_Pa, 1.0e11);
  EXPECT_DOUBLE_EQ(m.obstacles[0].poisson_ratio, 0.28);
  EXPECT_EQ(m.obstacles[1].type, ObstacleType::kCircle);
  EXPECT_EQ(m.obstacles[1].center_m, Vec2(0.0, -0.3));
  EXPECT_DOUBLE_EQ(m.obstacles[1].radius_m, 0.006);
  EXPECT_EQ(m.obstacles[2].type, ObstacleType::kSegment);
  EXPECT_EQ(m.obstacles[2].point_m, Vec2(-0.1, -0.4));
  EXPECT_EQ(m.obstacles[2].point_b_m, Vec2(0.1, -0.4));
  EXPECT_DOUBLE_EQ(m.obstacles[2].radius_m, 0.001);

  // Contact: given values, and per-kind defaults for the keys left out.
  const ContactParams& tk = m.contact[static_cast<int>(PairKind::kToothKernel)];
  const ContactParams& kk = m.contact[static_cast<int>(PairKind::kKernelKernel)];
  const ContactParams& ko = m.contact[static_cast<int>(PairKind::kKernelObstacle)];
  EXPECT_EQ(tk.law, ContactLaw::kRigid);
  EXPECT_DOUBLE_EQ(tk.restitution, 0.4);
  EXPECT_DOUBLE_EQ(tk.friction, 0.3);
  EXPECT_EQ(kk.law, ContactLaw::kCompliant);
  EXPECT_DOUBLE_EQ(kk.restitution, 0.34);
  EXPECT_EQ(ko.law, ContactLaw::kRigid);
  EXPECT_DOUBLE_EQ(ko.restitution, 0.47);
  EXPECT_DOUBLE_EQ(ko.friction, 0.2);
  EXPECT_DOUBLE_EQ(m.hc_min_impact_speed_mps, 0.05);

  EXPECT_EQ(m.gravity_mps2, Vec2(0.0, -9.8));
  EXPECT_EQ(m.integrator.type, IntegratorType::kTimeStepping);
  EXPECT_DOUBLE_EQ(m.integrator.tolerance, 1.0e-8);
  EXPECT_DOUBLE_EQ(m.integrator.dt_s, 2.0e-6);
  EXPECT_DOUBLE_EQ(m.integrator.theta, 0.6);
  EXPECT_DOUBLE_EQ(m.integrator.zeno_velocity_mps, 2.0e-3);
  EXPECT_DOUBLE_EQ(m.integrator.max_step_s, 5.0e-5);
  EXPECT_DOUBLE_EQ(m.duration_s, 0.01);
  EXPECT_DOUBLE_EQ(m.broadphase_margin_m, 0.003);
}

TEST(SceneLoader, MissingSectionsMeanEmptyOrDefault) {
  const Model m = modelFromYaml(YAML::Load("duration: 0.01\nteeth: []\nkernels:\n"));
  EXPECT_TRUE(m.teeth.empty());
  EXPECT_TRUE(m.kernels.empty());
  EXPECT_TRUE(m.obstacles.empty());
  EXPECT_DOUBLE_EQ(m.drum.radius_m, 0.20);
  EXPECT_EQ(m.n_dof, 0);
}

// ---------------------------------------------------------------------------------------------
// Refusals of values (each built by an override on the base scene).

TEST(SceneLoader, RefusesBadValues) {
  const std::vector<Refusal> cases = {
      // Non-positive sizes, moduli and times.
      {"kernels.0.mass=-1", {"kernels.0.mass", "in [1e-12, 1000]", "-1"}},
      {"kernels.0.mass=0", {"kernels.0.mass", "0"}},
      {"teeth.0.length=0", {"teeth.0.length", "in [1e-5, 10]", "0"}},
      {"teeth.0.diameter=-0.01", {"teeth.0.diameter", "-0.01"}},
      {"teeth.0.youngs_modulus=0", {"teeth.0.youngs_modulus", "0"}},
      {"teeth.0.density=-1140", {"teeth.0.density", "-1140"}},
      {"kernels.0.youngs_modulus=-2.8e8", {"kernels.0.youngs_modulus", "-2.8e8"}},
      {"drum.radius=0", {"drum.radius", "0"}},
      {"drum.max_acceleration=-5", {"drum.max_acceleration", "-5"}},
      {"integrator.dt=0", {"integrator.dt", "0"}},
      {"integrator.tolerance=-1e-9", {"integrator.tolerance", "-1e-9"}},
      {"integrator.max_step=0", {"integrator.max_step", "0"}},
      {"duration=0", {"duration", "0"}},
      {"obstacles.0={type: circle, center: [0, -0.3], radius: -0.005}",
       {"obstacles.0.radius", "-0.005"}},
      {"obstacles.0={type: segment, point: [0, -0.3], point_b: [0.1, -0.3], radius: -1}",
       {"obstacles.0.radius", "-1"}},
      {"obstacles.0={type: plane, point: [0, -0.5], normal: [0, 1], youngs_modulus: 0}",
       {"obstacles.0.youngs_modulus", "0"}},
      // NaN and infinity anywhere.
      {"kernels.0.mass=.nan", {"kernels.0.mass", "finite", ".nan"}},
      {"drum.speed=.inf", {"drum.speed", "finite", ".inf"}},
      {"drum.angle=-.inf", {"drum.angle", "-.inf"}},
      {"gravity=[0, .nan]", {"gravity", "finite", "[0, .nan]"}},
      {"kernels.0.velocity=[.inf, 0]", {"kernels.0.velocity", ".inf"}},
      {"contact.tooth_kernel.friction=.nan", {"contact.tooth_kernel.friction", ".nan"}},
      // Wrong types.
      {"kernels.0.mass=abc", {"kernels.0.mass", "expected a number", "abc"}},
      {"kernels.0.mass='2.8e-5'", {"kernels.0.mass", "expected a number", "\"2.8e-5\""}},
      {"kernels.0.mass=[1, 2]", {"kernels.0.mass", "expected a number", "[1, 2]"}},
      {"kernels.0.position=0.3", {"kernels.0.position", "list of 2", "0.3"}},
      {"kernels.0.position=[0.1, 0.2, 0.3]", {"kernels.0.position", "[0.1, 0.2, 0.3]"}},
      {"kernels.0.position=[0.1, x]", {"kernels.0.position", "[0.1, x]"}},
      {"teeth.0.modes=2.5", {"teeth.0.modes", "integer", "2.5"}},
      {"teeth.0.modes=-1", {"teeth.0.modes", "-1"}},
      {"teeth.0.modes=65", {"teeth.0.modes", "65"}},
      {"teeth.0.modes=automatic", {"teeth.0.modes", "automatic"}},
      {"teeth.0.static_correction=yes", {"teeth.0.static_correction", "yes"}},
      {"teeth.0.stations=1", {"teeth.0.stations", "in [2, 65]", "1"}},
      {"drum=5", {"drum", "expected a mapping", "5"}},
      {"teeth={length: 0.06}", {"teeth", "expected a list"}},
      // Semi-axes.
      {"kernels.0.semi_axes=[1.0e-3, 2.0e-3]",
       {"kernels.0.semi_axes", "a must be >= b", "[1.0e-3, 2.0e-3]"}},
      {"kernels.0.semi_axes=[1.0e-3, 0]", {"kernels.0.semi_axes", "in [1e-6, 1]", "[1.0e-3, 0]"}},
      // Ratios and coefficients.
      {"contact.tooth_kernel.restitution=1.5", {"contact.tooth_kernel.restitution", "1.5"}},
      {"contact.kernel_obstacle.restitution=-0.1", {"contact.kernel_obstacle.restitution", "-0.1"}},
      {"contact.kernel_kernel.friction=-0.2", {"contact.kernel_kernel.friction", "-0.2"}},
      {"teeth.0.damping_ratio=-0.01", {"teeth.0.damping_ratio", "-0.01"}},
      {"teeth.0.poisson_ratio=0.5", {"teeth.0.poisson_ratio", "0.5"}},
      {"integrator.theta=0.4", {"integrator.theta", "0.4"}},
      {"broadphase_margin=-0.001", {"broadphase_margin", "-0.001"}},
      {"deflection_validity=0", {"deflection_validity", "0"}},
      // Words.
      {"contact.tooth_kernel.law=elastic", {"contact.tooth_kernel.law", "elastic", "compliant"}},
      {"integrator.type=implicit", {"integrator.type", "implicit", "event_driven"}},
      {"obstacles.0.type=sphere", {"obstacles.0.type", "sphere", "plane"}},
      // Obstacles and pedicels.
      {"obstacles.0.normal=[0, 0]", {"obstacles.0.normal", "zero", "[0, 0]"}},
      {"obstacles.0={type: plane, point: [0, -0.5], normal: [0, 1], center: [0, 0]}",
       {"obstacles.0.center", "plane obstacle"}},
      {"obstacles.0={type: circle, radius: 0.01}", {"obstacles.0.center", "missing"}},
      {"obstacles.0={point: [0, 0]}", {"obstacles.0.type", "missing"}},
      {"kernels.0.pedicel={stiffness: 100}", {"kernels.0.pedicel.anchor", "missing"}},
      {"kernels.0.pedicel={anchor: [0, 0.26], damping: -1}", {"kernels.0.pedicel.damping", "-1"}},
      {"kernels.0.pedicel={anchor: [0, 0.26], stiffness: 0}", {"kernels.0.pedicel.stiffness", "0"}},
      {"kernels.0.pedicel={anchor: [0, 0.26], attach_point: [0.01, 0]}",
       {"kernels.0.pedicel.attach_point", "inside the kernel", "[0.01, 0]"}},
  };
  for (const Refusal& c : cases) expectRefused(refusalWithOverride(c.change), c);
}

TEST(SceneLoader, RefusesOverlapsAtStart) {
  const std::vector<Refusal> cases = {
      // The tooth lies on the X axis from x = 0.20 to 0.26 (radius 5 mm).
      {"kernels.0.position=[0.23, 0.004]", {"kernels.0.position", "teeth.0", "[0.23, 0.004]"}},
      {"kernels=[{position: [0, 0.245]}, {position: [0.004, 0.246]}]",
       {"kernels.1.position", "kernels.0", "[0.004, 0.246]"}},
      {"kernels.0.position=[0, -0.5]", {"kernels.0.position", "obstacles.0", "[0, -0.5]"}},
      {"obstacles.0={type: circle, center: [0.0, 0.25], radius: 0.005}",
       {"kernels.0.position", "obstacles.0"}},
      {"obstacles.0={type: segment, point: [-0.01, 0.245], point_b: [0.01, 0.245], radius: 0.001}",
       {"kernels.0.position", "obstacles.0"}},
      // With the drum turned by 90 degrees the tooth points along +Y, through the kernel.
      {"drum.angle=1.5707963267948966", {"kernels.0.position", "teeth.0"}},
  };
  for (const Refusal& c : cases) expectRefused(refusalWithOverride(c.change), c);
}

// ---------------------------------------------------------------------------------------------
// Refusals of keys (written as YAML, since an override cannot create an unknown key).

TEST(SceneLoader, RefusesUnknownKeysWithSuggestion) {
  const std::vector<Refusal> cases = {
      {"teeth: [{lenght: 0.06}]", {"teeth.0.lenght", "unknown key", "did you mean 'length'?"}},
      {"gravty: [0, -9.81]", {"gravty", "did you mean 'gravity'?"}},
      {"drum: {sped: 80}", {"drum.sped", "did you mean 'speed'?"}},
      {"drum: {flux_capacitor: 1}", {"drum.flux_capacitor", "known keys: radius"}},
      {"kernels: [{position: [0, 0.3], mas: 1.0e-5}]", {"kernels.0.mas", "'mass'"}},
      {"kernels: [{position: [0, 0.3], pedicel: {anchr: [0, 0.31]}}]",
       {"kernels.0.pedicel.anchr", "'anchor'"}},
      {"obstacles: [{type: plane, point: [0, -1], normal: [0, 1], normale: [0, 1]}]",
       {"obstacles.0.normale", "'normal'"}},
      {"contact: {tooth_kernel: {restitutoin: 0.5}}",
       {"contact.tooth_kernel.restitutoin", "'restitution'"}},
      {"contact: {tooth_kernal: {restitution: 0.5}}", {"contact.tooth_kernal", "'tooth_kernel'"}},
      {"integrator: {dtt: 1.0e-6}", {"integrator.dtt", "'dt'"}},
      {"duration: 0.01\nduration: 0.02", {"duration", "duplicate"}},
      {"[1, 2]", {"scene", "top level"}},
  };
  for (const Refusal& c : cases) {
    SCOPED_TRACE(c.change);
    expectRefused(refusal(YAML::Load(c.change)), c);
  }
}

// ---------------------------------------------------------------------------------------------
// Overrides.

TEST(SceneLoader, OverridesSetValues) {
  const Model m = baseWith({"teeth.0.modes=0", "drum.speed=100", "kernels.0.position=[0.01,0.3]"});
  EXPECT_EQ(m.teeth[0].n_modes, 0);
  EXPECT_DOUBLE_EQ(m.drum.initial_speed_radps, 100.0);
  EXPECT_EQ(m.kernels[0].initial_position_m, Vec2(0.01, 0.3));
  EXPECT_EQ(m.n_dof, 3);
}

TEST(SceneLoader, OverridesCreateKnownSections) {
  // integrator and contact are absent from the base scene.
  const Model m =
      baseWith({"integrator.dt=2.0e-6", "integrator.type=time_stepping",
                "contact.tooth_kernel.law=rigid", " duration = 0.005 ",
                "kernels.0.pedicel={anchor: [0.0, 0.26]}", "kernels.0.pedicel.stiffness=120"});
  EXPECT_DOUBLE_EQ(m.integrator.dt_s, 2.0e-6);
  EXPECT_EQ(m.integrator.type, IntegratorType::kTimeStepping);
  EXPECT_EQ(m.contact[0].law, ContactLaw::kRigid);
  EXPECT_DOUBLE_EQ(m.duration_s, 0.005);
  EXPECT_TRUE(m.kernels[0].pedicel.present);
  EXPECT_DOUBLE_EQ(m.kernels[0].pedicel.stiffness_Npm, 120.0);
}

TEST(SceneLoader, RefusesBadOverrides) {
  const std::vector<Refusal> cases = {
      {"teeth.3.modes=0", {"teeth.3", "out of range", "1 entry", "teeth.3.modes=0"}},
      {"obstacles.1.type=plane", {"obstacles.1", "out of range"}},
      {"teeth.0.lenght=0.05", {"teeth.0.lenght", "did you mean 'length'?"}},
      {"drum.sped=5", {"drum.sped", "'speed'"}},
      {"kernels.0.pedicel.stiffness=150", {"kernels.0.pedicel", "absent"}},
      {"teeth.x.length=0.05", {"teeth", "index", "'x'"}},
      {"drum.radius.x=1", {"drum.radius", "value"}},
      {"drum.speed", {"drum.speed", "key.path=value"}},
      {"drum.speed=", {"drum.speed", "empty value"}},
      {"=5", {"empty key path"}},
      {"drum..speed=5", {"empty key path component"}},
      {"drum.speed=[1,", {"drum.speed", "not valid YAML"}},
  };
  for (const Refusal& c : cases) expectRefused(refusalWithOverride(c.change), c);

  // A key list under a missing list: the list has no entries.
  YAML::Node root = YAML::Load("drum: {radius: 0.2}");
  try {
    applyOverride(&root, "kernels.0.mass=1");
    ADD_FAILURE() << "accepted kernels.0.mass on a scene without kernels";
  } catch (const SceneError& e) {
    EXPECT_NE(std::string(e.what()).find("kernels.0"), std::string::npos) << e.what();
  }
}

TEST(SceneLoader, FailedOverrideLeavesTreeUnchanged) {
  YAML::Node root = YAML::Load(kBaseScene);
  const std::string before = YAML::Dump(root);
  EXPECT_THROW(applyOverride(&root, "integrator.bogus=1"), SceneError);
  EXPECT_EQ(YAML::Dump(root), before);
}

// applyOverride works in place (no copy of the tree): a "*" whose last item is refused must
// leave the items before it unchanged too, and the message names that item.
TEST(SceneLoader, FailedStarOverrideLeavesEveryItemUnchanged) {
  YAML::Node root = YAML::Load(R"(
drum: {radius: 0.20, speed: 83.78}
teeth: [{mount_angle: 0.0, length: 0.06}]
kernels: [{position: [0.0, 0.245], pedicel: {anchor: [0.0, 0.255]}}, {position: [0.0, 0.3]}]
)");
  const std::string before = YAML::Dump(root);
  try {
    applyOverride(&root, "kernels.*.pedicel.anchor=[0.0, 0.26]");
    ADD_FAILURE() << "accepted a pedicel anchor on a kernel without pedicel";
  } catch (const SceneError& e) {
    EXPECT_NE(std::string(e.what()).find("kernels.1.pedicel: is absent"), std::string::npos)
        << e.what();
    EXPECT_NE(std::string(e.what()).find("override 'kernels.1.pedicel.anchor=[0.0, 0.26]'"),
              std::string::npos)
        << e.what();
  }
  EXPECT_EQ(YAML::Dump(root), before);
  // Nor does a refused list index or unknown key below a section that would be created.
  EXPECT_THROW(applyOverride(&root, "kernels.2.mass=1"), SceneError);
  EXPECT_THROW(applyOverride(&root, "integrator.bogus=1"), SceneError);
  EXPECT_EQ(YAML::Dump(root), before);
}

// A --set value is the node YAML::Load gives for its text, whether the loader takes the
// shortcut for number-like words or parses it (same scalar, tag, type and dump).
TEST(SceneLoader, OverrideValuesAreTheParsedYaml) {
  const char* const texts[] = {"62.83185307179586",
                               "0.052",
                               "-0.01",
                               "+3",
                               ".5",
                               "1e-5",
                               "2.06E11",
                               "0x1F",
                               "1_000",
                               "7",
                               "-.inf",
                               ".nan",
                               "null",
                               "~",
                               "-",
                               "---",
                               "...",
                               "true",
                               "\"5\"",
                               "'5'",
                               "[1, 2]",
                               "{a: 1}",
                               "5 # c",
                               "fast",
                               "-5-",
                               "1.2.3",
                               "- 5"};
  for (const char* text : texts) {
    SCOPED_TRACE(text);
    YAML::Node set = YAML::Load(kBaseScene);
    YAML::Node loaded = YAML::Load(kBaseScene);
    applyOverride(&set, std::string("drum.speed=") + text);
    loaded["drum"]["speed"] = YAML::Load(text);
    EXPECT_EQ(YAML::Dump(set), YAML::Dump(loaded));
    const YAML::Node a = set["drum"]["speed"], b = loaded["drum"]["speed"];
    EXPECT_EQ(a.Type(), b.Type());
    EXPECT_EQ(a.Tag(), b.Tag());
    if (a.IsScalar()) {
      EXPECT_EQ(a.Scalar(), b.Scalar());
    }
  }
}

// The items a "*" sets do not share one value node: a value changed in place afterwards (as
// --check's restitution does) changes one item only; a missing section is created; the tree
// changes in place, a copy made before does not.
TEST(SceneLoader, OverridesInPlaceKeepItemsApart) {
  YAML::Node root = YAML::Load(R"(
drum: {radius: 0.20, speed: 83.78}
teeth: [{mount_angle: 0.0, length: 0.06}, {mount_angle: 3.14, length: 0.06}]
kernels: [{position: [0.0, 0.245]}]
)");
  const YAML::Node copy = YAML::Clone(root);
  applyOverride(&root, "teeth.*.length=0.05");
  root["teeth"][0]["length"] = 0.07;
  EXPECT_EQ(root["teeth"][0]["length"].as<double>(), 0.07);
  EXPECT_EQ(root["teeth"][1]["length"].as<double>(), 0.05);
  applyOverride(&root, "teeth.1.length=0.055");
  EXPECT_EQ(root["teeth"][1]["length"].as<double>(), 0.055);
  EXPECT_EQ(root["teeth"][0]["length"].as<double>(), 0.07);
  applyOverride(&root, "integrator.type=event_driven");
  EXPECT_EQ(root["integrator"]["type"].as<std::string>(), "event_driven");
  EXPECT_EQ(copy["teeth"][0]["length"].as<double>(), 0.06);
  EXPECT_FALSE(copy["integrator"].IsDefined());
  // An empty tree becomes a mapping.
  YAML::Node empty;
  applyOverride(&empty, "drum.speed=80");
  EXPECT_EQ(YAML::Dump(empty), "drum:\n  speed: 80");
}

// ---------------------------------------------------------------------------------------------
// Files.

std::string writeTemp(const std::string& name, const std::string& text) {
  const std::string path = testing::TempDir() + name;
  std::ofstream(path) << text;
  return path;
}

TEST(SceneLoader, LoadSceneAppliesOverridesAndNamesTheFile) {
  const std::string path = writeTemp("scene_ok.yaml", kBaseScene);
  EXPECT_EQ(loadScene(path, {"teeth.0.modes=2"}).teeth[0].n_modes, 2);
  try {
    loadScene(path, {"kernels.0.mass=-1"});
    ADD_FAILURE() << "accepted a negative mass";
  } catch (const SceneError& e) {
    EXPECT_NE(std::string(e.what()).find(path + ": kernels.0.mass"), std::string::npos) << e.what();
  }
}

TEST(SceneLoader, ReportsMissingFileAndSyntaxErrors) {
  try {
    loadSceneYaml("/nonexistent/scene.yaml");
    ADD_FAILURE() << "opened a missing file";
  } catch (const SceneError& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent/scene.yaml"), std::string::npos);
  }
  const std::string path = writeTemp("scene_bad.yaml", "drum: {radius: 0.2}\nteeth: [\n");
  try {
    loadSceneYaml(path);
    ADD_FAILURE() << "parsed a broken file";
  } catch (const SceneError& e) {
    EXPECT_NE(std::string(e.what()).find(path + ":"), std::string::npos) << e.what();
  }
}

TEST(SceneLoader, ShippedDefaultSceneLoads) {
  const std::string path = std::string(THRESHING_SIM_SOURCE_DIR) + "/config/default_scene.yaml";
  if (!std::ifstream(path)) GTEST_SKIP() << path << " not present";
  const Model m = loadScene(path);
  EXPECT_TRUE(m.compiled);
  EXPECT_FALSE(m.teeth.empty());
}

// Every schema key has a row in the scene file reference (docs/scene_reference.md), and every row
// is a key.
TEST(SceneLoader, ReferenceDocumentsEveryKey) {
  const std::string path = std::string(THRESHING_SIM_SOURCE_DIR) + "/docs/scene_reference.md";
  std::ifstream file(path);
  ASSERT_TRUE(file) << path;
  std::vector<std::string> documented;
  bool inside = false;
  for (std::string line; std::getline(file, line);) {
    if (line.rfind("<!-- scene-reference -->", 0) == 0) inside = true;
    if (line.rfind("<!-- scene-reference-end", 0) == 0) inside = false;
    if (!inside || line.rfind("| `", 0) != 0) continue;
    const size_t end = line.find('`', 3);
    documented.push_back(line.substr(3, end - 3));
  }
  EXPECT_EQ(documented, sceneKeyPaths());
}

// The schema's defaults are the loader's: for every key with a default, a scene that leaves the
// key out and one that sets it to the default the reference prints load to the same Model.
// Minimal scenes: a tooth, a kernel on a pedicel and one obstacle of each type; a tooth and a
// stream (stream.* keys).
const char kMinimalScene[] = R"(
teeth: [{}]
kernels: [{position: [0.0, 0.3], pedicel: {anchor: [0.0, 0.31]}}]
obstacles:
  - {type: plane, point: [0.0, -0.5], normal: [0.0, 1.0]}
  - {type: circle, center: [0.3, -0.3]}
  - {type: segment, point: [-0.4, -0.4], point_b: [-0.3, -0.4]}
)";
const char kMinimalStream[] = R"(
teeth: [{}]
stream: {count: 3, rate: 2000}
)";

const char kMinimalFeed[] = R"(
teeth: [{}]
integrator: {islands: false}
feed: {rate: 100, inlet: -0.2, exit: 0.2}
)";

// Everything a scene key sets in a Model (and its damage thresholds and feed), printed exactly.
std::string fingerprint(const YAML::Node& root) {
  FeedSpec f;
  const Model m = modelFromYaml(root, nullptr, &f);
  const DamageThresholds dmg = damageFromYaml(root);
  std::ostringstream o;
  o << std::setprecision(17);
  const auto v2 = [&](const Vec2& v) { o << v.x() << ',' << v.y() << ' '; };
  o << m.drum.radius_m << ' ' << m.drum.initial_speed_radps << ' ' << m.drum.initial_angle_rad
    << ' ' << m.drum.max_acceleration_radps2 << '\n';
  for (const ToothModel& t : m.teeth)
    o << t.mount_angle_rad << ' ' << t.length_m << ' ' << t.diameter_m << ' ' << t.youngs_modulus_Pa
      << ' ' << t.poisson_ratio << ' ' << t.density_kgpm3 << ' ' << t.n_modes << ' '
      << t.damping_ratio << ' ' << t.n_stations << ' ' << static_cast<int>(t.beam_model) << ' '
      << t.static_correction << '\n';
  for (const KernelModel& k : m.kernels) {
    v2(k.initial_position_m);
    v2(k.initial_velocity_mps);
    o << k.initial_angle_rad << ' ' << k.initial_angular_velocity_radps << ' ' << k.semi_axis_a_m
      << ' ' << k.semi_axis_b_m << ' ' << k.mass_kg << ' ' << k.youngs_modulus_Pa << ' '
      << k.poisson_ratio << ' ' << k.pedicel.present << ' ';
    v2(k.pedicel.p_WA_W);
    v2(k.pedicel.p_KP_K);
    o << k.pedicel.stiffness_Npm << ' ' << k.pedicel.damping_Nspm << ' ' << k.pedicel.rest_length_m
      << ' ' << k.pedicel.detachment_force_N << '\n';
  }
  for (const ObstacleModel& b : m.obstacles)
    o << b.radius_m << ' ' << b.youngs_modulus_Pa << ' ' << b.poisson_ratio << '\n';
  for (const ContactParams& c : m.contact)
    o << static_cast<int>(c.law) << ' ' << c.restitution << ' ' << c.friction << '\n';
  v2(m.gravity_mps2);
  const IntegratorParams& i = m.integrator;
  o << m.hc_min_impact_speed_mps << ' ' << static_cast<int>(i.type) << ' ' << i.tolerance << ' '
    << i.dt_s << ' ' << i.theta << ' ' << i.zeno_velocity_mps << ' ' << i.max_step_s << ' '
    << i.exact_free_teeth << ' ' << i.modal_split << ' ' << i.islands << ' ' << m.duration_s << ' '
    << m.broadphase_margin_m << ' ' << m.macro_collision_gap_s << ' '
    << m.deflection_validity_fraction << ' ' << dmg.plastic_force_N << ' ' << dmg.fracture_force_N;
  o << '\n'
    << f.rate_per_s << ' ' << f.mat_speed_mps << ' ' << f.start_s << ' ' << f.seed << ' '
    << f.capacity << ' ' << f.inlet_x_m << ' ' << f.exit_x_m << ' ' << f.anchor_y_m << ' '
    << f.mat_thickness_m << ' ' << f.grate_y_m << ' ' << f.bound_radius_m << ' '
    << f.pedicel_length_m << ' ' << f.position_scatter_m << ' ' << f.angle_scatter_rad << ' ';
  v2(f.mass_kg);
  v2(f.detach_N);
  return o.str();
}

TEST(SceneLoader, SchemaDefaultsAreTheLoadersDefaults) {
  int checked = 0;
  for (const auto& [path, value] : sceneSchemaDefaults()) {
    if (value.empty() || value == "[]" || value == "absent" || value == "derived" ||
        value.rfind("required", 0) == 0)
      continue;
    SCOPED_TRACE(path + " = " + value);
    const bool stream = path.rfind("stream.", 0) == 0;
    const bool feed = path.rfind("feed.", 0) == 0;
    const YAML::Node absent = YAML::Load(stream ? kMinimalStream
                                         : feed ? kMinimalFeed
                                                : kMinimalScene);
    YAML::Node set = YAML::Clone(absent);
    std::string written = path;
    if (path == "obstacles.*.radius") written = "obstacles.1.radius";  // circles and segments
    applyOverride(&set, written + "=" + value);
    EXPECT_EQ(fingerprint(set), fingerprint(absent));
    ++checked;
  }
  EXPECT_GT(checked, 60);
  // The fingerprint sees a key set away from its default (so the comparison can fail).
  YAML::Node moved = YAML::Load(kMinimalScene);
  applyOverride(&moved, "teeth.0.poisson_ratio=0.36");
  EXPECT_NE(fingerprint(moved), fingerprint(YAML::Load(kMinimalScene)));
}

// ---------------------------------------------------------------------------------------------
// Result writers.

class ReportTest : public testing::Test {
 protected:
  void SetUp() override {
    model_ = baseWith({"kernels.0.pedicel={anchor: [0.0, 0.255]}"});
    resetData(model_, &data_);
  }
  Model model_;
  Data data_;
};

TEST_F(ReportTest, TraceHeaderMatchesRow) {
  std::ostringstream header, row;
  writeTraceHeader(header, model_);
  writeTraceRow(row, model_, data_);
  EXPECT_EQ(header.str().rfind("t_s,theta_rad,omega_radps,k0_x_m,k0_y_m,k0_psi_rad,", 0), 0u);
  EXPECT_NE(header.str().find(",tooth0_tip_deflection_m,tooth0_q0,"), std::string::npos);
  const auto commas = [](const std::string& s) { return std::count(s.begin(), s.end(), ','); };
  EXPECT_EQ(commas(header.str()), commas(row.str()));
  // Drum (3), kernel (6), tip deflection (1), one column per mode (modes: auto here).
  EXPECT_EQ(commas(header.str()), 3 + 6 + 1 + model_.teeth[0].n_modes - 1);
}

TEST_F(ReportTest, EventRowsMatchHeader) {
  ContactEvent e;
  e.t_s = 1e-3;
  e.is_impact = true;
  std::ostringstream header, rows;
  writeEventsHeader(header);
  writeEventRows(rows, {e, e});
  const auto commas = [](const std::string& s) { return std::count(s.begin(), s.end(), ','); };
  EXPECT_EQ(commas(rows.str()), 2 * commas(header.str()));
  EXPECT_EQ(rows.str().rfind("0.001,tooth_kernel,0,0,separated,impact,1,", 0), 0u);
}

TEST_F(ReportTest, SummaryJsonHasKeysAndNoNaN) {
  data_.stats.peak_normal_force_N = std::nan("");
  std::ostringstream out;
  writeSummaryJson(out, model_, data_, "ok", 1.5, 2.0);
  const std::string json = out.str();
  for (const char* key : {"\"status\"",
                          "\"sim_time_s\"",
                          "\"wall_time_s\": 1.5",
                          "\"steps\"",
                          "\"impacts\"",
                          "\"contact_episodes\"",
                          "\"peak_tangential_force_N\"",
                          "\"time_of_peak_normal_s\"",
                          "\"time_of_peak_tangential_s\"",
                          "\"total_normal_impulse_Ns\"",
                          "\"max_penetration_m\"",
                          "\"max_energy_gain_at_impact_J\"",
                          "\"energy_initial_J\"",
                          "\"energy_final_J\": 2",
                          "\"drive_work_J\"",
                          "\"numerical_recoveries\"",
                          "\"max_tip_deflection_ratio\"",
                          "\"warnings\": []",
                          "\"kernels\"",
                          "\"position_m\": [0, 0.24",
                          "\"angle_rad\"",
                          "\"velocity_mps\"",
                          "\"angular_velocity_radps\"",
                          "\"detached\": false",
                          "\"detach_time_s\": null"}) {
    EXPECT_NE(json.find(key), std::string::npos) << key << " missing in\n" << json;
  }
  EXPECT_NE(json.find("\"peak_normal_force_N\": null"), std::string::npos) << json;
  EXPECT_NE(json.find("non-finite values written as null: peak_normal_force_N"), std::string::npos)
      << json;
  EXPECT_EQ(json.find("nan"), std::string::npos) << json;
}

TEST_F(ReportTest, SummaryJsonPrintsFullPrecision) {
  data_.t_s = 0.1;
  std::ostringstream out;
  writeSummaryJson(out, model_, data_, "ok", 0.0, 0.0);
  EXPECT_NE(out.str().find("\"sim_time_s\": 0.10000000000000001"), std::string::npos);
}

TEST_F(ReportTest, HumanSummaryIsOneParagraph) {
  data_.stats.peak_normal_force_N = 41.2;
  data_.stats.warnings = {"rigid law with a short-period mode"};
  std::ostringstream out;
  printSummary(out, model_, data_, "ok", 1.25, 0.0);
  EXPECT_NE(out.str().find("peak normal force 41.2 N"), std::string::npos) << out.str();
  EXPECT_NE(out.str().find("1 tooth and 1 kernel"), std::string::npos) << out.str();
  EXPECT_NE(out.str().find("warning: rigid law"), std::string::npos) << out.str();
}

}  // namespace
}  // namespace threshing_sim
