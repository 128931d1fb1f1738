// Asynchronous core, stage "wake": what can touch what over one window [t0, t1].
//   - calendar: lazy kernels whose wake time falls in the window are brought to t0 and get a
//     new bound circle (or, when even the window does not fit, a join);
//   - tooth sweeps: the drum's motion over the window is known, so each tooth sweeps a known
//     annular sector (padded by its deflection bound, capsule radius and the margin); lazy
//     kernels' circles and other islands' kernels that meet it are joined to the tooth;
//   - island neighbourhoods: each island kernel's reach over the window (its ellipse grown by
//     its speed bound and two margins) against lazy kernels and other islands' kernels.
// A join is a pair of entity ids (tooth k -> k, kernel i -> T + i) that must share an island.
#include "async.h"

namespace threshing_sim {
namespace internal {
namespace {

constexpr double kTwoPi = 6.283185307179586;

// Bounding box of the annular sector {rho e(phi): phi in [phi0, phi1], rho in [r_in, r_out]}.
void sectorBox(double phi0, double phi1, double r_in, double r_out, Vec2* lo, Vec2* hi) {
  *lo = Vec2::Constant(std::numeric_limits<double>::infinity());
  *hi = -*lo;
  auto add = [&](double phi, double r) {
    const Vec2 p(r * std::cos(phi), r * std::sin(phi));
    *lo = lo->cwiseMin(p);
    *hi = hi->cwiseMax(p);
  };
  add(phi0, r_in), add(phi0, r_out), add(phi1, r_in), add(phi1, r_out);
  // Axis directions inside the angular range reach the outer radius.
  const double q = kTwoPi / 4;
  for (double a = std::ceil(phi0 / q) * q; a <= phi1; a += q) add(a, r_out);
}

// Pad around tooth k's undeformed centreline within which its surface stays over the window:
// deflection bound (generous inside an island, where contact forces work on it), capsule
// radius, margin [m].
double toothPad(const Model& m, const Data& d, const AsyncState& as, int k) {
  const ToothModel& tm = m.teeth[k];
  double deflection = toothDeflectionBound(m, d, as, k);
  if (as.tooth_island[k] >= 0)
    deflection = 2.0 * deflection + m.deflection_validity_fraction * tm.length_m;
  // A rod is inextensible: its every point is within L of its root, whatever the forces.
  if (tm.beam_model == ToothBeamModel::kLargeDeflection)
    deflection = std::min(deflection, tm.length_m);
  return deflection + 0.5 * tm.diameter_m + m.broadphase_margin_m;
}

void joinOnce(AsyncState* as, int a, int b) { as->joins.emplace_back(a, b); }

// Cell coordinate of x [m] in the grids' cells.
std::int64_t cellCoord(const AsyncState& as, double x_m) { return cellFloor(x_m / as.cell_m); }

}  // namespace

double islandReach(const Model& m, const Data& d, int i, double window_s) {
  return kernelSpeedBound(m, d.u, i) * window_s + 2.0 * m.broadphase_margin_m;
}

double islandPairReach(const Model& m, const Data& d, int i, int j, double window_s) {
  const KernelModel& ki = m.kernels[i];
  const KernelModel& kj = m.kernels[j];
  const double v_rel_mps = (d.u.segment<2>(ki.dof_offset) - d.u.segment<2>(kj.dof_offset)).norm() +
                           std::abs(d.u[ki.dof_offset + 2]) * ki.semi_axis_a_m +
                           std::abs(d.u[kj.dof_offset + 2]) * kj.semi_axis_a_m;
  return v_rel_mps * window_s + 4.0 * m.broadphase_margin_m;
}

void listIslandKernels(const Model& m, const Data& d, AsyncState* as, double window_s) {
  as->island_cells.clear();
  as->island_r_max_m = 0.0;
  for (const Island& isl : as->islands) {
    if (!isl.alive) continue;
    for (int i : isl.kernels) {
      const Vec2 c_W = d.z.segment<2>(m.kernels[i].dof_offset);
      as->island_cells.emplace_back(gridCellKey(cellCoord(*as, c_W.x()), cellCoord(*as, c_W.y())),
                                    i);
      as->island_r_max_m =
          std::max(as->island_r_max_m, m.kernels[i].semi_axis_a_m + islandReach(m, d, i, window_s));
    }
  }
  std::sort(as->island_cells.begin(), as->island_cells.end());
}

void islandGridQuery(AsyncState* as, const Vec2& lo, const Vec2& hi) {
  as->found.clear();
  const double pad = as->island_r_max_m;
  const std::int64_t x0 = cellCoord(*as, lo.x() - pad), x1 = cellCoord(*as, hi.x() + pad);
  const std::int64_t y0 = cellCoord(*as, lo.y() - pad), y1 = cellCoord(*as, hi.y() + pad);
  const auto& cells = as->island_cells;
  if ((x1 - x0 + 1) * (y1 - y0 + 1) > static_cast<std::int64_t>(cells.size())) {
    // More cells than island kernels: every island kernel is a candidate.
    for (const auto& entry : cells) as->found.push_back(entry.second);
    return;
  }
  for (std::int64_t cy = y0; cy <= y1; ++cy) {
    for (std::int64_t cx = x0; cx <= x1; ++cx) {
      const std::int64_t key = gridCellKey(cx, cy);
      auto it = std::lower_bound(cells.begin(), cells.end(), std::make_pair(key, -1));
      for (; it != cells.end() && it->first == key; ++it) as->found.push_back(it->second);
    }
  }
}

double sectorDistance(const Vec2& p, double phi0, double phi1, double r_in, double r_out) {
  const double rho = p.norm();
  double rel = std::atan2(p.y(), p.x()) - phi0;
  rel -= kTwoPi * std::floor(rel / kTwoPi);
  if (rel <= phi1 - phi0) return std::max({0.0, r_in - rho, rho - r_out});
  auto toSegment = [&](double phi) {
    const Vec2 e(std::cos(phi), std::sin(phi));
    const double s = std::clamp(p.dot(e), r_in, r_out);
    return (p - s * e).norm();
  };
  return std::min(toSegment(phi0), toSegment(phi1));
}

SweptSector sweptSector(double phi0_rad, double phi1_rad, double r_in_m, double r_out_m) {
  SweptSector sec;
  sec.phi0_rad = phi0_rad;
  sec.phi1_rad = phi1_rad;
  sec.r_in_m = r_in_m;
  sec.r_out_m = r_out_m;
  sec.e0_W = Vec2(std::cos(phi0_rad), std::sin(phi0_rad));
  sec.e1_W = Vec2(std::cos(phi1_rad), std::sin(phi1_rad));
  return sec;
}

double sectorEllipseGapBound(const SweptSector& sec, const OrientedEllipse& e) {
  const double circle_m =
      sectorDistance(e.center_W, sec.phi0_rad, sec.phi1_rad, sec.r_in_m, sec.r_out_m) - e.a_m;
  const double span_rad = sec.phi1_rad - sec.phi0_rad;
  if (!(span_rad < 0.5 * kTwoPi)) return circle_m;
  // Normal t(phi) of the line through the drum axis along e(phi). The centre's side of it,
  // t(phi).c = |c| sin(phi_c - phi), keeps one sign over the range when the ends agree, and
  // its size is smallest at an end (sin is concave there). The ellipse's support along t(phi)
  // is within a |t(phi) - t(end)| <= a span / 2 of its support at the nearer end.
  const Vec2 t0(-sec.e0_W.y(), sec.e0_W.x()), t1(-sec.e1_W.y(), sec.e1_W.x());
  const double s0_m = t0.dot(e.center_W), s1_m = t1.dot(e.center_W);
  if (!((s0_m > 0.0 && s1_m > 0.0) || (s0_m < 0.0 && s1_m < 0.0))) return circle_m;
  auto support = [&e](const Vec2& n) {
    const Vec2& u = e.axis_W;
    const double na_m = e.a_m * n.dot(u), nb_m = e.b_m * (u.x() * n.y() - u.y() * n.x());
    return std::sqrt(na_m * na_m + nb_m * nb_m);
  };
  const double beside_m = std::min(std::abs(s0_m), std::abs(s1_m)) -
                          std::max(support(t0), support(t1)) - 0.5 * e.a_m * span_rad;
  return std::max(circle_m, beside_m);
}

bool wakeDueKernels(const Model& m, Data* d, AsyncState* as, double t0, double t1) {
  for (int i = heapTop(*as); i >= 0 && as->kernels[i].wake_s < t1; i = heapTop(*as)) {
    heapRemove(as, i);
    gridRemove(as, i);
    if (!advanceLazyKernel(m, d, as, i, t0)) return false;
    predictKernel(m, *d, as, i, t0, t1);
  }
  return true;
}

namespace {
// A lazy kernel j met by something whose reach leaves it room_m [m] of growth: if its speed
// bound lets it stay lazy over the window within that room, it is brought to t0 and given a
// new, smaller bound circle, and stays lazy (returns true). DynamO's re-prediction of the
// neighbours: the island does not swallow a kernel only because its old circle was large.
bool tryShrink(const Model& m, Data* d, AsyncState* as, int j, double t0, double t1,
               double room_m) {
  if (!(room_m > 0.0) || as->kernels[j].t_s > t0) return false;
  if (lazySpeedBound(m, *d, *as, j, t1 - t0) * (t1 - t0) >= room_m) return false;
  heapRemove(as, j);
  gridRemove(as, j);
  if (!advanceLazyKernel(m, d, as, j, t0)) return false;
  ++as->counters.shrinks;
  return predictKernel(m, *d, as, j, t0, t1, room_m);
}
}  // namespace

void sweepTeeth(const Model& m, Data* d, AsyncState* as, double t0, double t1) {
  const Drive end = driveAt(m, *d, t1 - t0);
  const double th_lo = std::min(d->theta_rad, end.theta_rad);
  const double th_hi = std::max(d->theta_rad, end.theta_rad);
  const int T = static_cast<int>(m.teeth.size());
  for (int k = 0; k < T; ++k) {
    const ToothModel& tm = m.teeth[k];
    const double pad = toothPad(m, *d, *as, k);
    const double r_in = tm.p_DR_D.norm(), r_out = r_in + tm.length_m;
    const SweptSector sec =
        sweptSector(th_lo + tm.mount_angle_rad, th_hi + tm.mount_angle_rad, r_in, r_out);
    Vec2 lo, hi;
    sectorBox(sec.phi0_rad, sec.phi1_rad, r_in, r_out, &lo, &hi);
    // Whole cells beyond the padded annulus [r_in, r_out] are skipped (the test below would
    // skip each of their kernels).
    gridQueryAnnulus(as, lo - Vec2(pad, pad), hi + Vec2(pad, pad), r_in - pad, r_out + pad);
    as->found_copy = as->found;  // tryShrink queries the grid again
    for (int j : as->found_copy) {
      const KernelClock& kj = as->kernels[j];
      if (!kj.in_grid) continue;  // re-listed or joined meanwhile
      // A bound circle beyond the padded annulus [r_in, r_out]: clear of the sector (the test
      // below would say so too, since the ellipse bound is at least the circle's distance).
      const double rho = kj.bound_c_W.norm();
      if (rho - kj.bound_r_m > r_out + pad || rho + kj.bound_r_m < r_in - pad) continue;
      // Its ellipse, grown by its bound circle's growth, against the padded sector.
      const double gap = sectorEllipseGapBound(sec, orientedKernel(m, d->z, *as, j));
      if (gap - (kj.bound_r_m - m.kernels[j].semi_axis_a_m) > pad) continue;
      if (tryShrink(m, d, as, j, t0, t1, gap - pad)) continue;
      joinOnce(as, k, T + j);
      ++as->counters.tooth_wakes;
    }
    // Kernels of other islands, through the island grid.
    islandGridQuery(as, lo - Vec2(pad, pad), hi + Vec2(pad, pad));
    for (int i : as->found) {
      if (as->kernels[i].island == as->tooth_island[k]) continue;
      const double gap = sectorEllipseGapBound(sec, orientedKernel(m, d->z, *as, i));
      if (gap - islandReach(m, *d, i, t1 - t0) <= pad) joinOnce(as, k, T + i);
    }
  }
}

namespace {
// Lazy kernels that island kernel i may reach over the window [t0, t1] (through the grid of
// bound circles; each bound circle, then the ellipse bound): a neighbour whose speed bound
// keeps it clear is given a smaller circle (tryShrink), any other joins i's island.
void lazyNeighbours(const Model& m, Data* d, AsyncState* as, int i, double t0, double t1) {
  const int T = static_cast<int>(m.teeth.size());
  const OrientedEllipse ei = orientedKernel(m, d->z, *as, i);
  const double grow_i = islandReach(m, *d, i, t1 - t0);
  const double box_m = ei.a_m + grow_i;
  gridQuery(as, ei.center_W - Vec2(box_m, box_m), ei.center_W + Vec2(box_m, box_m));
  as->found_copy = as->found;  // tryShrink queries the grid again
  for (int j : as->found_copy) {
    const KernelClock& kj = as->kernels[j];
    if (!kj.in_grid) continue;
    const double circles_m = kj.bound_r_m + box_m;
    if ((kj.bound_c_W - ei.center_W).squaredNorm() > circles_m * circles_m) continue;
    const double grow_j = kj.bound_r_m - m.kernels[j].semi_axis_a_m;
    const double gap = ellipseGapBound(ei, orientedKernel(m, d->z, *as, j));
    if (gap > grow_i + grow_j) continue;
    if (tryShrink(m, d, as, j, t0, t1, gap - grow_i)) continue;
    joinOnce(as, T + i, T + j);
    ++as->counters.kernel_wakes;
  }
}

// Kernels of later island slots than s (each pair of islands once) that island kernel i may
// touch over the window, through the island grid and the pair's relative speed bound.
void islandKernelNeighbours(const Model& m, const Data& d, AsyncState* as, int s, int i,
                            double window_s) {
  const int T = static_cast<int>(m.teeth.size());
  const OrientedEllipse ei = orientedKernel(m, d.z, *as, i);
  const double box_m = ei.a_m + islandReach(m, d, i, window_s);
  islandGridQuery(as, ei.center_W - Vec2(box_m, box_m), ei.center_W + Vec2(box_m, box_m));
  for (int i2 : as->found) {
    if (as->kernels[i2].island <= s) continue;
    if (pairMayTouch(ei, orientedKernel(m, d.z, *as, i2), islandPairReach(m, d, i, i2, window_s)))
      joinOnce(as, T + i, T + i2);
  }
}
}  // namespace

void islandNeighbours(const Model& m, Data* d, AsyncState* as, double t0, double t1) {
  for (size_t s = 0; s < as->islands.size(); ++s) {
    if (!as->islands[s].alive) continue;
    for (int i : as->islands[s].kernels) {
      lazyNeighbours(m, d, as, i, t0, t1);
      islandKernelNeighbours(m, *d, as, static_cast<int>(s), i, t1 - t0);
    }
  }
}

void islandProximity(const Model& m, const Data& d, const AsyncState& as, int s, double window_s,
                     std::vector<std::pair<int, int>>* edges, std::vector<std::uint8_t>* pinned) {
  const Island& isl = as.islands[s];
  const int nT = static_cast<int>(isl.teeth.size()), nK = static_cast<int>(isl.kernels.size());
  edges->clear();
  pinned->assign(nT + nK, 0);
  // Pairs in contact.
  for (const auto& entry : isl.data().ws->memory) {
    if (entry.second.state == ContactState::kSeparated) continue;
    const std::uint64_t key = entry.first;
    const int a = static_cast<int>((key >> 30) & 0x3fffffff),
              b = static_cast<int>(key & 0x3fffffff);
    switch (static_cast<PairKind>(key >> 60)) {
      case PairKind::kToothKernel:
        edges->emplace_back(a, nT + b);
        break;
      case PairKind::kKernelKernel:
        edges->emplace_back(nT + a, nT + b);
        break;
      default:
        (*pinned)[nT + a] = 1;
    }
  }
  // Pairs within reach over the next window.
  const Drive end = driveAt(m, d, window_s);
  const double th_lo = std::min(d.theta_rad, end.theta_rad);
  const double th_hi = std::max(d.theta_rad, end.theta_rad);
  for (int a = 0; a < nT; ++a) {
    const ToothModel& tm = m.teeth[isl.teeth[a]];
    const double pad = toothPad(m, d, as, isl.teeth[a]);
    const double r_in = tm.p_DR_D.norm(), r_out = r_in + tm.length_m;
    const SweptSector sec =
        sweptSector(th_lo + tm.mount_angle_rad, th_hi + tm.mount_angle_rad, r_in, r_out);
    for (int b = 0; b < nK; ++b) {
      const int i = isl.kernels[b];
      const double gap = sectorEllipseGapBound(sec, orientedKernel(m, d.z, as, i));
      if (gap - islandReach(m, d, i, window_s) <= pad) edges->emplace_back(a, nT + b);
    }
  }
  for (int a = 0; a < nK; ++a) {
    const int i = isl.kernels[a];
    const OrientedEllipse ei = orientedKernel(m, d.z, as, i);
    for (int b = a + 1; b < nK; ++b) {
      const int j = isl.kernels[b];
      if (pairMayTouch(ei, orientedKernel(m, d.z, as, j), islandPairReach(m, d, i, j, window_s)))
        edges->emplace_back(nT + a, nT + b);
    }
    const double grow_i = islandReach(m, d, i, window_s);
    for (const ObstacleModel& o : m.obstacles)
      if (obstacleClearance(o, ei.center_W) - ei.a_m <= grow_i) (*pinned)[nT + a] = 1;
  }
}

}  // namespace internal
}  // namespace threshing_sim
