// The kernel stream generator: kernels on pedicels that tooth 0 meets at a set rate, with
// seeded scatter (stream.h).
#include "stream.h"

#include <algorithm>
#include <cmath>

#include "messages.h"
#include "schema.h"
#include "threshing_sim/core/constants.h"
#include "threshing_sim/core/geometry.h"
#include "threshing_sim/core/overlap.h"
#include "threshing_sim/core/uniform.h"

namespace threshing_sim {
namespace loader {
namespace {

// Smallest signed distance from kernel k to the kernels in the grid, the undeformed teeth at
// the initial drum angle and the obstacles; *other names the nearest body.
double clearance(const Model& model, const KernelGrid& grid, const KernelModel& k,
                 std::string* other) {
  const Ellipse e = kernelEllipseAt(k, k.initial_position_m, k.initial_angle_rad);
  Overlap nearest;
  double nearest_m = clearanceFromFixedBodies(model, model.drum.initial_angle_rad, e, &nearest);
  grid.forEachNear(e.center, [&](int j) {
    const KernelModel& kj = model.kernels[j];
    if ((kj.initial_position_m - e.center).norm() > kj.semi_axis_a_m + e.a_m) return;
    const double d_m =
        ellipseEllipse(kernelEllipseAt(kj, kj.initial_position_m, kj.initial_angle_rad), e)
            .distance_m;
    if (d_m < nearest_m) {
      nearest_m = d_m;
      nearest.other_kind = PairKind::kKernelKernel;
      nearest.other = j;
    }
  });
  if (nearest.other >= 0) *other = bodyName(nearest.other_kind, nearest.other);
  return nearest_m;
}

// Angle of drum rotation from tooth 0 to the next tooth ahead of it in the direction of
// rotation (2 pi with one tooth) [rad].
double angleToNextTooth(const Model& model, double direction) {
  double gap_rad = 2 * kPi;
  for (size_t t = 1; t < model.teeth.size(); ++t) {
    double delta = std::fmod(
        direction * (model.teeth[t].mount_angle_rad - model.teeth[0].mount_angle_rad), 2 * kPi);
    if (delta <= 0) delta += 2 * kPi;
    gap_rad = std::min(gap_rad, delta);
  }
  return gap_rad;
}

// The stream's parameters, and the kernel every draw starts from.

StreamSpec readStreamSpec(const Section& s) {
  StreamSpec spec;
  s.require("count");
  s.require("rate");
  spec.count = s.integer("count", spec.count);
  spec.rate_Hz = s.number("rate", spec.rate_Hz);
  spec.start_s = s.number("start", spec.start_s);
  spec.seed = s.integer("seed", spec.seed);
  spec.depth_m = s.number("depth", spec.depth_m);
  spec.position_scatter_m = s.number("position_scatter", spec.position_scatter_m);
  spec.angle_scatter_rad = s.number("angle_scatter", spec.angle_scatter_rad);
  KernelModel& base = spec.base;
  const Vec2 axes = s.vec2("semi_axes", Vec2(base.semi_axis_a_m, base.semi_axis_b_m));
  if (axes.minCoeff() <= 0 || axes.x() < axes.y()) {
    fail(s.path("semi_axes"),
         "must be [a, b] with a >= b > 0 (got " + show(s.node("semi_axes")) + ")");
  }
  base.semi_axis_a_m = axes.x();
  base.semi_axis_b_m = axes.y();
  spec.mass_kg = positiveRange(s, "mass_range", spec.mass_kg);
  base.youngs_modulus_Pa = s.number("youngs_modulus", base.youngs_modulus_Pa);
  base.poisson_ratio = s.number("poisson_ratio", base.poisson_ratio);
  spec.pedicel_length_m = s.number("pedicel_length", spec.pedicel_length_m);
  base.pedicel.present = true;
  base.pedicel.stiffness_Npm = s.number("pedicel_stiffness", base.pedicel.stiffness_Npm);
  base.pedicel.damping_Nspm = s.number("pedicel_damping", base.pedicel.damping_Nspm);
  base.pedicel.rest_length_m = -1.0;
  base.pedicel.p_KP_K = Vec2(base.semi_axis_a_m, 0.0);
  spec.detach_N = positiveRange(s, "detachment_force_range", spec.detach_N);
  return spec;
}

// The radius of the kernels' centres; refuses a depth that puts them at the drum axis, and a
// stream that would not pass before the next tooth reaches the first kernel's place.
double streamRadius(const Section& s, const Model& model, const StreamSpec& spec) {
  const double omega_radps = model.drum.initial_speed_radps;
  const double direction = omega_radps > 0 ? 1.0 : -1.0;
  const double tip_radius_m = model.drum.radius_m + model.teeth[0].length_m;
  const double radius_m = tip_radius_m - spec.depth_m;
  if (radius_m - spec.position_scatter_m <= spec.base.semi_axis_a_m) {
    fail(s.path("depth"), "puts the kernels at the drum axis (centre radius " + show(radius_m) +
                              " m, got " + show(s.node("depth")) + ")");
  }
  const double span_rad = std::abs(omega_radps) * (spec.start_s + (spec.count - 1) / spec.rate_Hz) +
                          spec.position_scatter_m / (radius_m - spec.position_scatter_m);
  const double gap_rad = angleToNextTooth(model, direction);
  if (span_rad >= gap_rad) {
    fail(s.path("rate"), "the stream spans " + show(span_rad) +
                             " rad of drum rotation but the next tooth follows tooth 0 after " +
                             show(gap_rad) + " rad; lower count or start, or raise rate (got " +
                             show(s.node("rate")) + ")");
  }
  return radius_m;
}

// One draw of kernel j (arriving at arrival_s) at centre radius radius_m: position, angle,
// pedicel anchor, mass and detachment force with their scatter.
void drawStreamKernel(const Model& model, const StreamSpec& spec, double radius_m, double arrival_s,
                      Uniform* uniform, KernelModel* k) {
  const double theta0_rad = model.drum.initial_angle_rad + model.teeth[0].mount_angle_rad;
  const double scatter_m = spec.position_scatter_m;
  const double r_m = radius_m + (*uniform)(-scatter_m, scatter_m);
  const double phi_rad = theta0_rad + model.drum.initial_speed_radps * arrival_s +
                         (*uniform)(-scatter_m, scatter_m) / r_m;
  const double psi_rad = phi_rad + (*uniform)(-spec.angle_scatter_rad, spec.angle_scatter_rad);
  const Vec2 axis(std::cos(psi_rad), std::sin(psi_rad));
  k->initial_position_m = r_m * Vec2(std::cos(phi_rad), std::sin(phi_rad));
  k->initial_angle_rad = psi_rad;
  k->pedicel.p_WA_W = k->initial_position_m + (k->semi_axis_a_m + spec.pedicel_length_m) * axis;
  k->mass_kg = (*uniform)(spec.mass_kg.x(), spec.mass_kg.y());
  k->pedicel.detachment_force_N = (*uniform)(spec.detach_N.x(), spec.detach_N.y());
}

}  // namespace

// The scatter's numbers: Uniform (core/uniform.h), the same on every standard library.

// [lo, hi] with 0 < lo <= hi.
Vec2 positiveRange(const Section& s, const std::string& key, const Vec2& fallback) {
  const Vec2 range = s.vec2(key, fallback);
  if (!(range.x() > 0 && range.x() <= range.y())) {
    fail(s.path(key), "must be [lo, hi] with 0 < lo <= hi (got " + show(s.node(key)) + ")");
  }
  return range;
}

// Appends the stream's kernels. Kernel j sits where the axis of tooth 0 is at time
// start + j / rate (drum at its initial speed), depth inside the tip circle, its long axis
// radial, held at its outer end by a pedicel running on outward; then scatter: uniform
// +-position_scatter radially and along the path, +-angle_scatter on the orientation, mass and
// detachment force uniform in their ranges. A draw that overlaps a body is redrawn.
void readStream(const Section& scene, Model* model) {
  const SceneNode& node = scene.node("stream");
  if (!node.defined() || node.isNull()) return;
  const Section s = scene.section("stream", "stream");
  if (model->teeth.empty()) fail("stream", "needs at least one tooth (teeth is empty)");
  if (model->drum.initial_speed_radps == 0)
    fail("drum.speed", "must not be 0 with a kernel stream");
  const StreamSpec spec = readStreamSpec(s);
  const double radius_m = streamRadius(s, *model, spec);
  // Kernels, each redrawn until it clears every body placed before it.
  Uniform uniform(static_cast<unsigned long long>(spec.seed));
  constexpr int kMaxDraws = 100;
  double largest_a_m = spec.base.semi_axis_a_m;
  for (const KernelModel& k : model->kernels) largest_a_m = std::max(largest_a_m, k.semi_axis_a_m);
  KernelGrid grid(2.0 * largest_a_m);
  for (size_t i = 0; i < model->kernels.size(); ++i)
    grid.insert(static_cast<int>(i), model->kernels[i].initial_position_m);
  for (int j = 0; j < spec.count; ++j) {
    KernelModel k = spec.base;
    std::string other;
    double distance_m = -1;
    for (int draw = 0; draw < kMaxDraws && distance_m < 0; ++draw) {
      drawStreamKernel(*model, spec, radius_m, spec.start_s + j / spec.rate_Hz, &uniform, &k);
      distance_m = clearance(*model, grid, k, &other);
    }
    if (distance_m < 0) {
      fail("stream", "kernel " + std::to_string(j) + " still overlaps " + other + " after " +
                         std::to_string(kMaxDraws) +
                         " draws; lower the scatter or the rate, or change the seed");
    }
    grid.insert(static_cast<int>(model->kernels.size()), k.initial_position_m);
    model->kernels.push_back(k);
  }
}

}  // namespace loader
}  // namespace threshing_sim
