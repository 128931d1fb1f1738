// threshing_sim core: the feed's pool of kernel slots (core/feed.h): the slots, parking a slot
// and placing a kernel into one.
#include <cmath>
#include <stdexcept>
#include <string>

#include "../internal.h"
#include "feed_internal.h"
#include "threshing_sim/core/feed.h"

namespace threshing_sim {

namespace {

[[noreturn]] void refuse(const std::string& key, const std::string& rule, double value) {
  char text[64];
  std::snprintf(text, sizeof(text), "%.17g", value);
  throw std::invalid_argument("feed." + key + ": " + rule + " (got " + text + ")");
}

// Every value of spec in its range (the scene loader checks the same bounds first).
void checkFeedSpec(const FeedSpec& s) {
  if (!(s.rate_per_s > 0 && s.rate_per_s <= 1e6))
    refuse("rate", "must be in (0, 1e6]", s.rate_per_s);
  if (!(s.mat_speed_mps > 0 && s.mat_speed_mps <= 100))
    refuse("mat_speed", "must be in (0, 100]", s.mat_speed_mps);
  if (!(s.capacity >= 1 && s.capacity <= 10000))
    refuse("capacity", "must be in [1, 10000]", s.capacity);
  if (!(s.exit_x_m > s.inlet_x_m)) refuse("exit", "must be greater than feed.inlet", s.exit_x_m);
  if (!std::isfinite(s.start_s) || s.start_s < 0) refuse("start", "must be >= 0", s.start_s);
  if (!(s.bound_radius_m > 0) || !std::isfinite(s.bound_radius_m))
    refuse("bound_radius", "must be > 0", s.bound_radius_m);
  for (double v : {s.anchor_y_m, s.grate_y_m, s.inlet_x_m, s.exit_x_m})
    if (!std::isfinite(v)) refuse("inlet", "geometry must be finite", v);
  if (!(s.grate_y_m < s.anchor_y_m)) refuse("grate", "must be below the mat", s.grate_y_m);
}

}  // namespace

Vec2 feedParkingPlace(int slot) { return Vec2(1e3 + 0.05 * slot, 1e3); }

void addFeedPool(const FeedSpec& spec, Model* model) {
  checkFeedSpec(spec);
  // A parked slot must be clear of every plane (a plane is unbounded).
  for (size_t o = 0; o < model->obstacles.size(); ++o) {
    const ObstacleModel& ob = model->obstacles[o];
    if (ob.type != ObstacleType::kPlane) continue;
    for (int slot : {0, spec.capacity - 1}) {
      const double side_m = ob.normal.normalized().dot(feedParkingPlace(slot) - ob.point_m);
      if (!(side_m > 1.0)) {
        throw std::invalid_argument("feed: the pool's parking place is behind plane obstacle " +
                                    std::to_string(o) + " (obstacles." + std::to_string(o) +
                                    ".normal must not point down)");
      }
    }
  }
  for (int slot = 0; slot < spec.capacity; ++slot) {
    KernelModel k = spec.base;
    k.initial_position_m = feedParkingPlace(slot);
    k.initial_angle_rad = 0.5 * kPi;
    k.initial_velocity_mps.setZero();
    k.initial_angular_velocity_radps = 0;
    k.mass_kg = spec.kernel_mass_mean_kg();
    k.pedicel.present = true;
    k.pedicel.p_KP_K = Vec2(k.semi_axis_a_m, 0.0);
    k.pedicel.rest_length_m = spec.pedicel_length_m;
    k.pedicel.p_WA_W = k.initial_position_m + Vec2(0, k.semi_axis_a_m + spec.pedicel_length_m);
    k.pedicel.v_WA_W_mps = Vec2(spec.mat_speed_mps, 0.0);
    k.pedicel.detachment_force_N = spec.detach_N.y();
    k.pool_slot = true;
    model->kernels.push_back(k);
  }
}

namespace internal {

void parkSlot(const Model& m, int i, Data* d) {
  const int o = m.kernels[i].dof_offset;
  d->z.segment<2>(o) = m.kernels[i].initial_position_m;
  d->z[o + 2] = 0.5 * kPi;
  d->u.segment<3>(o).setZero();
  d->kernel_attached[i] = 0;
  d->kernel_active[i] = 0;
}

void clearSlotHistory(int i, Data* d) {
  RunStats& s = d->stats;
  s.kernel_peak_normal_force_N[i] = 0;
  s.kernel_tooth_peaks[i] = KernelToothPeaks();
  s.kernel_impacts[i] = 0;
  s.kernel_detach_time_s[i] = -1;
  // The pair memory of the slot's last kernel (parked for a step: none of it is in use).
  for (PairTable::Entry& e : d->ws->memory) {
    // pairKey's layout: kind << 60 | a << 30 | b.
    const auto kind = static_cast<PairKind>(e.first >> 60);
    const int a = static_cast<int>((e.first >> 30) & 0x3FFFFFFFu);
    const int b = static_cast<int>(e.first & 0x3FFFFFFFu);
    const bool has_kernel = kind == PairKind::kToothKernel    ? b == i
                            : kind == PairKind::kKernelKernel ? (a == i || b == i)
                                                              : a == i;
    if (has_kernel) e.second = PairMemory();
  }
}

void placeKernel(const KernelModel& k, const Vec2& c_W, double psi_rad, const Vec2& v_W, int i,
                 Model* m, Data* d) {
  KernelModel& slot = m->kernels[i];
  const int o = slot.dof_offset;
  // compileKernel's uniform elliptic disc inertia for the new mass.
  slot.mass_kg = k.mass_kg;
  slot.inertia_kgm2 =
      k.mass_kg *
      (slot.semi_axis_a_m * slot.semi_axis_a_m + slot.semi_axis_b_m * slot.semi_axis_b_m) / 4.0;
  slot.pedicel.p_WA_W = k.pedicel.p_WA_W;
  slot.pedicel.detachment_force_N = k.pedicel.detachment_force_N;
  clearSlotHistory(i, d);
  d->z.segment<2>(o) = c_W;
  d->z[o + 2] = psi_rad;
  d->u.segment<2>(o) = v_W;
  d->u[o + 2] = 0;
  d->kernel_attached[i] = 1;
  d->kernel_active[i] = 1;
}

}  // namespace internal
}  // namespace threshing_sim
