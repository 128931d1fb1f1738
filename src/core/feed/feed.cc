// threshing_sim core: the feed's stages at a step boundary (core/feed.h): kernels retired by
// where they are, then the kernels due placed on the mat at the inlet.
#include "threshing_sim/core/feed.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <string>

#include "../internal.h"
#include "feed_internal.h"
#include "threshing_sim/core/constants.h"
#include "threshing_sim/core/geometry.h"
#include "threshing_sim/core/overlap.h"

namespace threshing_sim {

const char* toString(KernelFate fate) {
  switch (fate) {
    case KernelFate::kInDrum:
      return "in_drum";
    case KernelFate::kSeparated:
      return "separated";
    case KernelFate::kCarriedDetached:
      return "carried_over_detached";
    case KernelFate::kCarriedUnthreshed:
      return "carried_over_unthreshed";
    case KernelFate::kOutOfBounds:
      return "out_of_bounds";
  }
  return "?";
}

KernelFate feedFate(const FeedSpec& spec, const Vec2& c_W, bool attached) {
  const bool in_span = c_W.x() >= spec.inlet_x_m && c_W.x() <= spec.exit_x_m;
  if (c_W.y() < spec.grate_y_m && in_span) return KernelFate::kSeparated;
  if (c_W.x() > spec.exit_x_m && c_W.y() >= spec.grate_y_m) {
    return attached ? KernelFate::kCarriedUnthreshed : KernelFate::kCarriedDetached;
  }
  // Below the grate line outside its span, or out of the bounding circle; a NaN centre too.
  if (!(c_W.y() >= spec.grate_y_m) || !(c_W.norm() <= spec.bound_radius_m))
    return KernelFate::kOutOfBounds;
  return KernelFate::kInDrum;
}

double nextFeedArrival(const FeedSpec& spec, const FeedState& state) {
  if (!(spec.rate_per_s > 0)) return std::numeric_limits<double>::infinity();
  return state.base_t_s + static_cast<double>(state.counts.fed - state.base_n) / spec.rate_per_s;
}

std::string checkFeedRate(double rate_per_s, const FeedSpec& spec, int capacity) {
  char text[256];
  if (!std::isfinite(rate_per_s) || rate_per_s < 0 || rate_per_s > 1e6) {
    std::snprintf(text, sizeof(text), "feed rate %.17g 1/s refused: must be in [0, 1e6]",
                  rate_per_s);
    return text;
  }
  const double on_mat = rate_per_s *
                        (spec.exit_x_m - spec.inlet_x_m + 2 * spec.position_scatter_m) /
                        spec.mat_speed_mps;
  if (on_mat > capacity) {
    std::snprintf(text, sizeof(text),
                  "feed rate %.17g 1/s refused: it puts %.6g kernels on the mat, more than the "
                  "pool's %d slots (feed.capacity)",
                  rate_per_s, on_mat, capacity);
    return text;
  }
  return "";
}

std::string setFeedRate(double rate_per_s, double t_s, FeedSpec* spec, FeedState* state) {
  std::string why = checkFeedRate(rate_per_s, *spec, state->capacity);
  if (!why.empty()) return why;
  spec->rate_per_s = rate_per_s;
  state->base_n = state->counts.fed;
  const double after_last_s =
      state->counts.fed > 0 && rate_per_s > 0 ? state->last_arrival_s + 1.0 / rate_per_s : t_s;
  state->base_t_s = std::max({t_s, spec->start_s, after_last_s});
  return "";
}

void startFeed(const FeedSpec& spec, const Model& model, Data* data, FeedState* state) {
  FeedState& s = *state;
  s.capacity = spec.capacity;
  s.first_slot = static_cast<int>(model.kernels.size()) - spec.capacity;
  s.slot_id.assign(s.capacity, -1);
  s.slot_arrival_s.assign(s.capacity, 0.0);
  s.slot_parked_step.assign(s.capacity, -1);
  s.free_ring.resize(s.capacity);
  for (int slot = 0; slot < s.capacity; ++slot) s.free_ring[slot] = slot;
  s.free_head = 0;
  s.free_count = s.capacity;
  s.counts = FeedCounts();
  s.base_t_s = spec.start_s;
  s.base_n = 0;
  s.last_arrival_s = -std::numeric_limits<double>::infinity();
  s.retired.clear();
  s.retired.reserve(s.capacity);
  s.uniform = Uniform(static_cast<unsigned long long>(spec.seed));
  s.error.clear();
  for (int slot = 0; slot < s.capacity; ++slot)
    internal::parkSlot(model, s.first_slot + slot, data);
}

namespace {

void count(KernelFate fate, FeedCounts* c) {
  --c->in_drum;
  switch (fate) {
    case KernelFate::kSeparated:
      ++c->separated;
      break;
    case KernelFate::kCarriedDetached:
      ++c->carried_detached;
      break;
    case KernelFate::kCarriedUnthreshed:
      ++c->carried_unthreshed;
      break;
    default:
      ++c->out_of_bounds;
  }
}

// The final record of slot's kernel, which left as fate.
FeedRecord recordOf(const Model& m, const Data& d, const FeedState& s, int slot, KernelFate fate) {
  const int i = s.first_slot + slot;
  FeedRecord r;
  r.id = s.slot_id[slot];
  r.slot = i;
  r.arrival_s = s.slot_arrival_s[slot];
  r.retired_s = d.t_s;
  r.fate = fate;
  r.mass_kg = m.kernels[i].mass_kg;
  r.peak_normal_N = d.stats.kernel_tooth_peaks[i].normal_force_N;
  r.peak_tangential_N = d.stats.kernel_tooth_peaks[i].tangential_force_N;
  r.peak_contact_N = d.stats.kernel_peak_normal_force_N[i];
  r.impacts = d.stats.kernel_impacts[i];
  r.detach_s = d.stats.kernel_detach_time_s[i];
  r.exit_position_m = d.z.segment<2>(m.kernels[i].dof_offset);
  return r;
}

// Retires every kernel that has left: its record, its count, its slot parked and freed.
void retireKernels(const FeedSpec& spec, const Model& m, Data* d, FeedState* s) {
  for (int slot = 0; slot < s->capacity; ++slot) {
    if (s->slot_id[slot] < 0) continue;
    const int i = s->first_slot + slot;
    const KernelFate fate =
        feedFate(spec, d->z.segment<2>(m.kernels[i].dof_offset), d->kernel_attached[i] != 0);
    if (fate == KernelFate::kInDrum) continue;
    s->retired.push_back(recordOf(m, *d, *s, slot, fate));
    count(fate, &s->counts);
    internal::parkSlot(m, i, d);
    s->slot_id[slot] = -1;
    s->slot_parked_step[slot] = d->steps;
    s->free_ring[(s->free_head + s->free_count) % s->capacity] = slot;
    ++s->free_count;
  }
}

// Least clearance between kernels placed [m]: a fed kernel is drawn again when closer.
constexpr double kPlacementGap_m = 1e-4;

// Whether kernel k at pose (c_W, psi_rad) clears every active kernel by kPlacementGap_m (the
// teeth cannot reach the inlet: the scene loader refuses an inlet within their reach).
bool clearOfBodies(const Model& m, const Data& d, const KernelModel& k, const Vec2& c_W,
                   double psi_rad) {
  const Ellipse e = kernelEllipseAt(k, c_W, psi_rad);
  for (size_t j = 0; j < m.kernels.size(); ++j) {
    if (!d.kernel_active[j]) continue;
    const KernelModel& kj = m.kernels[j];
    const Vec2 c_j = d.z.segment<2>(kj.dof_offset);
    if ((c_j - c_W).norm() >= k.semi_axis_a_m + kj.semi_axis_a_m + kPlacementGap_m) continue;
    const Ellipse ej = kernelEllipseAt(kj, c_j, d.z[kj.dof_offset + 2]);
    if (ellipseEllipse(ej, e).distance_m < kPlacementGap_m) return false;
  }
  return true;
}

// Places the next kernel (arriving at arrival_s) into slot at d->t_s: anchor on the mat (moved
// on from the inlet since arrival), scatter along the mat and over its thickness, hanging
// below its anchor within +-angle_scatter, mass and detachment force uniform in their ranges;
// a draw that overlaps an active kernel is redrawn.
bool placeNext(const FeedSpec& spec, double arrival_s, int slot, Model* m, Data* d, FeedState* s) {
  constexpr int kMaxDraws = 100;
  const Vec2 v_W(spec.mat_speed_mps, 0.0);
  const double t_s = d->t_s;
  KernelModel k = spec.base;
  const double reach_m = k.semi_axis_a_m + spec.pedicel_length_m;
  for (int draw = 0; draw < kMaxDraws; ++draw) {
    Uniform& u = s->uniform;
    const double x_m = spec.inlet_x_m + spec.mat_speed_mps * (t_s - arrival_s) +
                       u(-spec.position_scatter_m, spec.position_scatter_m);
    const double y_m = spec.anchor_y_m + u(-0.5, 0.5) * spec.mat_thickness_m;
    const double psi_rad = 0.5 * kPi + u(-spec.angle_scatter_rad, spec.angle_scatter_rad);
    k.mass_kg = u(spec.mass_kg.x(), spec.mass_kg.y());
    k.pedicel.detachment_force_N = u(spec.detach_N.x(), spec.detach_N.y());
    const Vec2 p_WA(x_m, y_m);
    const Vec2 c_W = p_WA - reach_m * Vec2(std::cos(psi_rad), std::sin(psi_rad));
    if (!clearOfBodies(*m, *d, k, c_W, psi_rad)) continue;
    k.pedicel.p_WA_W = p_WA - t_s * v_W;  // the anchor at t = 0 on its line of motion
    internal::placeKernel(k, c_W, psi_rad, v_W, s->first_slot + slot, m, d);
    return true;
  }
  return false;
}

}  // namespace

void retireFeedKernels(const FeedSpec& spec, const Model& model, Data* data, FeedState* state) {
  retireKernels(spec, model, data, state);
}

bool feedKernelDue(const FeedSpec& spec, const FeedState& state, double t_s) {
  return nextFeedArrival(spec, state) <= t_s;
}

bool updateFeed(const FeedSpec& spec, Model* model, Data* data, FeedState* state) {
  retireKernels(spec, *model, data, state);
  return placeFeedKernels(spec, model, data, state);
}

bool placeFeedKernels(const FeedSpec& spec, Model* model, Data* data, FeedState* state) {
  FeedState& s = *state;
  // Every kernel due by now (at most one pool's worth: a full pool stops the loop).
  while (nextFeedArrival(spec, s) <= data->t_s) {
    const double arrival_s = nextFeedArrival(spec, s);
    char where[96];
    std::snprintf(where, sizeof(where),
                  "feed: kernel %ld (arrival %.9g s, placed at %.9g s): ", s.counts.fed, arrival_s,
                  data->t_s);
    if (s.free_count == 0 || s.slot_parked_step[s.free_ring[s.free_head]] >= data->steps) {
      s.error = std::string(where) + "no free slot: all " + std::to_string(s.capacity) +
                " slots of the pool (feed.capacity " + std::to_string(s.capacity) +
                ") are in use; raise feed.capacity or lower feed.rate";
      return false;
    }
    const int slot = s.free_ring[s.free_head];
    if (!placeNext(spec, arrival_s, slot, model, data, &s)) {
      s.error = std::string(where) +
                "still overlaps a kernel after 100 draws; lower feed.rate or raise "
                "feed.mat_thickness or feed.position_scatter";
      return false;
    }
    s.free_head = (s.free_head + 1) % s.capacity;
    --s.free_count;
    s.slot_id[slot] = s.counts.fed;
    s.slot_arrival_s[slot] = arrival_s;
    s.last_arrival_s = arrival_s;
    ++s.counts.fed;
    ++s.counts.in_drum;
  }
  return true;
}

}  // namespace threshing_sim
