// Overlap tests at a placement (see overlap.h).
#include "threshing_sim/core/overlap.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>

namespace threshing_sim {

std::string bodyName(PairKind kind, int index) {
  const char* list = kind == PairKind::kToothKernel    ? "teeth"
                     : kind == PairKind::kKernelKernel ? "kernels"
                                                       : "obstacles";
  return std::string(list) + "." + std::to_string(index);
}

std::string describe(const Overlap& o) {
  if (!o.found) return "no overlap";
  char depth[32];
  std::snprintf(depth, sizeof(depth), "%.6g", -o.distance_m);
  return bodyName(PairKind::kKernelKernel, o.kernel) + " overlaps " +
         bodyName(o.other_kind, o.other) + " by " + depth + " m";
}

KernelGrid::KernelGrid(double cell_m)
    : cell_m_(cell_m > 0 && std::isfinite(cell_m) ? cell_m : 1.0) {}

std::int64_t KernelGrid::cellOf(double x_m) const {
  // Clamped so that far-away (or non-finite) centres share the outermost cells.
  const double c = std::floor(x_m / cell_m_);
  return static_cast<std::int64_t>(std::isfinite(c) ? std::clamp(c, -1e9, 1e9) : 1e9);
}

void KernelGrid::insert(int kernel, const Vec2& center_m) {
  cells_[key(cellOf(center_m.x()), cellOf(center_m.y()))].push_back(kernel);
}

Ellipse kernelEllipseAt(const KernelModel& k, const Vec2& c_m, double psi_rad) {
  Ellipse e;
  e.center = c_m;
  e.angle_rad = psi_rad;
  e.a_m = k.semi_axis_a_m;
  e.b_m = k.semi_axis_b_m;
  return e;
}

namespace {

// Distance from p to the segment [a, b] [m].
double pointSegmentDistance(const Vec2& p, const Vec2& a, const Vec2& b) {
  const Vec2 ab = b - a;
  const double len2 = ab.squaredNorm();
  const double s = len2 > 0.0 ? std::clamp((p - a).dot(ab) / len2, 0.0, 1.0) : 0.0;
  return (p - (a + s * ab)).norm();
}

// A lower bound of obstacleDistance: the ellipse's bounding circle against the obstacle [m].
double obstacleDistanceBound(const ObstacleModel& ob, const Ellipse& e) {
  switch (ob.type) {
    case ObstacleType::kPlane:
      return ob.normal.dot(e.center - ob.point_m) - e.a_m;
    case ObstacleType::kCircle:
      return (e.center - ob.center_m).norm() - ob.radius_m - e.a_m;
    case ObstacleType::kSegment:
      return pointSegmentDistance(e.center, ob.point_m, ob.point_b_m) - ob.radius_m - e.a_m;
  }
  return -std::numeric_limits<double>::infinity();
}

double obstacleDistance(const ObstacleModel& ob, const Ellipse& e) {
  switch (ob.type) {
    case ObstacleType::kPlane:
      return planeEllipse(ob.point_m, ob.normal, e).distance_m;
    case ObstacleType::kCircle:
      return circleEllipse(ob.center_m, ob.radius_m, e).distance_m;
    case ObstacleType::kSegment:
      return segmentEllipse(ob.point_m, ob.point_b_m, e).distance_m - ob.radius_m;
  }
  return std::numeric_limits<double>::infinity();
}

// Kernels given by their ellipses, each against the earlier ones, the teeth and obstacles.
Overlap firstOverlap(const Model& model, double theta_rad, const std::vector<Ellipse>& kernels) {
  double largest_a_m = 0;
  for (const Ellipse& e : kernels) largest_a_m = std::max(largest_a_m, e.a_m);
  KernelGrid grid(2.0 * largest_a_m);
  for (size_t i = 0; i < kernels.size(); ++i) {
    const Ellipse& e = kernels[i];
    Overlap nearest;
    nearest.distance_m = clearanceFromFixedBodies(model, theta_rad, e, &nearest);
    grid.forEachNear(e.center, [&](int j) {
      const Ellipse& other = kernels[j];
      // Bounding circles apart: no overlap possible.
      if ((other.center - e.center).norm() > other.a_m + e.a_m) return;
      const double d_m = ellipseEllipse(other, e).distance_m;
      if (d_m < nearest.distance_m) {
        nearest.distance_m = d_m;
        nearest.other_kind = PairKind::kKernelKernel;
        nearest.other = j;
      }
    });
    grid.insert(static_cast<int>(i), e.center);
    if (nearest.distance_m < 0) {
      nearest.found = true;
      nearest.kernel = static_cast<int>(i);
      return nearest;
    }
  }
  return Overlap();
}

}  // namespace

double clearanceFromFixedBodies(const Model& model, double theta_rad, const Ellipse& e,
                                Overlap* nearest) {
  // The nearest of the teeth, then the obstacles (the first of equals); a body whose bounding-
  // circle bound says it is apart, by no less than the nearest so far, cannot be nearer and is
  // not measured (the answer is the one measuring them all gives).
  double best_m = std::numeric_limits<double>::infinity();
  const auto consider = [&](double bound_m, const auto& distance, PairKind kind, int index) {
    if (bound_m > 0.0 && !(bound_m < best_m)) return;
    const double d_m = distance();
    if (d_m < best_m) {
      best_m = d_m;
      nearest->other_kind = kind;
      nearest->other = index;
    }
  };
  const double c = std::cos(theta_rad), s = std::sin(theta_rad);
  for (size_t t = 0; t < model.teeth.size(); ++t) {
    const ToothModel& tooth = model.teeth[t];
    const Vec2 axis_D(std::cos(tooth.mount_angle_rad), std::sin(tooth.mount_angle_rad));
    const Vec2 axis_W(c * axis_D.x() - s * axis_D.y(), s * axis_D.x() + c * axis_D.y());
    const Vec2 root_W = model.drum.radius_m * axis_W;
    const Vec2 tip_W = root_W + tooth.length_m * axis_W;
    const double r_m = tooth.diameter_m / 2;
    consider(
        pointSegmentDistance(e.center, root_W, tip_W) - e.a_m - r_m,
        [&] { return segmentEllipse(root_W, tip_W, e).distance_m - r_m; }, PairKind::kToothKernel,
        static_cast<int>(t));
  }
  for (size_t o = 0; o < model.obstacles.size(); ++o) {
    const ObstacleModel& ob = model.obstacles[o];
    consider(
        obstacleDistanceBound(ob, e), [&] { return obstacleDistance(ob, e); },
        PairKind::kKernelObstacle, static_cast<int>(o));
  }
  return best_m;
}

Overlap findInitialOverlap(const Model& model, double theta_rad) {
  std::vector<Ellipse> kernels;
  kernels.reserve(model.kernels.size());
  for (const KernelModel& k : model.kernels)
    kernels.push_back(kernelEllipseAt(k, k.initial_position_m, k.initial_angle_rad));
  return firstOverlap(model, theta_rad, kernels);
}

Overlap findOverlap(const Model& model, const Data& data) {
  std::vector<Ellipse> kernels;
  kernels.reserve(model.kernels.size());
  for (const KernelModel& k : model.kernels)
    kernels.push_back(
        kernelEllipseAt(k, data.z.segment<2>(k.dof_offset), data.z[k.dof_offset + 2]));
  return firstOverlap(model, data.theta_rad, kernels);
}

}  // namespace threshing_sim
