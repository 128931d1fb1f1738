// threshing_sim core: the broad phase (broad_phase.h): teeth against kernels, kernels against
// kernels and kernels against obstacles, each by its own pre-selection, then the exact tests of
// the bounding shapes.
#include "broad_phase.h"

#include <algorithm>
#include <cmath>

#include "../internal.h"
#include "planar.h"
#include "stations.h"

namespace threshing_sim {
namespace internal {

void prepareBroadPhase(const Model& m, Workspace* ws) {
  // Obstacles by the lower end of their extent along x; planes have no extent and are always
  // tested.
  const size_t n_obs = m.obstacles.size();
  ws->broad.obstacle_order.clear();
  ws->broad.obstacle_planes.clear();
  ws->broad.obstacle_order.reserve(n_obs);
  ws->broad.obstacle_xmin_m.assign(n_obs, 0.0);
  ws->broad.obstacle_xmax_m.assign(n_obs, 0.0);
  ws->broad.obstacle_max_width_m = 0.0;
  for (size_t j = 0; j < n_obs; ++j) {
    const ObstacleModel& o = m.obstacles[j];
    if (o.type == ObstacleType::kPlane) {
      ws->broad.obstacle_planes.push_back(static_cast<int>(j));
      continue;
    }
    const double lo =
        o.type == ObstacleType::kCircle ? o.center_m.x() : std::min(o.point_m.x(), o.point_b_m.x());
    const double hi =
        o.type == ObstacleType::kCircle ? o.center_m.x() : std::max(o.point_m.x(), o.point_b_m.x());
    ws->broad.obstacle_xmin_m[j] = lo - o.radius_m;
    ws->broad.obstacle_xmax_m[j] = hi + o.radius_m;
    ws->broad.obstacle_max_width_m =
        std::max(ws->broad.obstacle_max_width_m,
                 ws->broad.obstacle_xmax_m[j] - ws->broad.obstacle_xmin_m[j]);
    ws->broad.obstacle_order.push_back(static_cast<int>(j));
  }
  std::sort(ws->broad.obstacle_order.begin(), ws->broad.obstacle_order.end(), [&](int a, int b) {
    return ws->broad.obstacle_xmin_m[a] < ws->broad.obstacle_xmin_m[b] ||
           (ws->broad.obstacle_xmin_m[a] == ws->broad.obstacle_xmin_m[b] && a < b);
  });
  ws->broad.obstacle_sorted_xmin_m.resize(ws->broad.obstacle_order.size());
  for (size_t i = 0; i < ws->broad.obstacle_order.size(); ++i)
    ws->broad.obstacle_sorted_xmin_m[i] = ws->broad.obstacle_xmin_m[ws->broad.obstacle_order[i]];
  // Per tooth, bounds of the stations' displacement from the rigid centreline: the largest
  // |phi_i(x_s)| per mode and the largest Frobenius norm of H(x_s) (>= its largest eigenvalue).
  ws->broad.tooth_phi_max.assign(m.teeth.size(), SmallVec());
  ws->broad.tooth_H_max.assign(m.teeth.size(), 0.0);
  for (size_t k = 0; k < m.teeth.size(); ++k) {
    const ToothModel& tm = m.teeth[k];
    SmallVec& phi_max = ws->broad.tooth_phi_max[k];
    phi_max.setZero(tm.n_modes);
    for (int st = 0; st < tm.n_stations && tm.n_modes > 0; ++st) {
      phi_max = phi_max.cwiseMax(tm.phi_s.row(st).transpose().cwiseAbs());
      ws->broad.tooth_H_max[k] = std::max(ws->broad.tooth_H_max[k], tm.H_s[st].norm());
    }
  }
  // The kernel order of the sweep starts afresh.
  ws->broad.sort_index.clear();
  ws->broad.sort_xmin_m.clear();
  ws->broad.grid_order.clear();
  ws->candidates.reserve(4 * m.kernels.size() * (m.teeth.size() + 4) + 64);
}

namespace {
// Whether kernel i (centre c, bounding radius r = a + margin) is within reach of obstacle o:
// the exact test of the broad phase.
bool obstacleInReach(const ObstacleModel& o, const Vec2& c, double r) {
  double dist = 0.0;
  if (o.type == ObstacleType::kPlane) {
    dist = o.normal.dot(c - o.point_m);
  } else if (o.type == ObstacleType::kCircle) {
    // A bar clearly out of reach along either axis is rejected without a square root (the
    // slack keeps the decision that of the exact test below).
    const double reach_m = (r + o.radius_m) * (1.0 + 1e-9) + 1e-12;
    if (std::abs(c.x() - o.center_m.x()) > reach_m || std::abs(c.y() - o.center_m.y()) > reach_m)
      return false;
    dist = (c - o.center_m).norm() - o.radius_m;
  } else {
    const Vec2 ab = o.point_b_m - o.point_m;
    const double s = std::clamp((c - o.point_m).dot(ab) / ab.squaredNorm(), 0.0, 1.0);
    dist = (c - (o.point_m + s * ab)).norm() - o.radius_m;
  }
  return dist <= r;
}
// Round-off slack of the interval searches below: they only pre-select, the exact tests decide,
// so a pre-selection a little too wide changes nothing [m].
double slackOf(double x_m) { return 1e-9 * (std::abs(x_m) + 1.0); }

// Orders the K bodies by (keyOf(i), i) into order, with keys[j] the key of order[j]. The
// order of the previous call is the starting point (the identity if its size is not K) and is
// repaired by insertion sort: about K comparisons while keys change little between calls. The
// order is total, so the result is the unique sorted order whatever the start.
template <class Key, class KeyOf>
void repairOrder(int K, KeyOf keyOf, std::vector<int>* order, std::vector<Key>* keys) {
  std::vector<int>& o = *order;
  std::vector<Key>& k = *keys;
  if (static_cast<int>(o.size()) != K) {
    o.resize(K);
    for (int i = 0; i < K; ++i) o[i] = i;
  }
  k.resize(K);
  for (int ia = 0; ia < K; ++ia) {
    const int a = o[ia];
    const Key ka = keyOf(a);
    int ib = ia;
    while (ib > 0 && (k[ib - 1] > ka || (k[ib - 1] == ka && o[ib - 1] > a))) {
      o[ib] = o[ib - 1];
      k[ib] = k[ib - 1];
      --ib;
    }
    o[ib] = a;
    k[ib] = ka;
  }
}

// Teeth against kernels: the deformed centreline's bounding box against the kernel's bounding
// circle; only the kernels whose xmin lies in the box's x range (widened by the largest
// kernel, a_max) are tested. Sets *first to the first kernel (in the x order) to test and
// returns the last xmin to test.
double kernelsInBox(const std::vector<double>& xmin, double a_max, const Vec2& lo, const Vec2& hi,
                    double pad, int* first) {
  const double from = lo.x() - pad - 2.0 * a_max, to = hi.x() + pad;
  *first = static_cast<int>(std::lower_bound(xmin.begin(), xmin.end(), from - slackOf(from)) -
                            xmin.begin());
  return to + slackOf(to);  // last xmin to test
}

// Stations on demand: the rigid centreline's box widened by a bound of the deflection,
// |w(x_s)| <= sum_i max_s |phi_i(x_s)| |q_i| and |w_c(x_s)| <= max_s |H(x_s)|_F |q|^2 / 2,
// holds every station. Only a tooth with some kernel in reach of that box has its
// stations computed; without one the exact box below would find none either.
bool toothMayTouch(const Model& m, const VecX& z, int k, double theta_rad, double pad, double a_max,
                   const Workspace* ws) {
  const ToothModel& tm = m.teeth[k];
  const int K = static_cast<int>(m.kernels.size());
  const std::vector<int>& order = ws->broad.sort_index;
  const std::vector<double>& xmin = ws->broad.sort_xmin_m;
  const Rotation2 rot(theta_rad);
  const auto q = z.segment(tm.dof_offset, tm.n_modes);
  // A large-deflection rod stays within its length of the root.
  const double deflection_m =
      tm.beam_model == ToothBeamModel::kLargeDeflection
          ? tm.length_m
          : (tm.n_modes > 0 ? ws->broad.tooth_phi_max[k].dot(q.cwiseAbs()) +
                                  0.5 * ws->broad.tooth_H_max[k] * q.squaredNorm()
                            : 0.0);
  const Vec2 root = rot * (tm.p_DR_D + tm.station_x_m[0] * tm.e1_D);
  const Vec2 tip = rot * (tm.p_DR_D + tm.station_x_m[tm.n_stations - 1] * tm.e1_D);
  const double grow_m = deflection_m * (1.0 + 1e-9) + 1e-9 * (root.norm() + tip.norm() + 1e-3);
  const Vec2 lo_b = root.cwiseMin(tip).array() - grow_m;
  const Vec2 hi_b = root.cwiseMax(tip).array() + grow_m;
  int first = 0;
  const double last = kernelsInBox(xmin, a_max, lo_b, hi_b, pad, &first);
  bool any = false;
  for (int ia = first; ia < K && xmin[ia] <= last && !any; ++ia) {
    const int i = order[ia];
    const Vec2 c = z.segment<2>(m.kernels[i].dof_offset);
    const double r = m.kernels[i].semi_axis_a_m + pad;
    any = !(c.x() + r < lo_b.x() || c.x() - r > hi_b.x() || c.y() + r < lo_b.y() ||
            c.y() - r > hi_b.y());
  }
  return any;
}

// Tooth-kernel candidates of every tooth (see kernelsInBox), with the stations computed on
// demand where stations_theta_rad is given (see toothMayTouch).
void toothKernelCandidates(const Model& m, const VecX& z, double margin_m, double a_max,
                           const double* stations_theta_rad, Workspace* ws) {
  const int K = static_cast<int>(m.kernels.size());
  const std::vector<int>& order = ws->broad.sort_index;
  const std::vector<double>& xmin = ws->broad.sort_xmin_m;
  for (size_t k = 0; k < m.teeth.size(); ++k) {
    const ToothModel& tm = m.teeth[k];
    const double pad = 0.5 * tm.diameter_m + margin_m;
    if (stations_theta_rad != nullptr) {
      if (!toothMayTouch(m, z, static_cast<int>(k), *stations_theta_rad, pad, a_max, ws)) continue;
      updateToothStations(m, z, *stations_theta_rad, static_cast<int>(k), ws);
    }
    const int s0 = ws->centreline.station_offset[k], s1 = ws->centreline.station_offset[k + 1];
    Vec2 lo = ws->centreline.stations_W[s0], hi = lo;
    for (int s = s0 + 1; s < s1; ++s) {
      lo = lo.cwiseMin(ws->centreline.stations_W[s]);
      hi = hi.cwiseMax(ws->centreline.stations_W[s]);
    }
    int first = 0;
    const double last = kernelsInBox(xmin, a_max, lo, hi, pad, &first);
    for (int ia = first; ia < K && xmin[ia] <= last; ++ia) {
      const int i = order[ia];
      const Vec2 c = z.segment<2>(m.kernels[i].dof_offset);
      const double r = m.kernels[i].semi_axis_a_m + pad;
      if (c.x() + r < lo.x() || c.x() - r > hi.x() || c.y() + r < lo.y() || c.y() - r > hi.y())
        continue;
      ws->candidates.push_back({PairKind::kToothKernel, static_cast<int>(k), i});
    }
  }
}

// Kernels against kernels: a uniform grid of cells as wide as the longest reach
// (2 a_max + margin, widened against round-off), so that two kernels in reach lie in the same
// or adjacent cells. Kernels are kept ordered by (cell row, cell column, index), repaired by
// insertion sort from the previous order (cells change rarely). Each kernel looks at the
// rest of its own cell, the next cell of its row and the three cells of the next row: a
// half stencil, so that each pair is met once.
void kernelKernelCandidates(const Model& m, const VecX& z, double margin_m, double a_max,
                            Workspace* ws) {
  const int K = static_cast<int>(m.kernels.size());
  const double cell_m = (2.0 * a_max + margin_m) * (1.0 + 1e-9) + 1e-12;
  std::vector<int>& g_order = ws->broad.grid_order;
  std::vector<std::int64_t>& g_key = ws->broad.grid_key;
  ws->broad.grid_cell.resize(K);
  // Cell coordinates, clamped (a kernel far away or not finite goes to the last cell).
  auto cellOf = [&](double x_m) {
    const double f = std::floor(x_m / cell_m);
    return static_cast<std::int64_t>(f >= -1e9 && f <= 1e9 ? f : 1e9);
  };
  const std::int64_t kRow = std::int64_t(1) << 32;  // key = row * 2^32 + column
  for (int i = 0; i < K; ++i) {
    const Vec2 c = z.segment<2>(m.kernels[i].dof_offset);
    ws->broad.grid_cell[i] = cellOf(c.y()) * kRow + cellOf(c.x());
  }
  repairOrder<std::int64_t>(
      K, [&](int i) { return ws->broad.grid_cell[i]; }, &g_order, &g_key);
  auto testPair = [&](int a, const Vec2& ca, double ra, int b) {
    const Vec2 cb = z.segment<2>(m.kernels[b].dof_offset);
    const double rr = ra + m.kernels[b].semi_axis_a_m + margin_m;
    if ((cb - ca).squaredNorm() > rr * rr) return;
    ws->candidates.push_back({PairKind::kKernelKernel, std::min(a, b), std::max(a, b)});
  };
  for (int ia = 0; ia < K; ++ia) {
    const int a = g_order[ia];
    const Vec2 ca = z.segment<2>(m.kernels[a].dof_offset);
    const double ra = m.kernels[a].semi_axis_a_m;
    const std::int64_t key = g_key[ia];
    // The rest of this cell and the next cell of the row.
    for (int ib = ia + 1; ib < K && g_key[ib] <= key + 1; ++ib) testPair(a, ca, ra, g_order[ib]);
    // The three cells of the next row.
    const std::int64_t lo = key + kRow - 1, hi = key + kRow + 1;
    for (int ib = static_cast<int>(std::lower_bound(g_key.begin() + ia + 1, g_key.end(), lo) -
                                   g_key.begin());
         ib < K && g_key[ib] <= hi; ++ib)
      testPair(a, ca, ra, g_order[ib]);
  }
}

// Kernels against obstacles: planes always; bars and plates only those whose x extent can
// meet the kernel's reach (found by bisection in the obstacles' xmin order).
void kernelObstacleCandidates(const Model& m, const VecX& z, double margin_m, Workspace* ws) {
  const int K = static_cast<int>(m.kernels.size());
  const std::vector<double>& obs_xmin = ws->broad.obstacle_sorted_xmin_m;
  for (int i = 0; i < K; ++i) {
    const Vec2 c = z.segment<2>(m.kernels[i].dof_offset);
    const double r = m.kernels[i].semi_axis_a_m + margin_m;
    for (int j : ws->broad.obstacle_planes)
      if (obstacleInReach(m.obstacles[j], c, r))
        ws->candidates.push_back({PairKind::kKernelObstacle, i, j});
    const double reach_lo = c.x() - r, to = c.x() + r;
    const double from = reach_lo - ws->broad.obstacle_max_width_m;
    const size_t first = static_cast<size_t>(
        std::lower_bound(obs_xmin.begin(), obs_xmin.end(), from - slackOf(from)) -
        obs_xmin.begin());
    for (size_t jo = first; jo < obs_xmin.size() && obs_xmin[jo] <= to + slackOf(to); ++jo) {
      const int j = ws->broad.obstacle_order[jo];
      if (ws->broad.obstacle_xmax_m[j] < reach_lo - slackOf(reach_lo)) continue;
      if (obstacleInReach(m.obstacles[j], c, r))
        ws->candidates.push_back({PairKind::kKernelObstacle, i, j});
    }
  }
}
}  // namespace

void broadPhase(const Model& m, const VecX& z, double margin_m, Workspace* ws,
                const double* stations_theta_rad) {
  ws->candidates.clear();
  const int K = static_cast<int>(m.kernels.size());
  if (ws->broad.obstacle_xmin_m.size() != m.obstacles.size() ||
      ws->broad.tooth_H_max.size() != m.teeth.size())
    prepareBroadPhase(m, ws);
  // Kernels by the lower end of their bounding circle along x (kernels move little between
  // steps: the previous order is repaired).
  repairOrder<double>(
      K, [&](int i) { return z[m.kernels[i].dof_offset] - m.kernels[i].semi_axis_a_m; },
      &ws->broad.sort_index, &ws->broad.sort_xmin_m);
  double a_max = 0.0;
  for (int i = 0; i < K; ++i) a_max = std::max(a_max, m.kernels[i].semi_axis_a_m);
  toothKernelCandidates(m, z, margin_m, a_max, stations_theta_rad, ws);
  kernelKernelCandidates(m, z, margin_m, a_max, ws);
  kernelObstacleCandidates(m, z, margin_m, ws);
  std::sort(ws->candidates.begin(), ws->candidates.end());
}

void broadPhaseBruteForce(const Model& m, const VecX& z, double margin_m, Workspace* ws) {
  ws->candidates.clear();
  const int K = static_cast<int>(m.kernels.size());
  // Every tooth against every kernel, bounding box against bounding circle.
  for (size_t k = 0; k < m.teeth.size(); ++k) {
    const int s0 = ws->centreline.station_offset[k], s1 = ws->centreline.station_offset[k + 1];
    Vec2 lo = ws->centreline.stations_W[s0], hi = lo;
    for (int s = s0 + 1; s < s1; ++s) {
      lo = lo.cwiseMin(ws->centreline.stations_W[s]);
      hi = hi.cwiseMax(ws->centreline.stations_W[s]);
    }
    const double pad = 0.5 * m.teeth[k].diameter_m + margin_m;
    for (int i = 0; i < K; ++i) {
      const Vec2 c = z.segment<2>(m.kernels[i].dof_offset);
      const double r = m.kernels[i].semi_axis_a_m + pad;
      if (c.x() + r < lo.x() || c.x() - r > hi.x() || c.y() + r < lo.y() || c.y() - r > hi.y())
        continue;
      ws->candidates.push_back({PairKind::kToothKernel, static_cast<int>(k), i});
    }
  }
  // Every kernel pair, bounding circles.
  for (int a = 0; a < K; ++a) {
    for (int b = a + 1; b < K; ++b) {
      const Vec2 d = z.segment<2>(m.kernels[b].dof_offset) - z.segment<2>(m.kernels[a].dof_offset);
      const double rr = m.kernels[a].semi_axis_a_m + m.kernels[b].semi_axis_a_m + margin_m;
      if (d.squaredNorm() <= rr * rr) ws->candidates.push_back({PairKind::kKernelKernel, a, b});
    }
  }
  // Every kernel against every obstacle.
  for (int i = 0; i < K; ++i) {
    const Vec2 c = z.segment<2>(m.kernels[i].dof_offset);
    const double r = m.kernels[i].semi_axis_a_m + margin_m;
    for (size_t j = 0; j < m.obstacles.size(); ++j)
      if (obstacleInReach(m.obstacles[j], c, r))
        ws->candidates.push_back({PairKind::kKernelObstacle, i, static_cast<int>(j)});
  }
  std::sort(ws->candidates.begin(), ws->candidates.end());
}

}  // namespace internal
}  // namespace threshing_sim
