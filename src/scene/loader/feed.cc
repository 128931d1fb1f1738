// The continuous feed's reader (core/feed.h): the section's values, the geometry from tooth
// 0's tip circle, the pool's capacity (stream.h).
#include <algorithm>
#include <cmath>

#include "messages.h"
#include "schema.h"
#include "stream.h"

namespace threshing_sim {
namespace loader {
namespace {

// The section's values and the kernel every fed kernel starts from.
FeedSpec readFeedValues(const Section& s) {
  FeedSpec spec;
  s.require("rate");
  s.require("inlet");
  s.require("exit");
  spec.rate_per_s = s.number("rate", spec.rate_per_s);
  spec.mat_speed_mps = s.number("mat_speed", spec.mat_speed_mps);
  spec.start_s = s.number("start", spec.start_s);
  spec.seed = s.integer("seed", spec.seed);
  spec.inlet_x_m = s.number("inlet", spec.inlet_x_m);
  spec.exit_x_m = s.number("exit", spec.exit_x_m);
  if (!(spec.exit_x_m > spec.inlet_x_m)) {
    fail(s.path("exit"), "must be greater than feed.inlet (" + show(spec.inlet_x_m) + " m) (got " +
                             show(spec.exit_x_m) + ")");
  }
  spec.mat_thickness_m = s.number("mat_thickness", spec.mat_thickness_m);
  spec.bound_radius_m = s.number("bound_radius", spec.bound_radius_m);
  spec.position_scatter_m = s.number("position_scatter", spec.position_scatter_m);
  spec.angle_scatter_rad = s.number("angle_scatter", spec.angle_scatter_rad);
  KernelModel& base = spec.base;
  const Vec2 axes = s.vec2("semi_axes", Vec2(base.semi_axis_a_m, base.semi_axis_b_m));
  if (axes.x() < axes.y()) {
    fail(s.path("semi_axes"), "must be [a, b] with a >= b (got " + show(s.node("semi_axes")) + ")");
  }
  base.semi_axis_a_m = axes.x();
  base.semi_axis_b_m = axes.y();
  spec.mass_kg = positiveRange(s, "mass_range", spec.mass_kg);
  base.youngs_modulus_Pa = s.number("youngs_modulus", base.youngs_modulus_Pa);
  base.poisson_ratio = s.number("poisson_ratio", base.poisson_ratio);
  spec.pedicel_length_m = s.number("pedicel_length", spec.pedicel_length_m);
  base.pedicel.stiffness_Npm = s.number("pedicel_stiffness", base.pedicel.stiffness_Npm);
  base.pedicel.damping_Nspm = s.number("pedicel_damping", base.pedicel.damping_Nspm);
  spec.detach_N = positiveRange(s, "detachment_force_range", spec.detach_N);
  return spec;
}

// Refuses an inlet within the teeth's reach: every point a kernel can occupy at arrival (within
// 2 a + pedicel length of an anchor in the box of the position scatter and the mat's thickness)
// must lie outside every tooth's tip circle grown by its radius and 1 mm.
void checkInletClear(const Section& s, const Model& model, const FeedSpec& spec) {
  double reach_m = 0;
  for (const ToothModel& t : model.teeth)
    reach_m = std::max(reach_m, model.drum.radius_m + t.length_m + 0.5 * t.diameter_m);
  const double x_m = std::max(spec.inlet_x_m - spec.position_scatter_m,
                              std::min(0.0, spec.inlet_x_m + spec.position_scatter_m));
  const double y_m = std::max(spec.anchor_y_m - 0.5 * spec.mat_thickness_m,
                              std::min(0.0, spec.anchor_y_m + 0.5 * spec.mat_thickness_m));
  const double kernel_m = 2 * spec.base.semi_axis_a_m + spec.pedicel_length_m;
  const double gap_m = std::hypot(x_m, y_m) - kernel_m - reach_m;
  if (!(gap_m > 1e-3)) {
    fail(s.path("inlet"), "puts arriving kernels within the teeth's reach (" + show(reach_m) +
                              " m from the axis, " + show(gap_m) +
                              " m clear; needs 1 mm): move it away from the drum (got " +
                              show(s.node("inlet")) + ")");
  }
}

// The mat's and the grate's heights from tooth 0's tip circle, then the pool's capacity
// (given, or derived from the kernels riding the mat).
void placeFeed(const Section& s, const Model& model, FeedSpec* spec) {
  const double tip_radius_m = model.drum.radius_m + model.teeth[0].length_m;
  const double depth_m = s.number("depth", kFeedDepth_m);
  spec->anchor_y_m = -(tip_radius_m - depth_m) + spec->base.semi_axis_a_m + spec->pedicel_length_m;
  spec->grate_y_m = -(tip_radius_m + s.number("grate_clearance", kFeedGrateClearance_m));
  if (!(spec->grate_y_m < spec->anchor_y_m - spec->base.semi_axis_a_m - spec->pedicel_length_m)) {
    fail(s.path("grate_clearance"), "puts the grate above the kernels (depth " + show(depth_m) +
                                        " m) (got " + show(s.node("grate_clearance")) + ")");
  }
  if (!(spec->bound_radius_m > -spec->grate_y_m)) {
    fail(s.path("bound_radius"), "must exceed the grate's distance from the axis, " +
                                     show(-spec->grate_y_m) + " m (got " +
                                     show(spec->bound_radius_m) + ")");
  }
  checkInletClear(s, model, *spec);
  const double on_mat = spec->rate_per_s *
                        (spec->exit_x_m - spec->inlet_x_m + 2 * spec->position_scatter_m) /
                        spec->mat_speed_mps;
  if (s.has("capacity")) {
    spec->capacity = s.integer("capacity", 0);
    if (spec->capacity < on_mat) {
      fail(s.path("capacity"), "cannot hold the " + show(std::ceil(on_mat)) +
                                   " kernels riding the mat (rate x span / mat_speed) (got " +
                                   show(s.node("capacity")) + ")");
    }
    return;
  }
  const double derived = std::ceil(1.5 * on_mat) + 16;
  if (derived > 10000) {
    fail(s.path("rate"),
         "needs a pool of " + show(derived) +
             " kernel slots, more than 10000 (rate x span / mat_speed = " + show(on_mat) +
             " kernels on the mat); lower it or raise "
             "feed.mat_speed (got " +
             show(s.node("rate")) + ")");
  }
  spec->capacity = static_cast<int>(derived);
}

}  // namespace

// The feed of the scene (capacity 0 when it has none); refuses a feed the scene cannot run.
FeedSpec readFeed(const Section& scene, const Model& model) {
  const SceneNode& node = scene.node("feed");
  if (!node.defined() || node.isNull()) return FeedSpec();
  const Section s = scene.section("feed", "feed");
  FeedSpec spec = readFeedValues(s);
  if (model.teeth.empty()) fail("feed", "needs at least one tooth (teeth is empty)");
  if (!(model.drum.initial_speed_radps > 0)) {
    fail("drum.speed",
         "must be > 0 with a feed (the mat moves along +x, with the drum's bottom) "
         "(got " +
             show(model.drum.initial_speed_radps) + ")");
  }
  if (model.integrator.islands) {
    fail("integrator.islands",
         "must be false with a feed (its moving anchors are in the global "
         "scheme only) (got true)");
  }
  placeFeed(s, model, &spec);
  return spec;
}

}  // namespace loader
}  // namespace threshing_sim
