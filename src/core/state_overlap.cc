#include "threshing_sim/core/state_overlap.h"

#include <algorithm>
#include <cstdio>
#include <limits>

#include "threshing_sim/core/geometry.h"
#include "threshing_sim/core/simulator.h"

namespace threshing_sim {
namespace {

Ellipse kernelEllipse(const Model& model, const Data& data, int i) {
  const KernelModel& k = model.kernels[i];
  Ellipse e;
  e.center = kernelPosition(model, data, i);
  e.angle_rad = kernelAngle(model, data, i);
  e.a_m = k.semi_axis_a_m;
  e.b_m = k.semi_axis_b_m;
  return e;
}

// Signed distance of tooth k's capsule (radius d/2 about its deformed centreline, sampled at
// the model's contact stations) to the ellipse [m].
double toothDistance(const Model& model, const Data& data, int k, const Ellipse& e) {
  const ToothModel& tooth = model.teeth[k];
  const int n = std::max(2, tooth.n_stations);
  double best_m = std::numeric_limits<double>::infinity();
  Vec2 p0 = toothPointWorld(model, data, k, 0.0);
  for (int j = 1; j < n; ++j) {
    const Vec2 p1 = toothPointWorld(model, data, k, tooth.length_m * j / (n - 1));
    best_m = std::min(best_m, segmentEllipse(p0, p1, e).distance_m - 0.5 * tooth.diameter_m);
    p0 = p1;
  }
  return best_m;
}

double obstacleDistance(const ObstacleModel& o, const Ellipse& e) {
  switch (o.type) {
    case ObstacleType::kCircle:
      return circleEllipse(o.center_m, o.radius_m, e).distance_m;
    case ObstacleType::kSegment:
      return segmentEllipse(o.point_m, o.point_b_m, e).distance_m - o.radius_m;
    default:
      return planeEllipse(o.point_m, o.normal, e).distance_m;
  }
}

bool report(std::string* what, const char* kind_a, int a, const char* kind_b, int b,
            double distance_m) {
  if (what) {
    char text[160];
    std::snprintf(text, sizeof(text), "%s %d and %s %d overlap by %.3g m", kind_a, a, kind_b, b,
                  -distance_m);
    *what = text;
  }
  return true;
}

}  // namespace

bool bodiesOverlap(const Model& model, const Data& data, std::string* what, double tolerance_m) {
  const int n_kernels = static_cast<int>(model.kernels.size());
  for (int i = 0; i < n_kernels; ++i) {
    const Ellipse e = kernelEllipse(model, data, i);
    for (int k = 0; k < static_cast<int>(model.teeth.size()); ++k) {
      const double d_m = toothDistance(model, data, k, e);
      if (d_m < -tolerance_m) return report(what, "tooth", k, "kernel", i, d_m);
    }
    for (int o = 0; o < static_cast<int>(model.obstacles.size()); ++o) {
      const double d_m = obstacleDistance(model.obstacles[o], e);
      if (d_m < -tolerance_m) return report(what, "kernel", i, "obstacle", o, d_m);
    }
    for (int j = i + 1; j < n_kernels; ++j) {
      const Ellipse f = kernelEllipse(model, data, j);
      // Bounding circles apart: no overlap (and no ellipse-ellipse query).
      if ((e.center - f.center).norm() > e.a_m + f.a_m) continue;
      const double d_m = ellipseEllipse(e, f).distance_m;
      if (d_m < -tolerance_m) return report(what, "kernel", i, "kernel", j, d_m);
    }
  }
  return false;
}

}  // namespace threshing_sim
