// Unit tests of ToothCache (tooth_cache.h): a model compiled through the cache is bit for bit
// the model compiled without it, whether the tooth came from the cache or not, and a change in
// any input of compileTooth misses the cache.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstring>
#include <functional>
#include <set>
#include <string>
#include <vector>

#include "sim_test_util.h"
#include "threshing_sim/core/model.h"
#include "threshing_sim/core/tooth_cache.h"

namespace threshing_sim {
namespace {

using testutil::defaultSceneModel;
using testutil::nylonTooth;

bool same(double a, double b) { return std::memcmp(&a, &b, sizeof(double)) == 0; }
bool same(int a, int b) { return a == b; }
bool same(bool a, bool b) { return a == b; }

template <typename Derived>
bool same(const Eigen::MatrixBase<Derived>& a, const Eigen::MatrixBase<Derived>& b) {
  return a.rows() == b.rows() && a.cols() == b.cols() &&
         (a.size() == 0 || std::memcmp(a.derived().data(), b.derived().data(),
                                       sizeof(double) * static_cast<size_t>(a.size())) == 0);
}

bool same(const std::vector<MatX>& a, const std::vector<MatX>& b) {
  if (a.size() != b.size()) return false;
  for (size_t i = 0; i < a.size(); ++i)
    if (!same(a[i], b[i])) return false;
  return true;
}

bool same(const std::shared_ptr<const std::vector<double>>& a,
          const std::shared_ptr<const std::vector<double>>& b) {
  if (!a || !b) return !a && !b;
  return a->size() == b->size() &&
         (a->empty() || std::memcmp(a->data(), b->data(), sizeof(double) * a->size()) == 0);
}

bool same(const std::vector<ResidualPanel>& a, const std::vector<ResidualPanel>& b) {
  if (a.size() != b.size()) return false;
  for (size_t i = 0; i < a.size(); ++i) {
    if (std::memcmp(&a[i], &b[i], sizeof(ResidualPanel)) != 0) return false;
  }
  return true;
}

// Every field of the two teeth, bit for bit (the field's name on a difference).
void expectSameTooth(const ToothModel& a, const ToothModel& b, const std::string& where) {
#define EXPECT_SAME_FIELD(f) EXPECT_TRUE(same(a.f, b.f)) << where << ": " #f
  EXPECT_SAME_FIELD(mount_angle_rad);
  EXPECT_SAME_FIELD(length_m);
  EXPECT_SAME_FIELD(diameter_m);
  EXPECT_SAME_FIELD(youngs_modulus_Pa);
  EXPECT_SAME_FIELD(poisson_ratio);
  EXPECT_SAME_FIELD(density_kgpm3);
  EXPECT_SAME_FIELD(n_modes);
  EXPECT_SAME_FIELD(damping_ratio);
  EXPECT_SAME_FIELD(n_stations);
  EXPECT_TRUE(a.beam_model == b.beam_model) << where << ": beam_model";
  EXPECT_SAME_FIELD(static_correction);
  EXPECT_TRUE(a.section_rotation == b.section_rotation) << where << ": section_rotation";
  EXPECT_SAME_FIELD(quasi_static_from_mode);
  EXPECT_SAME_FIELD(quasi_static_speedup);
  EXPECT_SAME_FIELD(area_m2);
  EXPECT_SAME_FIELD(second_moment_m4);
  EXPECT_SAME_FIELD(mass_per_length_kgpm);
  EXPECT_SAME_FIELD(p_DR_D);
  EXPECT_SAME_FIELD(e1_D);
  EXPECT_SAME_FIELD(e2_D);
  EXPECT_SAME_FIELD(beta_per_m);
  EXPECT_SAME_FIELD(sigma);
  EXPECT_SAME_FIELD(half_one_minus_sigma);
  EXPECT_SAME_FIELD(norm_C);
  EXPECT_SAME_FIELD(omega0_sq);
  EXPECT_SAME_FIELD(rotation_factor);
  EXPECT_SAME_FIELD(damping_coeff);
  EXPECT_SAME_FIELD(K_G);
  EXPECT_SAME_FIELD(p_inertia);
  EXPECT_SAME_FIELD(I0_kgm2);
  EXPECT_SAME_FIELD(station_x_m);
  EXPECT_SAME_FIELD(phi_s);
  EXPECT_SAME_FIELD(dphi_s);
  EXPECT_SAME_FIELD(H_s);
  EXPECT_SAME_FIELD(mode_table_intervals);
  EXPECT_SAME_FIELD(mode_table_dx_m);
  EXPECT_SAME_FIELD(mode_table);
  EXPECT_SAME_FIELD(beta4_per_m4);
  EXPECT_SAME_FIELD(dof_offset);
  EXPECT_SAME_FIELD(ld_intervals);
  EXPECT_SAME_FIELD(ld_node_s_m);
  EXPECT_SAME_FIELD(ld_node_mass_kg);
  EXPECT_SAME_FIELD(ld_Phi);
  EXPECT_SAME_FIELD(ld_K);
  EXPECT_SAME_FIELD(ld_D);
  EXPECT_SAME_FIELD(ld_rotation_filter);
  EXPECT_SAME_FIELD(ld_frequencies_Hz);
  EXPECT_SAME_FIELD(ld_root_T);
  EXPECT_SAME_FIELD(modes_auto);
  EXPECT_SAME_FIELD(contact_time_s);
  EXPECT_SAME_FIELD(residual_modes);
  EXPECT_SAME_FIELD(residual_contact_time_s);
  EXPECT_SAME_FIELD(residual_omega_radps);
  EXPECT_SAME_FIELD(residual_ww);
  EXPECT_SAME_FIELD(residual_wt);
  EXPECT_SAME_FIELD(residual_tt);
  EXPECT_SAME_FIELD(residual_panels);
  EXPECT_SAME_FIELD(residual_nodes_ww);
  EXPECT_SAME_FIELD(residual_nodes_wt);
  EXPECT_SAME_FIELD(residual_nodes_tt);
  EXPECT_SAME_FIELD(residual_table_error);
#undef EXPECT_SAME_FIELD
}

void expectSameModel(const Model& a, const Model& b, const std::string& where) {
  ASSERT_EQ(a.teeth.size(), b.teeth.size()) << where;
  for (size_t k = 0; k < a.teeth.size(); ++k)
    expectSameTooth(a.teeth[k], b.teeth[k], where + ", tooth " + std::to_string(k));
  EXPECT_EQ(a.n_dof, b.n_dof) << where;
  EXPECT_EQ(a.has_large_deflection, b.has_large_deflection) << where;
  EXPECT_TRUE(same(a.drum.speed_bound_radps, b.drum.speed_bound_radps)) << where;
}

// The default scene with its tooth changed by `edit` (automatic modes: the count and the
// contact times depend on the drum speed, which compileTooth does not read).
Model sceneWith(double speed_radps, const std::function<void(ToothModel*)>& edit) {
  Model m = defaultSceneModel();
  m.drum.initial_speed_radps = speed_radps;
  m.teeth[0].n_modes = kAutoModes;
  edit(&m.teeth[0]);
  return m;
}

Model compiled(Model m, ToothCache* cache) {
  compileModel(&m, cache);
  return m;
}

// Tooth variants covering every branch of compileTooth and compileResidual.
std::vector<std::pair<std::string, std::function<void(ToothModel*)>>> variants() {
  return {
      {"modal, automatic modes", [](ToothModel*) {}},
      {"modal, 6 modes", [](ToothModel* t) { t->n_modes = 6; }},
      {"Euler-Bernoulli sections",
       [](ToothModel* t) { t->section_rotation = ToothSectionRotation::kEulerBernoulli; }},
      {"no static correction", [](ToothModel* t) { t->static_correction = false; }},
      {"rigid", [](ToothModel* t) { t->n_modes = 0; }},
      {"large deflection", [](ToothModel* t) { t->beam_model = ToothBeamModel::kLargeDeflection; }},
  };
}

TEST(ToothCache, CachedCompileEqualsUncached) {
  for (const auto& [name, edit] : variants()) {
    ToothCache cache;
    // The first speed compiles the tooth (a miss), the others take it from the cache unless
    // the automatic mode count changed with the speed (then a miss too).
    std::set<int> mode_counts;
    for (const double speed_radps : {83.78, 62.8, 157.1, 83.78}) {
      const Model cached = compiled(sceneWith(speed_radps, edit), &cache);
      const Model fresh = compiled(sceneWith(speed_radps, edit), nullptr);
      expectSameModel(cached, fresh, name + " at " + std::to_string(speed_radps) + " rad/s");
      mode_counts.insert(fresh.teeth[0].n_modes);
    }
    EXPECT_EQ(cache.misses(), mode_counts.size()) << name;
    EXPECT_EQ(cache.hits(), 4 - mode_counts.size()) << name;
    EXPECT_GE(cache.hits(), 1u) << name;
  }
}

// A change in any of compileTooth's inputs (the key) compiles the tooth again.
TEST(ToothCache, ChangedInputMisses) {
  const std::vector<std::pair<std::string, std::function<void(Model*)>>> changes = {
      {"drum radius", [](Model* m) { m->drum.radius_m = 0.21; }},
      {"mount angle", [](Model* m) { m->teeth[0].mount_angle_rad = 0.1; }},
      {"length", [](Model* m) { m->teeth[0].length_m = 0.062; }},
      {"diameter", [](Model* m) { m->teeth[0].diameter_m = 0.011; }},
      {"Young's modulus", [](Model* m) { m->teeth[0].youngs_modulus_Pa = 3.1e9; }},
      {"Poisson ratio", [](Model* m) { m->teeth[0].poisson_ratio = 0.3; }},
      {"density", [](Model* m) { m->teeth[0].density_kgpm3 = 1200; }},
      {"modes", [](Model* m) { m->teeth[0].n_modes = 5; }},
      {"damping ratio", [](Model* m) { m->teeth[0].damping_ratio = 0.03; }},
      {"stations", [](Model* m) { m->teeth[0].n_stations = 11; }},
      {"beam model", [](Model* m) { m->teeth[0].beam_model = ToothBeamModel::kLargeDeflection; }},
      {"section rotation",
       [](Model* m) { m->teeth[0].section_rotation = ToothSectionRotation::kEulerBernoulli; }},
      {"quasi-static modes",
       [](Model* m) {
         m->teeth[0].quasi_static_from_mode = 2;
         m->teeth[0].quasi_static_speedup = 10;
       }},
  };
  for (const auto& [name, change] : changes) {
    ToothCache cache;
    Model base = defaultSceneModel();
    base.teeth[0].n_modes = 4;
    compiled(base, &cache);
    Model changed = base;
    change(&changed);
    const Model cached = compiled(changed, &cache);
    EXPECT_EQ(cache.hits(), 0u) << name;
    EXPECT_EQ(cache.misses(), 2u) << name;
    expectSameModel(cached, compiled(changed, nullptr), name);
    // And the original tooth is still a hit.
    compiled(base, &cache);
    EXPECT_EQ(cache.hits(), 1u) << name;
  }
}

// Values compileTooth does not read (the static correction, the drum speed and what follows
// from it) share the kept tooth, and keep their own values.
TEST(ToothCache, OtherInputsHitAndKeepTheirValues) {
  ToothCache cache;
  Model a = defaultSceneModel();
  a.teeth[0].n_modes = 4;
  compiled(a, &cache);
  Model b = a;
  b.teeth[0].static_correction = false;
  b.drum.initial_speed_radps = 150.0;
  const Model cached = compiled(b, &cache);
  EXPECT_EQ(cache.hits(), 1u);
  expectSameModel(cached, compiled(b, nullptr), "static correction off, 150 rad/s");
  EXPECT_FALSE(cached.teeth[0].static_correction);
}

// A bad tooth throws as without the cache, and is not kept.
TEST(ToothCache, BadToothThrowsAndIsNotKept) {
  ToothCache cache;
  Model m = defaultSceneModel();
  m.teeth[0].damping_ratio = 1.5;
  EXPECT_THROW(compiled(m, &cache), std::invalid_argument);
  EXPECT_EQ(cache.size(), 0u);
  EXPECT_THROW(compiled(m, &cache), std::invalid_argument);
}

// Full: emptied, then filling again.
TEST(ToothCache, BoundedSize) {
  ToothCache cache;
  Model m = defaultSceneModel();
  m.teeth[0].n_modes = 2;
  for (size_t i = 0; i <= ToothCache::kMaxTeeth; ++i) {
    m.teeth[0].length_m = 0.05 + 1e-5 * static_cast<double>(i);
    compiled(m, &cache);
  }
  EXPECT_EQ(cache.size(), 1u);
  EXPECT_EQ(cache.misses(), ToothCache::kMaxTeeth + 1);
}

// Teeth of 16 modes (about 0.4 MB of tables each): the bytes kept stay within the bound. A
// tooth of 64 modes (about 6.5 MB) is above an eighth of it: compiled, never kept.
TEST(ToothCache, BoundedBytes) {
  ToothCache cache;
  Model m = defaultSceneModel();
  m.teeth[0].n_modes = 16;
  size_t largest = 0;
  for (int i = 0; i < 40; ++i) {
    m.teeth[0].length_m = 0.05 + 5e-4 * i;
    compiled(m, &cache);
    EXPECT_LE(cache.bytes(), ToothCache::kMaxBytes) << i;
    largest = std::max(largest, cache.size());
  }
  EXPECT_GE(largest, 4u);
  EXPECT_LT(largest, 40u);
  EXPECT_EQ(cache.misses(), 40u);

  ToothCache big;
  m.teeth[0].n_modes = 64;
  const Model first = compiled(m, &big);
  const Model again = compiled(m, &big);
  EXPECT_EQ(big.size(), 0u);
  EXPECT_EQ(big.misses(), 2u);
  expectSameModel(first, again, "64 modes");
}
}  // namespace
}  // namespace threshing_sim
