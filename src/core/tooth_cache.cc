// Compiled teeth kept between model compilations (tooth_cache.h).
#include "threshing_sim/core/tooth_cache.h"

#include <cstring>

#include "threshing_sim/core/beam.h"

namespace threshing_sim {
namespace {

// A new ToothModel field must be sorted here: into toothCompileKey if compileTooth (beam.cc,
// large_deflection.cc) reads it, into copyCompiled if compileTooth writes it, else nowhere
// (then update the size). test_tooth_cache checks a cached compile against a fresh one.
static_assert(sizeof(ToothModel) == 848,
              "ToothModel changed: sort its new field into toothCompileKey or copyCompiled");

template <typename T>
void append(const T& value, std::string* key) {
  key->append(reinterpret_cast<const char*>(&value), sizeof(value));
}

// The fields compileTooth writes, from the compiled tooth `from` into *to.
void copyCompiled(const ToothModel& from, ToothModel* to) {
  ToothModel& t = *to;
  t.area_m2 = from.area_m2;
  t.second_moment_m4 = from.second_moment_m4;
  t.mass_per_length_kgpm = from.mass_per_length_kgpm;
  t.p_DR_D = from.p_DR_D;
  t.e1_D = from.e1_D;
  t.e2_D = from.e2_D;
  t.beta_per_m = from.beta_per_m;
  t.sigma = from.sigma;
  t.half_one_minus_sigma = from.half_one_minus_sigma;
  t.norm_C = from.norm_C;
  t.omega0_sq = from.omega0_sq;
  t.rotation_factor = from.rotation_factor;
  t.damping_coeff = from.damping_coeff;
  t.K_G = from.K_G;
  t.p_inertia = from.p_inertia;
  t.I0_kgm2 = from.I0_kgm2;
  t.station_x_m = from.station_x_m;
  t.phi_s = from.phi_s;
  t.dphi_s = from.dphi_s;
  t.H_s = from.H_s;
  t.mode_table_intervals = from.mode_table_intervals;
  t.mode_table_dx_m = from.mode_table_dx_m;
  t.mode_table = from.mode_table;  // immutable once compiled: shared
  t.beta4_per_m4 = from.beta4_per_m4;
  t.ddphi_bound = from.ddphi_bound;
  t.ld_intervals = from.ld_intervals;
  t.ld_node_s_m = from.ld_node_s_m;
  t.ld_node_mass_kg = from.ld_node_mass_kg;
  t.ld_Phi = from.ld_Phi;
  t.ld_K = from.ld_K;
  t.ld_D = from.ld_D;
  t.ld_rotation_filter = from.ld_rotation_filter;
  t.ld_frequencies_Hz = from.ld_frequencies_Hz;
  t.ld_root_T = from.ld_root_T;
}

// The size of a compiled tooth with its tables (approximate: the arrays' payloads) [bytes].
size_t toothBytes(const ToothModel& t) {
  size_t doubles = static_cast<size_t>(
      t.beta_per_m.size() + t.sigma.size() + t.half_one_minus_sigma.size() + t.norm_C.size() +
      t.omega0_sq.size() + t.rotation_factor.size() + t.damping_coeff.size() + t.K_G.size() +
      t.p_inertia.size() + t.station_x_m.size() + t.phi_s.size() + t.dphi_s.size() +
      t.beta4_per_m4.size() + t.ld_node_s_m.size() + t.ld_node_mass_kg.size() + t.ld_Phi.size() +
      t.ld_K.size() + t.ld_D.size() + t.ld_rotation_filter.size() + t.ld_frequencies_Hz.size());
  for (const MatX& H : t.H_s) doubles += static_cast<size_t>(H.size());
  if (t.mode_table) doubles += t.mode_table->size();
  return sizeof(ToothModel) + sizeof(double) * doubles;
}

}  // namespace

std::string toothCompileKey(double drum_radius_m, const ToothModel& tooth) {
  std::string key;
  key.reserve(96);
  append(drum_radius_m, &key);
  append(tooth.mount_angle_rad, &key);
  append(tooth.length_m, &key);
  append(tooth.diameter_m, &key);
  append(tooth.youngs_modulus_Pa, &key);
  append(tooth.poisson_ratio, &key);
  append(tooth.density_kgpm3, &key);
  append(tooth.n_modes, &key);
  append(tooth.damping_ratio, &key);
  append(tooth.n_stations, &key);
  append(tooth.beam_model, &key);
  append(tooth.section_rotation, &key);
  append(tooth.quasi_static_from_mode, &key);
  append(tooth.quasi_static_speedup, &key);
  return key;
}

void ToothCache::compile(double drum_radius_m, ToothModel* tooth) {
  const std::string key = toothCompileKey(drum_radius_m, *tooth);
  const auto found = teeth_.find(key);
  if (found != teeth_.end()) {
    ++hits_;
    copyCompiled(found->second, tooth);
    return;
  }
  ++misses_;
  compileTooth(drum_radius_m, tooth);  // throws on a bad tooth: nothing kept
  const size_t bytes = toothBytes(*tooth);
  if (bytes > kMaxBytes / 8) return;  // alone above an eighth of the bound: not kept
  if (teeth_.size() >= kMaxTeeth || bytes_ + bytes > kMaxBytes) {
    teeth_.clear();
    bytes_ = 0;
  }
  teeth_.emplace(key, *tooth);
  bytes_ += bytes;
}

}  // namespace threshing_sim
