// The asynchronous island-local scheduler (src/core/async/): its stages against closed forms and
// brute force, and the whole scheme against the global one (integrator.islands: false) on
// models built in code. Scene-file agreement: test/scene/test_islands_scenes.cc.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <random>

#include "../../src/core/async/async.h"
#include "sim_test_util.h"
#include "threshing_sim/core/large_deflection.h"
#include "threshing_sim/core/simulator.h"
#include "threshing_sim/core/step_observer.h"

namespace threshing_sim {
namespace {

using internal::AsyncState;
using testutil::kPi;

// --- wake.cc: the swept sector -----------------------------------------------------------------

TEST(Wake, SectorDistanceClosedForms) {
  const double r_in = 0.2, r_out = 0.26;
  // Inside the angular range: radial distance to the annulus (zero inside it).
  EXPECT_DOUBLE_EQ(internal::sectorDistance(Vec2(0.23, 0.0), -0.1, 0.1, r_in, r_out), 0.0);
  EXPECT_NEAR(internal::sectorDistance(Vec2(0.30, 0.0), -0.1, 0.1, r_in, r_out), 0.04, 1e-15);
  EXPECT_NEAR(internal::sectorDistance(Vec2(0.15, 0.0), -0.1, 0.1, r_in, r_out), 0.05, 1e-15);
  // Beyond the range: distance to the nearest bounding segment (here the one at angle 0.1).
  const Vec2 p = 0.23 * Vec2(std::cos(0.1 + 0.05), std::sin(0.1 + 0.05));
  EXPECT_NEAR(internal::sectorDistance(p, -0.1, 0.1, r_in, r_out), 0.23 * std::sin(0.05), 1e-12);
  // Angles wrap: a sector across +-pi.
  EXPECT_DOUBLE_EQ(internal::sectorDistance(Vec2(-0.23, 1e-3), kPi - 0.1, kPi + 0.1, r_in, r_out),
                   0.0);
}

TEST(Wake, SectorDistanceIsTheDistanceToSampledSegments) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-0.4, 0.4), ang(-4.0, 4.0), span(0.0, 0.5);
  for (int n = 0; n < 500; ++n) {
    const Vec2 p(u(rng), u(rng));
    const double phi0 = ang(rng), phi1 = phi0 + span(rng);
    double best = std::numeric_limits<double>::infinity();
    for (int s = 0; s <= 2000; ++s) {
      const double phi = phi0 + (phi1 - phi0) * s / 2000.0;
      const Vec2 e(std::cos(phi), std::sin(phi));
      const double t = std::clamp(p.dot(e), 0.2, 0.26);
      best = std::min(best, (p - t * e).norm());
    }
    // Sampling the angle at 2000 points leaves at most 0.26 x span / 2000 of slack.
    const double got = internal::sectorDistance(p, phi0, phi1, 0.2, 0.26);
    EXPECT_LE(got, best + 1e-12);
    EXPECT_GE(got, best - 0.26 * (phi1 - phi0) / 2000.0 - 1e-12);
  }
}

// --- body_motion.cc: the large-deflection rod's deflection bound ----------------------------

// A free rod (soft: E = 5 MPa, 6 shape functions) released bent by a tip load to about 0.3 L
// and moving, on the drum at 800 rpm: the bound its Jacobi energy gives at the start holds the
// centreline's distance from its undeformed line at every step after, over 20 ms (more than a
// period of its first mode), and is not loose by more than a small factor.
TEST(RodDeflectionBound, HoldsWhileTheRodMovesFreely) {
  Model m = testutil::defaultSceneModel(IntegratorType::kEventDriven);
  m.integrator.islands = false;
  m.teeth[0].beam_model = ToothBeamModel::kLargeDeflection;
  m.teeth[0].youngs_modulus_Pa = 5e6;
  m.teeth[0].n_modes = 6;
  m.kernels[0].initial_position_m = Vec2(-0.3, -0.3);  // far from the tooth
  m.duration_s = 0.02;
  compileModel(&m);
  const ToothModel& tm = m.teeth[0];
  Data d;
  resetData(m, &d);
  VecX q;
  ldStaticTipLoad(tm, Vec2(0.0, 0.7), &q);  // PL^2 / EI about 1
  d.z.segment(tm.dof_offset, tm.n_modes) = q;
  d.u.segment(tm.dof_offset, tm.n_modes) = -0.5 * q / 0.01;
  auto distance = [&](const Data& data) {
    double worst = 0.0;
    for (int s = 1; s <= 20; ++s) {
      const double x = tm.length_m * s / 20.0;
      worst = std::max(
          worst, std::hypot(toothDeflection(m, data, 0, x), toothForeshortening(m, data, 0, x)));
    }
    return worst;
  };
  AsyncState as;
  const double bound = internal::toothDeflectionBound(m, d, as, 0);
  const double start = distance(d);
  EXPECT_GT(start, 0.2 * tm.length_m);
  double largest = start;
  while (d.t_s < m.duration_s) {
    ASSERT_NE(step(m, &d), StepStatus::kFailed);
    largest = std::max(largest, distance(d));
  }
  std::printf("ROD_BOUND start %.4f L, largest %.4f L, bound %.4f L\n", start / tm.length_m,
              largest / tm.length_m, bound / tm.length_m);
  EXPECT_LE(largest, bound);
  EXPECT_LE(bound, 3.0 * largest);
}

// --- calendar.cc: heap and grid -------------------------------------------------------------

AsyncState gridState(int n, double cell_m) {
  AsyncState as;
  as.kernels.assign(n, internal::KernelClock());
  as.cell_m = cell_m;
  as.r_cap_m = 0.5 * cell_m;
  as.cell_key.assign(64, internal::kEmptyCell);
  as.cell_head.assign(64, -1);
  return as;
}

// gridQueryAnnulus: gridQuery's list, in its order, less only circles clear of the annulus
// (whole cells out of it are dropped; some are, over these queries).
TEST(Calendar, AnnulusQueryDropsOnlyCirclesClearOfTheAnnulus) {
  const int n = 400;
  AsyncState as = gridState(n, 0.02);
  std::mt19937 rng(13);
  std::uniform_real_distribution<double> u(-0.3, 0.3), r(0.001, 0.01), w(0.0, 0.1);
  for (int i = 0; i < n; ++i) {
    as.kernels[i].bound_c_W = Vec2(u(rng), u(rng));
    as.kernels[i].bound_r_m = r(rng);
    internal::gridInsert(&as, i);
  }
  for (int i = 0; i < n; i += 5) internal::gridRemove(&as, i);
  long dropped = 0, kept = 0;
  for (int q = 0; q < 300; ++q) {
    const Vec2 lo(u(rng), u(rng));
    const Vec2 hi = lo + Vec2(w(rng), w(rng));
    const double r_lo = 0.2 + 0.5 * u(rng), r_hi = r_lo + w(rng);
    internal::gridQuery(&as, lo, hi);
    const std::vector<int> all = as.found;
    internal::gridQueryAnnulus(&as, lo, hi, r_lo, r_hi);
    const std::vector<int> some = as.found;
    size_t p = 0;
    for (int j : all) {
      if (p < some.size() && some[p] == j) {
        ++p;
        ++kept;
        continue;
      }
      const internal::KernelClock& k = as.kernels[j];
      const double rho = k.bound_c_W.norm();
      EXPECT_TRUE(rho - k.bound_r_m > r_hi || rho + k.bound_r_m < r_lo)
          << "kernel " << j << " query " << q;
      ++dropped;
    }
    EXPECT_EQ(p, some.size()) << "query " << q;  // nothing else, in gridQuery's order
  }
  EXPECT_GT(dropped, 100);
  EXPECT_GT(kept, 100);
}

TEST(Calendar, HeapPopsByWakeTimeThenIndex) {
  AsyncState as = gridState(200, 0.01);
  std::mt19937 rng(3);
  std::uniform_int_distribution<int> t(0, 20);
  for (int i = 0; i < 200; ++i) {
    as.kernels[i].wake_s = 1e-3 * t(rng);  // many ties
    internal::heapPush(&as, i);
  }
  for (int i = 0; i < 200; i += 7) internal::heapRemove(&as, i);  // removal from the middle
  double last_t = -1;
  int last_i = -1;
  for (int top = internal::heapTop(as); top >= 0; top = internal::heapTop(as)) {
    const double w = as.kernels[top].wake_s;
    EXPECT_TRUE(w > last_t || (w == last_t && top > last_i));
    EXPECT_NE(top % 7, 0);
    last_t = w;
    last_i = top;
    internal::heapRemove(&as, top);
  }
}

TEST(Calendar, GridQueryFindsEveryCircleMeetingTheBox) {
  const int n = 400;
  AsyncState as = gridState(n, 0.02);
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(-0.3, 0.3), r(0.001, 0.01);
  for (int i = 0; i < n; ++i) {
    as.kernels[i].bound_c_W = Vec2(u(rng), u(rng));
    as.kernels[i].bound_r_m = r(rng);
    internal::gridInsert(&as, i);
  }
  for (int i = 0; i < n; i += 5) internal::gridRemove(&as, i);
  for (int q = 0; q < 200; ++q) {
    const Vec2 lo(u(rng), u(rng));
    const Vec2 hi = lo + Vec2(0.05 * std::abs(u(rng)), 0.05 * std::abs(u(rng)));
    internal::gridQuery(&as, lo, hi);
    std::vector<int> found = as.found;
    std::sort(found.begin(), found.end());
    for (int i = 0; i < n; ++i) {
      const internal::KernelClock& k = as.kernels[i];
      const Vec2 nearest = k.bound_c_W.cwiseMax(lo).cwiseMin(hi);
      const bool meets = (nearest - k.bound_c_W).norm() <= k.bound_r_m;
      const bool listed = std::binary_search(found.begin(), found.end(), i);
      if (i % 5 == 0) {
        EXPECT_FALSE(listed);
      } else if (meets) {
        EXPECT_TRUE(listed) << "kernel " << i << " query " << q;
      }
    }
  }
}

// n kernels on pedicels over a patch of 12 columns 4 mm apart and rows 15.6 mm apart (several to
// a grid cell): those with i % 4 == 1 hang 2 mm aside (they swing), the others at rest.
Model pedicelPatch(int n) {
  Model m = testutil::bareModel(IntegratorType::kEventDriven);
  m.integrator.islands = true;
  m.integrator.tolerance = 1e-6;
  for (int i = 0; i < n; ++i) {
    const Vec2 anchor(0.004 * (i % 12), -0.015625 * (i / 12));
    m.kernels.push_back(testutil::hangingKernel(anchor, i % 4 == 1 ? 2e-3 : 0.0));
  }
  compileModel(&m);
  return m;
}

// The grid as set-up lists it, kept alongside: every kernel listed at set-up in index order,
// each at its cell's head; removals and insertions as gridRemove and gridInsert make them; a
// query lists cell after cell (rows, then columns), each cell's list from its head.
struct ReferenceGrid {
  const AsyncState* as = nullptr;
  std::map<std::int64_t, std::vector<int>> cells;  // cell key -> its kernels, head first
  std::vector<std::int64_t> cell_of;               // per kernel: its cell while listed
  std::int64_t cellAt(const Vec2& c) const {
    return internal::gridCellKey(internal::cellFloor(c.x() / as->cell_m),
                                 internal::cellFloor(c.y() / as->cell_m));
  }
  void insert(int i) {
    cell_of[i] = cellAt(as->kernels[i].bound_c_W);
    std::vector<int>& l = cells[cell_of[i]];
    l.insert(l.begin(), i);
  }
  void remove(int i) {
    std::vector<int>& l = cells[cell_of[i]];
    l.erase(std::find(l.begin(), l.end(), i));
  }
  std::vector<int> query(const Vec2& lo, const Vec2& hi) const {
    std::vector<int> out;
    const double pad = as->r_cap_m, c = as->cell_m;
    const std::int64_t x0 = internal::cellFloor((lo.x() - pad) / c);
    const std::int64_t x1 = internal::cellFloor((hi.x() + pad) / c);
    const std::int64_t y0 = internal::cellFloor((lo.y() - pad) / c);
    const std::int64_t y1 = internal::cellFloor((hi.y() + pad) / c);
    if ((x1 - x0 + 1) * (y1 - y0 + 1) > static_cast<std::int64_t>(as->cell_key.size())) {
      for (size_t i = 0; i < as->kernels.size(); ++i)
        if (as->kernels[i].in_grid) out.push_back(static_cast<int>(i));
      return out;
    }
    for (std::int64_t cy = y0; cy <= y1; ++cy) {
      for (std::int64_t cx = x0; cx <= x1; ++cx) {
        const auto it = cells.find(internal::gridCellKey(cx, cy));
        if (it != cells.end()) out.insert(out.end(), it->second.begin(), it->second.end());
      }
    }
    return out;
  }
};

// The sleeping field (kernels asleep at set-up, their cells not written) is written into the
// grid only when a query may reach it, and then where set-up would have listed it: every query
// lists the same kernels in the same order as a grid that listed every kernel at set-up, through
// removals and insertions of swinging kernels before and of any kernel after; a sweep's annulus
// clear of the field passes it over without writing it.
TEST(Calendar, TheSleepingFieldIsListedWhereSetUpListsIt) {
  const int n = 96;
  const Model m = pedicelPatch(n);
  Data d;
  resetData(m, &d);
  AsyncState as;
  ASSERT_EQ(internal::listKernelsAtSetUp(m, d, &as), n / 4);  // the swinging ones
  ASSERT_EQ(as.field_unlisted, n - n / 4);
  ReferenceGrid ref;
  ref.as = &as;
  ref.cell_of.assign(n, 0);
  for (int i = 0; i < n; ++i) ref.insert(i);
  std::mt19937 rng(29);
  std::uniform_real_distribution<double> ux(-0.02, 0.07), uy(-0.15, 0.01), w(0.0, 0.03);
  auto moveAndInsert = [&](int i) {
    as.kernels[i].bound_c_W = Vec2(ux(rng), uy(rng));
    internal::gridInsert(&as, i);
    ref.insert(i);
  };
  // Before the field is written: swinging kernels leave the grid, some come back elsewhere;
  // queries away from the field and a sweep clear of it do not write it.
  for (int i = 1; i < n; i += 8) {
    internal::gridRemove(&as, i);
    ref.remove(i);
    if (i % 16 == 1) moveAndInsert(i);
  }
  internal::gridQuery(&as, Vec2(0.5, 0.5), Vec2(0.52, 0.52));
  EXPECT_TRUE(as.found.empty());
  const Vec2 lo(-0.02, -0.15), hi(0.07, 0.01);
  internal::gridQueryAnnulus(&as, lo, hi, 0.3, 0.35);  // beyond every centre (|c| < 0.16 m)
  EXPECT_EQ(as.field_unlisted, n - n / 4);
  for (int j : as.found) EXPECT_NE(as.kernels[j].listing, internal::GridListing::kUnlisted);
  // The first query that may reach it writes it, where set-up would have.
  internal::gridQuery(&as, Vec2(0.01, -0.05), Vec2(0.02, -0.04));
  EXPECT_EQ(as.field_unlisted, 0);
  EXPECT_EQ(as.found, ref.query(Vec2(0.01, -0.05), Vec2(0.02, -0.04)));
  // Then any kernel leaves and comes back, between queries.
  std::uniform_int_distribution<int> pick(0, n - 1), op(0, 3);
  int compared = 0;
  for (int q = 0; q < 600; ++q) {
    const int i = pick(rng);
    if (op(rng) == 0) {
      if (as.kernels[i].in_grid) {
        internal::gridRemove(&as, i);
        ref.remove(i);
      } else {
        moveAndInsert(i);
      }
      continue;
    }
    const Vec2 a(ux(rng), uy(rng)), b = a + Vec2(w(rng), w(rng));
    internal::gridQuery(&as, a, b);
    ASSERT_EQ(as.found, ref.query(a, b)) << "query " << q;
    compared += static_cast<int>(as.found.size());
  }
  EXPECT_GT(compared, 1000);
}

// --- calendar.cc / wake.cc: bounds without trigonometry ---------------------------------------

internal::OrientedEllipse oriented(const Vec2& c_W, double psi_rad, double a_m, double b_m) {
  internal::OrientedEllipse e;
  e.center_W = c_W;
  e.axis_W = Vec2(std::cos(psi_rad), std::sin(psi_rad));
  e.a_m = a_m;
  e.b_m = b_m;
  return e;
}

Ellipse plain(const Vec2& c_W, double psi_rad, double a_m, double b_m) {
  Ellipse e;
  e.center = c_W;
  e.angle_rad = psi_rad;
  e.a_m = a_m;
  e.b_m = b_m;
  return e;
}

// The supporting-line bound never exceeds the exact signed distance (ellipseEllipse), apart or
// overlapping, and is exact for two discs.
TEST(Bounds, EllipseGapBoundNeverExceedsTheDistance) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> pos(-0.015, 0.015), ang(-4.0, 4.0), a(1e-3, 6e-3),
      ratio(0.2, 1.0);
  int apart = 0, overlapping = 0;
  for (int n = 0; n < 4000; ++n) {
    const double a1 = a(rng), a2 = a(rng), b1 = a1 * ratio(rng), b2 = a2 * ratio(rng);
    const Vec2 c1(pos(rng), pos(rng)), c2(pos(rng), pos(rng));
    const double p1 = ang(rng), p2 = ang(rng);
    const double exact = ellipseEllipse(plain(c1, p1, a1, b1), plain(c2, p2, a2, b2)).distance_m;
    const double bound =
        internal::ellipseGapBound(oriented(c1, p1, a1, b1), oriented(c2, p2, a2, b2));
    EXPECT_LE(bound, exact + 1e-12) << "case " << n;
    (exact > 0 ? apart : overlapping) += 1;
  }
  EXPECT_GT(apart, 500);
  EXPECT_GT(overlapping, 250);
  const double discs = internal::ellipseGapBound(oriented(Vec2(0, 0), 0.3, 2e-3, 2e-3),
                                                 oriented(Vec2(5e-3, 1e-3), -1.0, 1e-3, 1e-3));
  EXPECT_NEAR(discs, std::sqrt(26e-6) - 3e-3, 1e-15);
}

// pairMayTouch with the relative speed bound of two rigidly moving ellipses never claims
// separation for a pair that touches within the window (exact distance along the motion).
TEST(Bounds, PairMayTouchIsConservativeOverTheWindow) {
  std::mt19937 rng(9);
  std::uniform_real_distribution<double> pos(-0.02, 0.02), ang(-4.0, 4.0), vel(-20.0, 20.0),
      spin(-3000.0, 3000.0), ratio(0.2, 1.0);
  const double a1 = 5e-3, a2 = 4e-3, window_s = 2e-4;
  int separated = 0, touched = 0, close_calls = 0;
  for (int n = 0; n < 3000; ++n) {
    const double b1 = a1 * ratio(rng), b2 = a2 * ratio(rng);
    const Vec2 c1(pos(rng), pos(rng)), c2(pos(rng), pos(rng));
    const Vec2 v1(vel(rng), vel(rng)), v2(vel(rng), vel(rng));
    const double p1 = ang(rng), p2 = ang(rng), w1 = spin(rng), w2 = spin(rng);
    const double reach_m = ((v1 - v2).norm() + std::abs(w1) * a1 + std::abs(w2) * a2) * window_s;
    const bool may =
        internal::pairMayTouch(oriented(c1, p1, a1, b1), oriented(c2, p2, a2, b2), reach_m);
    const double start = ellipseEllipse(plain(c1, p1, a1, b1), plain(c2, p2, a2, b2)).distance_m;
    double closest = std::numeric_limits<double>::infinity();
    for (int k = 0; k <= 200; ++k) {
      const double t = window_s * k / 200.0;
      closest = std::min(closest, ellipseEllipse(plain(c1 + t * v1, p1 + t * w1, a1, b1),
                                                 plain(c2 + t * v2, p2 + t * w2, a2, b2))
                                      .distance_m);
    }
    if (!may) {
      ++separated;
      EXPECT_GT(closest, 0.0) << "case " << n << ": claimed apart, touches within the window";
      if (closest < 0.5 * start) ++close_calls;  // it closed half its gap within the window
    }
    if (closest <= 0.0) ++touched;
  }
  EXPECT_GT(separated, 300);
  EXPECT_GT(touched, 300);
  EXPECT_GT(close_calls, 20);  // pairs that close in fast are among those claimed apart
}

// The sector bound never exceeds the distance from the ellipse to the swept sector (its radial
// segments sampled finely, each distance exact), and beats the bounding circle for thin
// kernels beside the sweep.
TEST(Bounds, SectorEllipseGapBoundNeverExceedsTheDistance) {
  std::mt19937 rng(21);
  std::uniform_real_distribution<double> rad(0.17, 0.23), ang(-0.2, 0.2), psi(-4.0, 4.0),
      span(0.0, 0.05);
  const double r_in = 0.14, r_out = 0.2, a = 5e-3, b = 1.3e-3;
  int sharper = 0, near = 0;
  for (int n = 0; n < 1500; ++n) {
    // Centres near the sweep, and every third one anywhere around the drum axis.
    const double phi0 = ang(rng), phi1 = phi0 + span(rng), rho = rad(rng);
    const double phi_c = n % 3 == 2 ? psi(rng) : 2.0 * ang(rng);
    const Vec2 c(rho * std::cos(phi_c), rho * std::sin(phi_c));
    // Half the cases radial (the stream's kernels), half at random angles.
    const double psi_rad = n % 2 == 0 ? phi_c : psi(rng);
    const internal::SweptSector sec = internal::sweptSector(phi0, phi1, r_in, r_out);
    const double bound = internal::sectorEllipseGapBound(sec, oriented(c, psi_rad, a, b));
    double sampled = std::numeric_limits<double>::infinity();
    for (int k = 0; k <= 1000; ++k) {
      const double phi = phi0 + (phi1 - phi0) * k / 1000.0;
      const Vec2 e(std::cos(phi), std::sin(phi));
      sampled = std::min(sampled,
                         segmentEllipse(r_in * e, r_out * e, plain(c, psi_rad, a, b)).distance_m);
    }
    EXPECT_LE(bound, std::max(sampled, 0.0) + 1e-12) << "case " << n;
    const double circle = internal::sectorDistance(c, phi0, phi1, r_in, r_out) - a;
    if (bound > circle + 1e-3) ++sharper;
    if (sampled > 0.0 && sampled < 3e-3) ++near;
  }
  EXPECT_GT(sharper, 100);
  EXPECT_GT(near, 25);
}

TEST(Bounds, OrientedKernelCachesTheAxisOfTheCurrentAngle) {
  Model m = testutil::bareModel(IntegratorType::kEventDriven);
  m.kernels = {testutil::makeKernel(5e-3, 1.3e-3, Vec2(0.01, 0.02), Vec2::Zero(), 0.4)};
  compileModel(&m);
  Data d;
  resetData(m, &d);
  AsyncState as;
  as.kernels.assign(1, internal::KernelClock());
  for (double psi : {0.4, 0.4, -2.0, 3.0, 3.0}) {
    d.z[m.kernels[0].dof_offset + 2] = psi;
    const internal::OrientedEllipse e = internal::orientedKernel(m, d.z, as, 0);
    EXPECT_EQ(e.axis_W.x(), std::cos(psi));
    EXPECT_EQ(e.axis_W.y(), std::sin(psi));
    EXPECT_EQ(e.center_W, Vec2(0.01, 0.02));
  }
}

// The neighbour search of islands (islandNeighbours through the lazy grid and the island grid)
// finds exactly the pairs within reach of a brute-force O(N^2) pass: island kernels against
// lazy kernels (ellipse bound against the two growths) and against kernels of later islands
// (pairMayTouch with the pair's relative speed bound).
TEST(IslandGrid, NeighbourSearchFindsExactlyThePairsWithinReach) {
  const int n = 300, n_islands = 12;
  Model m = testutil::bareModel(IntegratorType::kEventDriven);
  std::mt19937 rng(17);
  std::uniform_real_distribution<double> pos(-0.08, 0.08), ang(-4.0, 4.0), vel(-15.0, 15.0),
      u01(0.0, 1.0);
  for (int i = 0; i < n; ++i)
    m.kernels.push_back(testutil::makeKernel(5e-3, 1.3e-3, Vec2(pos(rng), pos(rng)),
                                             Vec2(vel(rng), vel(rng)), ang(rng)));
  compileModel(&m);
  Data d;
  resetData(m, &d);
  for (int i = 0; i < n; ++i) d.u[m.kernels[i].dof_offset + 2] = 2000.0 * (u01(rng) - 0.5);
  AsyncState as;
  as.kernels.assign(n, internal::KernelClock());
  as.r_cap_m = 5e-3 + 4.0 * m.broadphase_margin_m;
  as.cell_m = 2.0 * as.r_cap_m;
  as.cell_key.assign(2048, internal::kEmptyCell);
  as.cell_head.assign(2048, -1);
  as.entity_slot.assign(n, -1);
  as.islands.resize(n_islands);
  // A third of the kernels in islands, the rest lazy with bound circles (clocks past the
  // window's start, so that none is re-predicted: every pair within reach must join).
  const double t0 = 0.0, t1 = 1e-4;
  for (int i = 0; i < n; ++i) {
    internal::KernelClock& kc = as.kernels[i];
    if (i % 3 == 0) {
      const int s = (i / 3) % n_islands;
      as.islands[s].alive = s != 5;  // one dead slot
      if (s == 5) continue;
      as.islands[s].kernels.push_back(i);
      kc.motion = internal::KernelMotion::kIsland;
      kc.island = s;
    } else {
      kc.t_s = 1.0;
      kc.bound_c_W = d.z.segment<2>(m.kernels[i].dof_offset);
      kc.bound_r_m = 5e-3 + (as.r_cap_m - 5e-3) * u01(rng);
      internal::gridInsert(&as, i);
    }
  }
  internal::listIslandKernels(m, d, &as, t1 - t0);
  internal::islandNeighbours(m, &d, &as, t0, t1);
  const int T = static_cast<int>(m.teeth.size());
  std::vector<std::pair<int, int>> got, want;
  for (const auto& jn : as.joins) got.emplace_back(jn.first - T, jn.second - T);
  for (int i = 0; i < n; ++i) {
    const int s = as.kernels[i].island;
    if (s < 0) continue;
    const internal::OrientedEllipse ei = internal::orientedKernel(m, d.z, as, i);
    for (int j = 0; j < n; ++j) {
      const internal::KernelClock& kj = as.kernels[j];
      const internal::OrientedEllipse ej = internal::orientedKernel(m, d.z, as, j);
      if (kj.in_grid) {
        const double grow = internal::islandReach(m, d, i, t1 - t0) + kj.bound_r_m - 5e-3;
        if (internal::ellipseGapBound(ei, ej) <= grow) want.emplace_back(i, j);
      } else if (kj.island > s &&
                 internal::pairMayTouch(ei, ej, internal::islandPairReach(m, d, i, j, t1 - t0))) {
        want.emplace_back(i, j);
      }
    }
  }
  std::sort(got.begin(), got.end());
  std::sort(want.begin(), want.end());
  EXPECT_GT(want.size(), 20u);
  EXPECT_EQ(got, want);
  // The island grid alone: every island kernel whose circle meets a box is listed.
  for (int q = 0; q < 100; ++q) {
    const Vec2 lo(pos(rng), pos(rng)), hi = lo + Vec2(0.02 * u01(rng), 0.02 * u01(rng));
    internal::islandGridQuery(&as, lo, hi);
    for (const auto& entry : as.island_cells) {
      const int i = entry.second;
      const Vec2 c = d.z.segment<2>(m.kernels[i].dof_offset);
      const double r = 5e-3 + internal::islandReach(m, d, i, t1 - t0);
      if ((c.cwiseMax(lo).cwiseMin(hi) - c).norm() <= r) {
        EXPECT_NE(std::find(as.found.begin(), as.found.end(), i), as.found.end());
      }
    }
  }
}

// --- body_motion.cc: lone bodies -----------------------------------------------------------

// A lone kernel on its pedicel, far from anything, under both schemes.
Model pedicelModel(IntegratorType type, bool islands) {
  Model m = testutil::bareModel(type);
  KernelModel k = testutil::makeKernel(5e-3, 1.3e-3, Vec2(0.0, 0.0), Vec2(0.0, 0.0), 0.7);
  k.pedicel.present = true;
  k.pedicel.p_WA_W = Vec2(0.0, 0.0) + 8e-3 * Vec2(std::cos(0.7), std::sin(0.7));
  k.pedicel.p_KP_K = Vec2(5e-3, 0.0);
  k.pedicel.stiffness_Npm = 1600.0;
  k.pedicel.damping_Nspm = 0.002;
  k.pedicel.detachment_force_N = 1.6;
  m.kernels.push_back(k);
  m.integrator.islands = islands;
  m.integrator.tolerance = 1e-8;
  compileModel(&m);
  return m;
}

TEST(BodyMotion, PedicelClockAgreesWithTheGlobalIntegrator) {
  Data g, a;
  const Model mg = pedicelModel(IntegratorType::kEventDriven, false);
  const Model ma = pedicelModel(IntegratorType::kEventDriven, true);
  resetData(mg, &g);
  resetData(ma, &a);
  ASSERT_EQ(advanceTo(mg, &g, 0.05), StepStatus::kOk);
  ASSERT_EQ(advanceTo(ma, &a, 0.05), StepStatus::kOk);
  // Same error control on the same equations: the states agree to the tolerance's scale.
  EXPECT_LT((g.z - a.z).norm(), 1e-9);
  EXPECT_LT((g.u - a.u).norm(), 1e-6);
  EXPECT_GT(a.stats.scheduler.pedicel_steps, 0);
  EXPECT_EQ(a.stats.scheduler.island_steps, 0);  // it never needed an island
}

// A field of kernels hanging at rest (each at its static equilibrium, 12 mm apart) and one
// swinging 5 cm beyond them: the resting ones are listed asleep at
// set-up without a prediction (the bulk set-up), stay where they are bit for bit, and the
// swinging one is predicted and moves as under the global scheme.
Model hangingField(bool islands) {
  Model m = testutil::bareModel(IntegratorType::kEventDriven);
  m.integrator.islands = islands;
  m.integrator.tolerance = 1e-8;
  for (int i = 0; i < 41; ++i) {
    const bool swinging = i == 40;  // the last one, 5 cm away, pushed sideways
    const Vec2 anchor(swinging ? 0.53 : 0.012 * i, 0.0);
    m.kernels.push_back(testutil::hangingKernel(anchor, swinging ? 2e-3 : 0.0));
  }
  compileModel(&m);
  return m;
}

TEST(BodyMotion, KernelsAtRestAreListedAsleepWithoutPrediction) {
  const Model ma = hangingField(true), mg = hangingField(false);
  Data a, g;
  resetData(ma, &a);
  resetData(mg, &g);
  const VecX z0 = a.z;
  ASSERT_EQ(advanceTo(ma, &a, 0.002), StepStatus::kOk);
  ASSERT_EQ(advanceTo(mg, &g, 0.002), StepStatus::kOk);
  const SchedulerStats& s = a.stats.scheduler;
  EXPECT_GE(s.asleep, 40);       // the resting ones, at set-up
  EXPECT_GE(s.predictions, 1);   // the swinging one
  EXPECT_LT(s.predictions, 40);  // and no resting one
  const int last = ma.kernels.back().dof_offset;
  for (int d = 0; d < last; ++d) {
    EXPECT_EQ(a.z[d], z0[d]) << d;
    EXPECT_EQ(a.u[d], 0.0) << d;
  }
  // The swinging one moved (by ~0.1 mm), and as under the global scheme to within its lone
  // clock's error (its closed form about the hanging equilibrium); the global scheme's resting
  // kernels stay put too.
  EXPECT_GT((a.z.segment<3>(last) - z0.segment<3>(last)).norm(), 1e-5);
  EXPECT_LT((a.z.head(last) - g.z.head(last)).norm(), 1e-12);
  EXPECT_LT((a.z - g.z).norm(), 1e-6);
}

// restsOnPedicel (set-up's inline at-rest test on the state arrays) decides as lazyAtRestAt,
// over states from at rest to swinging hard (both outcomes).
TEST(BodyMotion, BulkAtRestTestDecidesAsThePedicelRates) {
  const Model m = hangingField(true);
  Data d;
  resetData(m, &d);
  std::mt19937 rng(17);
  std::uniform_real_distribution<double> unit(-1.0, 1.0), decade(-14.0, -2.0);
  int rest = 0, moving = 0;
  for (int n = 0; n < 4000; ++n) {
    const int i = n % 40;
    const KernelModel& k = m.kernels[i];
    Data& p = d;  // perturbed, then restored
    const Eigen::Vector3d z0 = d.z.segment<3>(k.dof_offset), u0 = d.u.segment<3>(k.dof_offset);
    const double scale = std::pow(10.0, decade(rng));
    for (int j = 0; j < 3; ++j) {
      p.z[k.dof_offset + j] += (n % 3 == 0 ? 0.0 : scale) * unit(rng);
      p.u[k.dof_offset + j] = (n % 3 == 1 ? 0.0 : scale) * unit(rng);
    }
    const double psi = p.z[k.dof_offset + 2], horizon = std::pow(10.0, 0.25 * decade(rng));
    const bool bulk = internal::restsOnPedicel(k, m.gravity_mps2, m.integrator.tolerance,
                                               p.z.data() + k.dof_offset, p.u.data() + k.dof_offset,
                                               std::cos(psi), std::sin(psi), horizon);
    const bool rates = internal::lazyAtRestAt(m, p, i, horizon, std::cos(psi), std::sin(psi));
    EXPECT_EQ(bulk, rates) << "sample " << n;
    d.z.segment<3>(k.dof_offset) = z0;
    d.u.segment<3>(k.dof_offset) = u0;
    (rates ? rest : moving) += 1;
  }
  EXPECT_GT(rest, 100);
  EXPECT_GT(moving, 100);
}

// A field at rest out of the tooth's reach is never looked at kernel by kernel while the tooth
// sweeps past window after window: no prediction, no kernel in the sweeps' lists (whole grid
// cells are skipped), and it stays put bit for bit. A lazy kernel in the tooth's path is.
TEST(BodyMotion, AFieldAtRestOutOfReachIsNotLookedAtPerWindow) {
  for (const IntegratorType type : {IntegratorType::kEventDriven, IntegratorType::kTimeStepping}) {
    Model m = testutil::defaultSceneModel(type);
    m.integrator.islands = true;
    m.kernels.clear();
    for (int row = 0; row < 4; ++row) {
      for (int col = 0; col < 25; ++col) {
        // Centres on arcs 15 mm apart from 0.305 m (the tooth reaches 0.26 m), 12 mm apart
        // along them, over the angles the tooth sweeps and beyond: beside its path, not in it.
        const double rho = 0.305 + 0.015 * row, phi = -0.05 + 0.012 * col / rho;
        const Vec2 centre(rho * std::cos(phi), rho * std::sin(phi));
        m.kernels.push_back(testutil::hangingKernel(centre + Vec2(0.0, testutil::kHangDepth_m)));
      }
    }
    compileModel(&m);
    Data d;
    resetData(m, &d);
    const VecX z0 = d.z.tail(3 * 100), u0 = d.u.tail(3 * 100);
    ASSERT_EQ(advanceTo(m, &d, 0.002), StepStatus::kOk);
    const SchedulerStats& s = d.stats.scheduler;
    EXPECT_GE(s.windows, 10);
    EXPECT_EQ(s.asleep, 100);
    EXPECT_EQ(s.predictions, 0);
    EXPECT_EQ(d.ws->async->swept_kernels, 0);
    EXPECT_EQ(d.ws->async->field_unlisted, 100);  // not even written into the grid
    EXPECT_TRUE(testutil::sameBits(d.z.tail(3 * 100), z0));
    EXPECT_TRUE(testutil::sameBits(d.u.tail(3 * 100), u0));
    // The default scene's free kernel, lazy until the tooth reaches it, is looked at.
    Model strike = testutil::defaultSceneModel(type);
    strike.integrator.islands = true;
    compileModel(&strike);
    Data ds;
    resetData(strike, &ds);
    ASSERT_EQ(advanceTo(strike, &ds, 0.002), StepStatus::kOk);
    EXPECT_GT(ds.ws->async->swept_kernels, 0);
  }
}

TEST(BodyMotion, LazySpeedBoundHoldsAlongThePedicelTrajectory) {
  const Model m = pedicelModel(IntegratorType::kEventDriven, false);
  Data d;
  resetData(m, &d);
  AsyncState as;
  as.kernels.assign(1, internal::KernelClock());
  as.kernels[0].motion = internal::KernelMotion::kPedicel;
  const double horizon = 0.02;
  const double bound = internal::lazySpeedBound(m, d, as, 0, horizon);
  for (int s = 1; s <= 200; ++s) {
    ASSERT_EQ(advanceTo(m, &d, horizon * s / 200.0), StepStatus::kOk);
    const double v = internal::kernelSpeedBound(m, d.u, 0);
    EXPECT_LE(v, bound) << "t = " << d.t_s;
  }
}

TEST(BodyMotion, FreeKernelFliesItsParabolaExactly) {
  Model m = testutil::bareModel(IntegratorType::kEventDriven);
  m.kernels.push_back(testutil::makeKernel(5e-3, 1.3e-3, Vec2(0.1, 0.2), Vec2(3.0, 4.0), 0.3));
  m.kernels[0].initial_angular_velocity_radps = 50.0;
  m.integrator.islands = true;
  compileModel(&m);
  Data d;
  resetData(m, &d);
  const double t = 0.037;
  ASSERT_EQ(advanceTo(m, &d, t), StepStatus::kOk);
  const Vec2 c = Vec2(0.1, 0.2) + t * Vec2(3.0, 4.0) + 0.5 * t * t * m.gravity_mps2;
  EXPECT_NEAR((d.z.head<2>() - c).norm(), 0.0, 1e-15);
  EXPECT_NEAR(d.z[2], 0.3 + 50.0 * t, 1e-14);
  EXPECT_EQ(d.stats.scheduler.island_steps, 0);
}

// --- the whole scheme against the global one ---------------------------------------------

class IslandsVsGlobal : public ::testing::TestWithParam<IntegratorType> {};

TEST_P(IslandsVsGlobal, DefaultStrikeAgrees) {
  Model mg = testutil::defaultSceneModel(GetParam());
  mg.integrator.islands = false;
  Model ma = mg;
  ma.integrator.islands = true;
  compileModel(&mg);
  compileModel(&ma);
  Data g, a;
  resetData(mg, &g);
  resetData(ma, &a);
  ASSERT_NE(advanceTo(mg, &g, mg.duration_s), StepStatus::kFailed);
  ASSERT_NE(advanceTo(ma, &a, ma.duration_s), StepStatus::kFailed);
  EXPECT_EQ(a.stats.impacts, g.stats.impacts);
  ASSERT_EQ(a.events.size(), g.events.size());
  for (size_t e = 0; e < g.events.size(); ++e) {
    EXPECT_TRUE(a.events[e].pair == g.events[e].pair);
    EXPECT_EQ(a.events[e].to, g.events[e].to);
    EXPECT_NEAR(a.events[e].t_s, g.events[e].t_s, 1e-9);
  }
  // The contact is integrated by the same scheme from the same state: agreement to round-off
  // and the step sequence's error (well inside the tolerance).
  const double tol = 1e-8;
  EXPECT_NEAR(a.stats.peak_normal_force_N, g.stats.peak_normal_force_N,
              tol * g.stats.peak_normal_force_N);
  EXPECT_LT((a.u.tail<3>() - g.u.tail<3>()).norm(), tol * g.u.tail<3>().norm());
  // The drive's work: time stepping advances a free tooth by the theta-method, the island
  // scheme exactly, so there the two differ within time stepping's own error (h against h/2).
  double drive_tol_J = 1e-9;
  if (GetParam() == IntegratorType::kTimeStepping) {
    Model mh = mg;
    mh.integrator.dt_s *= 0.5;
    Data h;
    resetData(mh, &h);
    ASSERT_NE(advanceTo(mh, &h, mh.duration_s), StepStatus::kFailed);
    drive_tol_J = std::abs(h.stats.drive_work_J - g.stats.drive_work_J);
  }
  EXPECT_NEAR(a.stats.drive_work_J, g.stats.drive_work_J, drive_tol_J);
  // Lone phases cost no island steps: fewer than the global scheme's.
  EXPECT_LT(a.steps, g.steps);
  EXPECT_GT(a.stats.scheduler.free_advances, 0);
}

TEST_P(IslandsVsGlobal, RerunsAreBitIdentical) {
  Model m = testutil::defaultSceneModel(GetParam());
  m.integrator.islands = true;
  compileModel(&m);
  Data a, b;
  resetData(m, &a);
  resetData(m, &b);
  for (int chunk = 1; chunk <= 10; ++chunk) {
    advanceTo(m, &a, m.duration_s * chunk / 10);
    advanceTo(m, &b, m.duration_s * chunk / 10);
  }
  EXPECT_EQ(0, std::memcmp(a.z.data(), b.z.data(), sizeof(double) * a.z.size()));
  EXPECT_EQ(0, std::memcmp(a.u.data(), b.u.data(), sizeof(double) * a.u.size()));
  EXPECT_EQ(a.stats.peak_normal_force_N, b.stats.peak_normal_force_N);
  // A reset replays the same run bit for bit.
  Data c;
  resetData(m, &c);
  advanceTo(m, &c, m.duration_s);
  resetData(m, &c);
  for (int chunk = 1; chunk <= 10; ++chunk) advanceTo(m, &c, m.duration_s * chunk / 10);
  EXPECT_EQ(0, std::memcmp(a.z.data(), c.z.data(), sizeof(double) * a.z.size()));
}

// Records what the island scheme reports of its islands' steps.
class StepCounter : public StepObserver {
 public:
  void islandStep(const Model& model, const IslandStep& step) override {
    ++steps;
    EXPECT_GE(step.t_s, last_t_s[step.kernels->front()]) << "steps of an island in time order";
    last_t_s[step.kernels->front()] = step.t_s;
    for (const ContactInfo& c : *step.contacts) {
      if (c.pair.kind != PairKind::kToothKernel) continue;
      EXPECT_TRUE(std::binary_search(step.teeth->begin(), step.teeth->end(), c.pair.a));
      EXPECT_TRUE(std::binary_search(step.kernels->begin(), step.kernels->end(), c.pair.b));
      peak_N = std::max(peak_N, c.normal_force_N);
      if (c.state != ContactState::kSeparated) ++closed_steps;
    }
    z.setConstant(model.n_dof, std::numeric_limits<double>::quiet_NaN());
    u = z;
    step.writeState(model, &z, &u);
    for (int i : *step.kernels)
      EXPECT_TRUE(z.segment<3>(model.kernels[i].dof_offset).allFinite() &&
                  u.segment<3>(model.kernels[i].dof_offset).allFinite());
  }
  long steps = 0, closed_steps = 0;
  double peak_N = 0;
  std::map<int, double> last_t_s;
  VecX z, u;
};

// An observer of the islands' steps sees every accepted island step (the default strike's
// closed steps among them, in global numbers) and changes nothing: the run is bit for bit the
// unobserved one.
TEST_P(IslandsVsGlobal, ObservingIslandStepsChangesNothing) {
  Model m = testutil::defaultSceneModel(GetParam());
  m.integrator.islands = true;
  compileModel(&m);
  Data a, b;
  resetData(m, &a);
  resetData(m, &b);
  StepCounter counter;
  b.observer = &counter;
  for (int chunk = 1; chunk <= 10; ++chunk) {
    ASSERT_NE(advanceTo(m, &a, m.duration_s * chunk / 10), StepStatus::kFailed);
    ASSERT_NE(advanceTo(m, &b, m.duration_s * chunk / 10), StepStatus::kFailed);
  }
  EXPECT_EQ(0, std::memcmp(a.z.data(), b.z.data(), sizeof(double) * a.z.size()));
  EXPECT_EQ(0, std::memcmp(a.u.data(), b.u.data(), sizeof(double) * a.u.size()));
  EXPECT_EQ(a.t_s, b.t_s);
  EXPECT_EQ(a.steps, b.steps);
  EXPECT_EQ(a.stats.impacts, b.stats.impacts);
  EXPECT_EQ(a.stats.peak_normal_force_N, b.stats.peak_normal_force_N);
  EXPECT_EQ(a.stats.rejected_steps, b.stats.rejected_steps);
  ASSERT_EQ(a.events.size(), b.events.size());
  for (size_t e = 0; e < a.events.size(); ++e) EXPECT_EQ(a.events[e].t_s, b.events[e].t_s);
  // Every island step is reported; the strike's closed steps among them.
  EXPECT_EQ(counter.steps, b.stats.scheduler.island_steps);
  EXPECT_GT(counter.closed_steps, GetParam() == IntegratorType::kEventDriven ? 15 : 2);
  std::printf("observed %ld island steps, %ld closed, peak %.6g N (core %.6g N)\n", counter.steps,
              counter.closed_steps, counter.peak_N, b.stats.peak_normal_force_N);
  EXPECT_GT(counter.peak_N, 0.5 * b.stats.peak_normal_force_N);
  EXPECT_LE(counter.peak_N, b.stats.peak_normal_force_N * (1 + 1e-12));
}

// The energy account (energy now against energy at the start, the drive's work and what the
// impacts dissipated; the rest is the teeth's modal damping) is the global scheme's.
double energyResidual(const Model& m, const Data& d) {
  double lost = 0.0;
  for (const ContactEvent& e : d.events) lost += e.is_impact ? e.energy_lost_J : 0.0;
  return mechanicalEnergy(m, d) - d.stats.energy_initial_J - d.stats.drive_work_J + lost;
}

TEST(IslandsEnergy, AccountMatchesTheGlobalScheme) {
  Model mg = testutil::defaultSceneModel(IntegratorType::kEventDriven);
  mg.integrator.islands = false;
  Model ma = mg;
  ma.integrator.islands = true;
  compileModel(&mg);
  compileModel(&ma);
  Data g, a;
  resetData(mg, &g);
  resetData(ma, &a);
  ASSERT_NE(advanceTo(mg, &g, mg.duration_s), StepStatus::kFailed);
  ASSERT_NE(advanceTo(ma, &a, ma.duration_s), StepStatus::kFailed);
  EXPECT_NEAR(energyResidual(ma, a), energyResidual(mg, g), 1e-9);
  EXPECT_LE(a.stats.max_energy_gain_at_impact_J, 1e-12);
}

INSTANTIATE_TEST_SUITE_P(BothIntegrators, IslandsVsGlobal,
                         ::testing::Values(IntegratorType::kEventDriven,
                                           IntegratorType::kTimeStepping),
                         [](const ::testing::TestParamInfo<IntegratorType>& info) {
                           return info.param == IntegratorType::kEventDriven
                                      ? std::string("EventDriven")
                                      : std::string("TimeStepping");
                         });

}  // namespace
}  // namespace threshing_sim
