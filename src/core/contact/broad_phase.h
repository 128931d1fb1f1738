// threshing_sim core, private: the broad phase, the candidate pairs whose bounding shapes are
// within a margin (src/core/contact/broad_phase.cc).
#pragma once

#include <cstdint>
#include <vector>

#include "../small_vec.h"
#include "threshing_sim/core/data.h"
#include "threshing_sim/core/model.h"

namespace threshing_sim {
namespace internal {

// The broad phase's orders and bounds, kept across calls (Workspace::broad).
struct BroadPhaseScratch {
  std::vector<int> sort_index;          // sweep-and-prune order of the kernels (kept across steps)
  std::vector<double> sort_xmin_m;      // their bounding circles' lower x, in that order [m]
  std::vector<int> grid_order;          // kernels by grid cell (kernel pairs; kept across steps)
  std::vector<std::int64_t> grid_key;   // their cells (row * 2^32 + column), in that order
  std::vector<std::int64_t> grid_cell;  // cell of each kernel, by kernel index
  std::vector<int> obstacle_order;      // bars and plates (not planes) by increasing xmin
  std::vector<double> obstacle_sorted_xmin_m;            // their xmin in that order [m]
  std::vector<double> obstacle_xmin_m, obstacle_xmax_m;  // x extent per obstacle [m]
  double obstacle_max_width_m = 0;      // largest xmax - xmin of a bar or plate [m]
  std::vector<int> obstacle_planes;     // planes (unbounded: tested against every kernel)
  std::vector<SmallVec> tooth_phi_max;  // per tooth, max_s |phi_i(x_s)| [1/sqrt(kg)]
  std::vector<double> tooth_H_max;      // per tooth, max_s |H(x_s)|_F [1/(kg m)]
};

// Broad phase: pairs whose bounding shapes are within margin_m; fills ws->candidates, sorted.
// Requires updateStations for z first. Kernel pairs through a uniform grid, teeth against
// kernels by bisection in the kernels' x order, kernels against obstacles by bisection in the
// obstacles' x order; the kernels' orders are kept from the previous call and repaired by
// insertion sort (O(K) while kernels move little). The cost per call is O(K + candidates +
// pairs in neighbouring cells), not O(K^2) nor O(K x obstacles).
// With stations_theta_rad, the tooth stations are not required first: broadPhase lays them
// out and computes them (at that drum angle) only for the teeth that can have a candidate;
// the other teeth's stations are left stale.
void broadPhase(const Model& m, const VecX& z, double margin_m, Workspace* ws,
                const double* stations_theta_rad = nullptr);
// The same candidates by testing every pair (O(K^2 + K x obstacles)); the reference of the
// broad phase's tests.
void broadPhaseBruteForce(const Model& m, const VecX& z, double margin_m, Workspace* ws);
// Per-model set-up of the broad phase (obstacles' x order, a fresh kernel order); resetData
// calls it, and broadPhase when the obstacle count changed.
void prepareBroadPhase(const Model& m, Workspace* ws);

}  // namespace internal
}  // namespace threshing_sim
