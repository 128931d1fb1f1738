// Tests of the scene features behind the threshing scenes: the kernel stream, wildcard overrides
// and override files, the damage thresholds and the macro-collision gap.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <string>
#include <vector>

#include "threshing_sim/core/constants.h"
#include "threshing_sim/scene/scene_loader.h"

namespace threshing_sim {
namespace {

// Two teeth 90 degrees apart and a stream of four kernels ahead of tooth 0.
const char kStreamScene[] = R"(
drum: {radius: 0.14, speed: 83.78, angle: -2.0}
teeth:
  - {mount_angle: 0.0, length: 0.06, modes: 2}
  - {mount_angle: 1.5707963267948966, length: 0.06, modes: 2}
stream: {count: 4, rate: 2000.0, start: 0.001, seed: 3, depth: 0.005, position_scatter: 0.001,
         angle_scatter: 0.4, pedicel_length: 0.003, detachment_force_range: [0.5, 2.0]}
)";

Model load(const char* text, const std::vector<std::string>& overrides = {}) {
  YAML::Node root = YAML::Load(text);
  for (const std::string& a : overrides) applyOverride(&root, a);
  return modelFromYaml(root);
}

std::string refusal(const char* text, const std::vector<std::string>& overrides) {
  try {
    load(text, overrides);
  } catch (const SceneError& e) {
    return e.what();
  }
  return "";
}

// ---------------------------------------------------------------------------------------------
// Kernel stream.

TEST(KernelStream, PlacesKernelsOnToothPathWithPedicels) {
  const Model m = load(kStreamScene);
  ASSERT_EQ(m.kernels.size(), 4u);
  const double omega = 83.78, r_nominal = 0.14 + 0.06 - 0.005;
  for (size_t j = 0; j < m.kernels.size(); ++j) {
    const KernelModel& k = m.kernels[j];
    // Centre within the scatter of its nominal place: tooth 0's angle at start + j / rate.
    const double phi_nominal = -2.0 + omega * (0.001 + j / 2000.0);
    const double r = k.initial_position_m.norm();
    const double phi = std::atan2(k.initial_position_m.y(), k.initial_position_m.x());
    EXPECT_NEAR(r, r_nominal, 0.001 + 1e-12) << "kernel " << j;
    EXPECT_NEAR(phi * r, phi_nominal * r, 0.001 + 1e-9) << "kernel " << j;
    EXPECT_NEAR(k.initial_angle_rad, phi, 0.4 + 0.001 / r) << "kernel " << j;
    // Pedicel: unloaded, at the outer end, anchored 3 mm further along the long axis.
    ASSERT_TRUE(k.pedicel.present);
    EXPECT_EQ(k.pedicel.p_KP_K, Vec2(k.semi_axis_a_m, 0.0));
    EXPECT_NEAR(k.pedicel.rest_length_m, 0.003, 1e-12);
    EXPECT_GE(k.pedicel.detachment_force_N, 0.5);
    EXPECT_LE(k.pedicel.detachment_force_N, 2.0);
    EXPECT_GE(k.mass_kg, 2.4e-5);
    EXPECT_LE(k.mass_kg, 3.1e-5);
  }
}

TEST(KernelStream, IsDeterministicFromTheSeed) {
  const Model a = load(kStreamScene), b = load(kStreamScene);
  const Model c = load(kStreamScene, {"stream.seed=4"});
  ASSERT_EQ(a.kernels.size(), c.kernels.size());
  bool differs = false;
  for (size_t j = 0; j < a.kernels.size(); ++j) {
    EXPECT_EQ(a.kernels[j].initial_position_m, b.kernels[j].initial_position_m);
    EXPECT_EQ(a.kernels[j].initial_angle_rad, b.kernels[j].initial_angle_rad);
    EXPECT_EQ(a.kernels[j].mass_kg, b.kernels[j].mass_kg);
    differs = differs || a.kernels[j].initial_position_m != c.kernels[j].initial_position_m;
  }
  EXPECT_TRUE(differs) << "seeds 3 and 4 gave the same kernels";
}

TEST(KernelStream, AppendsAfterListedKernels) {
  const Model m = load(kStreamScene, {"kernels=[{position: [0.0, 0.5]}]"});
  ASSERT_EQ(m.kernels.size(), 5u);
  EXPECT_EQ(m.kernels[0].initial_position_m, Vec2(0.0, 0.5));
  EXPECT_FALSE(m.kernels[0].pedicel.present);
  EXPECT_TRUE(m.kernels[4].pedicel.present);
}

TEST(KernelStream, RefusesStreamsThatDoNotFit) {
  // Twelve kernels at 100/s span 0.11 s of a drum that turns 90 degrees in 0.019 s.
  const std::string too_long = refusal(kStreamScene, {"stream.count=12", "stream.rate=100"});
  EXPECT_NE(too_long.find("stream.rate"), std::string::npos) << too_long;
  EXPECT_NE(too_long.find("next tooth"), std::string::npos) << too_long;
  // A still drum meets nothing; kernels packed closer than their size cannot be placed.
  EXPECT_NE(refusal(kStreamScene, {"drum.speed=0"}).find("drum.speed"), std::string::npos);
  const std::string packed =
      refusal(kStreamScene, {"stream.rate=200000", "stream.position_scatter=0"});
  EXPECT_NE(packed.find("overlaps"), std::string::npos) << packed;
  // A missing required key and a bad range name the key.
  EXPECT_NE(refusal("stream: {rate: 10}\nteeth: [{}]", {}).find("stream.count"), std::string::npos);
  EXPECT_NE(refusal(kStreamScene, {"stream.mass_range=[3.0e-5, 2.0e-5]"}).find("stream.mass_range"),
            std::string::npos);
}

// ---------------------------------------------------------------------------------------------
// Overrides: wildcards and override files.

TEST(Overrides, WildcardSetsEveryListItem) {
  const Model m = load(kStreamScene, {"teeth.*.modes=0", "teeth.*.youngs_modulus=2.06e11"});
  for (const ToothModel& t : m.teeth) {
    EXPECT_EQ(t.n_modes, 0);
    EXPECT_DOUBLE_EQ(t.youngs_modulus_Pa, 2.06e11);
  }
  // An empty list has nothing to set, and a bad value leaves the tree unchanged.
  YAML::Node root = YAML::Load("teeth: []");
  EXPECT_THROW(applyOverride(&root, "teeth.*.modes=0"), SceneError);
  root = YAML::Load(kStreamScene);
  EXPECT_THROW(applyOverride(&root, "teeth.*.nodes=0"), SceneError);
  EXPECT_EQ(root["teeth"][0]["modes"].as<int>(), 2);
}

TEST(Overrides, FileHoldsKeyPathsAndValues) {
  const std::string path = testing::TempDir() + "variant.yaml";
  std::ofstream(path) << "# a tooth variant\n"
                         "teeth.*.modes: 0   # rigid\n"
                         "teeth.1.length: 0.05\n"
                         "contact.tooth_kernel: {friction: 0.4}\n";
  const std::vector<std::string> overrides = overridesFromFile(path);
  ASSERT_EQ(overrides.size(), 3u);
  EXPECT_EQ(overrides[0], "teeth.*.modes=0");
  const Model m = load(kStreamScene, overrides);
  EXPECT_EQ(m.teeth[0].n_modes, 0);
  EXPECT_DOUBLE_EQ(m.teeth[1].length_m, 0.05);
  EXPECT_DOUBLE_EQ(m.contact[static_cast<int>(PairKind::kToothKernel)].friction, 0.4);

  std::ofstream(path) << "- not a mapping\n";
  EXPECT_THROW(overridesFromFile(path), SceneError);
  std::remove(path.c_str());
}

// ---------------------------------------------------------------------------------------------
// Outcome settings.

TEST(OutcomeSettings, DamageAndMacroCollisionGap) {
  const YAML::Node defaults = YAML::Load("teeth: []");
  EXPECT_DOUBLE_EQ(damageFromYaml(defaults).plastic_force_N, 139.0);
  EXPECT_DOUBLE_EQ(damageFromYaml(defaults).fracture_force_N, 146.0);
  EXPECT_DOUBLE_EQ(modelFromYaml(defaults).macro_collision_gap_s, 2e-3);

  const YAML::Node set =
      YAML::Load("damage: {plastic_force: 100, fracture_force: 120}\nmacro_collision_gap: 1e-4");
  EXPECT_DOUBLE_EQ(damageFromYaml(set).plastic_force_N, 100.0);
  EXPECT_DOUBLE_EQ(damageFromYaml(set).fracture_force_N, 120.0);
  EXPECT_DOUBLE_EQ(modelFromYaml(set).macro_collision_gap_s, 1e-4);

  const std::string swapped = refusal("damage: {plastic_force: 150, fracture_force: 140}", {});
  EXPECT_NE(swapped.find("damage.fracture_force"), std::string::npos) << swapped;
  EXPECT_NE(refusal("macro_collision_gap: 0", {}).find("macro_collision_gap"), std::string::npos);
}

}  // namespace
}  // namespace threshing_sim
