// threshing_sim core: bodies overlapping one another at a placement (the scene loader's start
// check, and the node's check before a reset puts the kernels back at their start poses).
//
// Kernels are tested against the kernels before them (a uniform grid of cells two largest
// semi-axes wide, so n kernels cost O(n) ellipse tests instead of O(n^2)), the teeth as
// undeformed capsules (radius d/2 from root to tip) at a given drum angle, and the obstacles.
#pragma once

#include <cstdint>
#include <string>
#include <unordered_map>
#include <vector>

#include "threshing_sim/core/data.h"
#include "threshing_sim/core/geometry.h"
#include "threshing_sim/core/model.h"

namespace threshing_sim {

// The nearest body to one kernel, or the first overlap found.
struct Overlap {
  bool found = false;                             // some kernel overlaps some body
  int kernel = -1;                                // index of the kernel
  PairKind other_kind = PairKind::kKernelKernel;  // what the other body is
  int other = -1;                                 // its index (kernel, tooth or obstacle)
  double distance_m = 0;                          // signed distance (negative: overlap depth) [m]
};

// "kernels.3 overlaps teeth.0 by 0.00123 m" (or "no overlap").
std::string describe(const Overlap& overlap);
// "kernels.2", "teeth.0", "obstacles.1".
std::string bodyName(PairKind kind, int index);

// Kernels by the grid cell of their centre, for neighbour queries in O(1) per kernel.
class KernelGrid {
 public:
  // cell_m: at least twice the largest bounding radius (semi-axis a) of the kernels inserted.
  explicit KernelGrid(double cell_m);
  void insert(int kernel, const Vec2& center_m);
  // Calls f(kernel) for each inserted kernel whose centre lies in the 3 x 3 cells around
  // center_m: every kernel whose bounding circle can reach a circle of radius cell_m / 2 there.
  template <class F>
  void forEachNear(const Vec2& center_m, F f) const {
    const std::int64_t cx = cellOf(center_m.x()), cy = cellOf(center_m.y());
    for (std::int64_t dx = -1; dx <= 1; ++dx)
      for (std::int64_t dy = -1; dy <= 1; ++dy) {
        const auto it = cells_.find(key(cx + dx, cy + dy));
        if (it == cells_.end()) continue;
        for (int k : it->second) f(k);
      }
  }

 private:
  std::int64_t cellOf(double x_m) const;
  static std::int64_t key(std::int64_t cx, std::int64_t cy) { return cx * 0x100000001LL + cy; }
  double cell_m_;
  std::unordered_map<std::int64_t, std::vector<int>> cells_;
};

// The ellipse of a kernel model at pose (c, psi).
Ellipse kernelEllipseAt(const KernelModel& k, const Vec2& c_m, double psi_rad);

// Smallest signed distance from the ellipse e to the undeformed teeth at drum angle theta_rad
// and to the obstacles; *nearest receives the body (kernel left -1).
double clearanceFromFixedBodies(const Model& model, double theta_rad, const Ellipse& e,
                                Overlap* nearest);

// First kernel (in index order) overlapping an earlier kernel, a tooth or an obstacle, with
// the kernels at their initial poses and the undeformed teeth at drum angle theta_rad: what
// resetBodiesKeepTime() would produce at that angle. found = false when all are clear.
Overlap findInitialOverlap(const Model& model, double theta_rad);

// The same for the current kernel poses of data (teeth undeformed at data.theta_rad).
Overlap findOverlap(const Model& model, const Data& data);

}  // namespace threshing_sim
