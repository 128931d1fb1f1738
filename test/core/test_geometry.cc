// Tests of the planar distance queries (geometry.h) against closed forms and brute force.
//
// Brute force: the boundary is sampled densely in its parameter t (x = a cos t, y = b sin t) and
// the best sample is polished by a golden-section search between its neighbours, so the
// reference is exact to about 1e-12 of the ellipse size. Tolerances below are stated relative to
// that size.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <random>
#include <vector>

#include "../../src/core/cos_sin_memo.h"
#include "threshing_sim/core/constants.h"
#include "threshing_sim/core/geometry.h"

namespace threshing_sim {
namespace {

constexpr int kBruteSamples = 20000;

Ellipse makeEllipse(double cx_m, double cy_m, double angle_rad, double a_m, double b_m) {
  Ellipse e;
  e.center = Vec2(cx_m, cy_m);
  e.angle_rad = angle_rad;
  e.a_m = a_m;
  e.b_m = b_m;
  return e;
}

Vec2 rotate(const Vec2& v, double angle_rad) {
  const double c = std::cos(angle_rad), s = std::sin(angle_rad);
  return Vec2(c * v.x() - s * v.y(), s * v.x() + c * v.y());
}

// Boundary point at parameter t, and a point's coordinates in the ellipse frame.
Vec2 boundaryPoint(const Ellipse& e, double t_rad) {
  return e.center + rotate(Vec2(e.a_m * std::cos(t_rad), e.b_m * std::sin(t_rad)), e.angle_rad);
}
Vec2 toEllipseFrame(const Ellipse& e, const Vec2& p) { return rotate(p - e.center, -e.angle_rad); }

// Implicit function (x/a)^2 + (y/b)^2 - 1 of a world point: negative inside.
double implicitValue(const Ellipse& e, const Vec2& p) {
  const Vec2 q = toEllipseFrame(e, p);
  return q.x() * q.x() / (e.a_m * e.a_m) + q.y() * q.y() / (e.b_m * e.b_m) - 1.0;
}

// Outward unit normal at a boundary point.
Vec2 outwardNormal(const Ellipse& e, const Vec2& q_W) {
  const Vec2 q = toEllipseFrame(e, q_W);
  return rotate(Vec2(q.x() / (e.a_m * e.a_m), q.y() / (e.b_m * e.b_m)).normalized(), e.angle_rad);
}

// Minimum of f over [lo, hi] (unimodal there) by golden section, to rounding.
template <typename F>
double goldenMinimum(const F& f, double lo, double hi) {
  for (int i = 0; i < 100; ++i) {
    const double m1 = lo + 0.381966 * (hi - lo), m2 = hi - 0.381966 * (hi - lo);
    if (f(m1) < f(m2)) {
      hi = m2;
    } else {
      lo = m1;
    }
  }
  return f(0.5 * (lo + hi));
}

// Minimum of f over [lo, hi]: dense sampling, then golden section between the best sample's
// neighbours.
template <typename F>
double bruteMinimum(const F& f, double lo, double hi, int n_samples) {
  const double step = (hi - lo) / n_samples;
  int best_k = 0;
  double best = f(lo);
  for (int k = 1; k <= n_samples; ++k) {
    const double v = f(lo + k * step);
    if (v < best) best = v, best_k = k;
  }
  return std::fmin(best, goldenMinimum(f, lo + std::fmax(best_k - 1, 0) * step,
                                       lo + std::fmin(best_k + 1, n_samples) * step));
}

// Minimum of f(t) over one turn of the boundary parameter.
template <typename F>
double bruteMinOverTurn(const F& f) {
  return bruteMinimum(f, 0.0, 2.0 * kPi, kBruteSamples);
}

// Signed distance from p to the ellipse boundary by brute force.
double bruteSignedDistance(const Vec2& p, const Ellipse& e) {
  const double d = bruteMinOverTurn([&](double t) { return (boundaryPoint(e, t) - p).norm(); });
  return implicitValue(e, p) < 0 ? -d : d;
}

// Minimum over e1's boundary of the signed distance to e2 (exact point-ellipse query, checked
// separately), by dense sampling of e1's boundary; for separated pairs it is their distance.
double bruteBoundaryDistance(const Ellipse& e1, const Ellipse& e2) {
  return bruteMinOverTurn(
      [&](double t) { return pointEllipse(boundaryPoint(e1, t), e2).distance_m; });
}

// Signed distance of a pair by brute force from both boundaries: the true distance when
// separated; negative whenever they overlap (crossing boundaries or one inside the other).
double bruteEllipseDistance(const Ellipse& e1, const Ellipse& e2) {
  return std::fmin(bruteBoundaryDistance(e1, e2), bruteBoundaryDistance(e2, e1));
}

// Invariants of every result whose body 2 is the ellipse e: point2 on the boundary (1e-12
// relative: rounding of the projection), unit normal equal to minus the outward normal there,
// and point2 - point1 = distance * normal (1e-12 of the scale).
void expectConsistent(const Proximity& r, const Ellipse& e, double scale_m) {
  EXPECT_NEAR(implicitValue(e, r.point2), 0.0, 1e-12);
  EXPECT_NEAR(r.normal.norm(), 1.0, 1e-14);
  EXPECT_LT((r.normal + outwardNormal(e, r.point2)).norm(), 1e-9);
  EXPECT_LT((r.point2 - r.point1 - r.distance_m * r.normal).norm(), 1e-12 * scale_m);
}

// Random draws are sequenced (argument evaluation order is unspecified) so that every compiler
// generates the same shapes. A random vector in the square of half-width h_m:
Vec2 randomVector(std::mt19937* rng, double h_m) {
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  const double x_m = h_m * unit(*rng);
  return Vec2(x_m, h_m * unit(*rng));
}

// A random ellipse with semi-major axis in [0.5, 2] m, the given aspect ratio, any angle,
// centred in a box of half-width box_m.
Ellipse randomEllipse(std::mt19937* rng, double aspect, double box_m) {
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  const double a_m = 0.5 + 1.5 * unit(*rng);
  const double cx_m = box_m * (2 * unit(*rng) - 1);
  const double cy_m = box_m * (2 * unit(*rng) - 1);
  const double angle_rad = 2 * kPi * unit(*rng);
  return makeEllipse(cx_m, cy_m, angle_rad, a_m, a_m / aspect);
}

// ----------------------------------------------------------------------------------------------
// Point - ellipse

// Random points inside and outside, for a circle up to a/b = 100: brute force agrees to 1e-10
// (brute-force polish and rounding are at 1e-12).
TEST(PointEllipse, MatchesBruteForceInsideAndOutside) {
  std::mt19937 rng(1);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  for (const double aspect : {1.0, 1.2, 2.0, 5.0, 20.0, 100.0}) {
    const Ellipse e = makeEllipse(0.3, -0.2, 0.7, 1.0, 1.0 / aspect);
    int n_inside = 0;
    for (int i = 0; i < 100; ++i) {
      // Half of the points are drawn close to the boundary, where the ellipse is most curved.
      Vec2 p = e.center + randomVector(&rng, 2.0);
      if (i % 2 == 1) {
        const Vec2 q = boundaryPoint(e, kPi * unit(rng));
        p = q + randomVector(&rng, 0.02);
      }
      const Proximity r = pointEllipse(p, e);
      EXPECT_NEAR(r.distance_m, bruteSignedDistance(p, e), 1e-10) << "aspect " << aspect;
      EXPECT_EQ(r.point1, p);
      expectConsistent(r, e, 1.0);
      n_inside += r.distance_m < 0;
    }
    EXPECT_GT(n_inside, 5) << "aspect " << aspect;
  }
}

// Points on the axes: closed forms. On the major axis near the centre the closest point leaves
// the axis, at distance b sqrt(1 - x^2 / (a^2 - b^2)); beyond x = (a^2 - b^2)/a it is the vertex.
TEST(PointEllipse, PointsOnTheAxes) {
  const double a = 2.0, b = 0.5;
  const Ellipse e = makeEllipse(1.0, 2.0, 0.4, a, b);
  const auto at = [&](double x, double y) {
    return pointEllipse(e.center + rotate(Vec2(x, y), 0.4), e);
  };
  // Major axis, outside and inside beyond the evolute's cusp: the a-vertex.
  for (const double x : {3.0, 2.0, 1.95, -1.95, -5.0}) {
    const Proximity r = at(x, 0.0);
    EXPECT_NEAR(r.distance_m, std::abs(x) - a, 1e-14) << x;
    EXPECT_LT((toEllipseFrame(e, r.point2) - Vec2(std::copysign(a, x), 0)).norm(), 1e-14);
  }
  // Major axis near the centre: off-axis closest point.
  for (const double x : {0.0, 0.5, -1.2, 1.8}) {
    const Proximity r = at(x, 0.0);
    EXPECT_NEAR(r.distance_m, -b * std::sqrt(1 - x * x / (a * a - b * b)), 1e-14) << x;
    expectConsistent(r, e, a);
  }
  // Minor axis, inside and outside: the b-vertex.
  for (const double y : {0.3, 0.5, -0.1, 1.5, -4.0}) {
    const Proximity r = at(0.0, y);
    EXPECT_NEAR(r.distance_m, std::abs(y) - b, 1e-14) << y;
    EXPECT_LT((toEllipseFrame(e, r.point2) - Vec2(0, std::copysign(b, y))).norm(), 1e-14);
  }
}

// The centre of a circle is equidistant from the whole boundary: the answer is the point on the
// a-axis (deterministic); the centre of a proper ellipse projects onto the b-vertex.
TEST(PointEllipse, CentreIsDeterministic) {
  const Ellipse circle = makeEllipse(1.0, -1.0, 0.3, 0.7, 0.7);
  const Proximity r = pointEllipse(circle.center, circle);
  EXPECT_DOUBLE_EQ(r.distance_m, -0.7);
  EXPECT_LT((r.point2 - (circle.center + 0.7 * Vec2(std::cos(0.3), std::sin(0.3)))).norm(), 1e-15);
  expectConsistent(r, circle, 1.0);

  const Ellipse e = makeEllipse(1.0, -1.0, 0.3, 0.7, 0.2);
  const Proximity s = pointEllipse(e.center, e);
  EXPECT_NEAR(s.distance_m, -0.2, 1e-15);
  EXPECT_LT((toEllipseFrame(e, s.point2) - Vec2(0, 0.2)).norm(), 1e-15);
}

// Boundary points are at distance 0 (to rounding, 1e-14 of the size) and project onto
// themselves; the normal is still minus the outward normal.
TEST(PointEllipse, BoundaryPointsHaveZeroDistance) {
  for (const double aspect : {1.0, 3.0, 100.0}) {
    const Ellipse e = makeEllipse(-0.5, 0.25, 2.0, 1.5, 1.5 / aspect);
    for (int k = 0; k < 64; ++k) {
      const Vec2 q = boundaryPoint(e, 2 * kPi * k / 64 + 0.01);
      const Proximity r = pointEllipse(q, e);
      EXPECT_NEAR(r.distance_m, 0.0, 1e-14);
      EXPECT_LT((r.point2 - q).norm(), 1e-14);
      EXPECT_LT((r.normal + outwardNormal(e, q)).norm(), 1e-9);
    }
  }
}

// Very far, very near and very eccentric (a/b = 1e4) inputs stay accurate: a far point on the
// minor axis at exactly D - b; near points at their offset along the normal (1e-15: rounding of
// the offset point itself).
TEST(PointEllipse, ExtremeInputs) {
  const Ellipse e = makeEllipse(0.0, 0.0, 0.0, 1.0, 1e-4);
  const Proximity far = pointEllipse(Vec2(0.0, 1e6), e);
  EXPECT_NEAR(far.distance_m, 1e6 - 1e-4, 1e-9);
  for (int k = 1; k < 16; ++k) {
    const Vec2 q = boundaryPoint(e, 2 * kPi * k / 16 + 0.1);
    // Inner offsets stay below the half-width b sin(t) >= 1e-5 of the ellipse at these t.
    for (const double offset_m : {1e-9, -1e-9, 1e-5, -1e-7}) {
      const Proximity r = pointEllipse(q + offset_m * outwardNormal(e, q), e);
      EXPECT_NEAR(r.distance_m, offset_m, 1e-15) << k << " " << offset_m;
      EXPECT_LT((r.point2 - q).norm(), 1e-14);
    }
  }
}

// ----------------------------------------------------------------------------------------------
// Segment - ellipse

// Random segments, many crossing: the minimum over s of the exact signed distance, by dense
// sampling of s plus golden polish (f is convex), agrees to 1e-10.
TEST(SegmentEllipse, MatchesBruteForceOverTheSegment) {
  std::mt19937 rng(2);
  for (const double aspect : {1.0, 1.5, 4.0, 30.0}) {
    const Ellipse e = makeEllipse(0.1, 0.2, -0.4, 1.0, 1.0 / aspect);
    int n_crossing = 0;
    for (int i = 0; i < 60; ++i) {
      const Vec2 p0 = e.center + randomVector(&rng, 2.5);
      const Vec2 p1 = e.center + randomVector(&rng, 2.5);
      const auto f = [&](double s) { return pointEllipse(p0 + s * (p1 - p0), e).distance_m; };
      const double best = bruteMinimum(f, 0.0, 1.0, 2000);
      const Proximity r = segmentEllipse(p0, p1, e);
      EXPECT_NEAR(r.distance_m, best, 1e-10) << "aspect " << aspect << " i " << i;
      EXPECT_GE(r.param, 0.0);
      EXPECT_LE(r.param, 1.0);
      EXPECT_LT((r.point1 - (p0 + r.param * (p1 - p0))).norm(), 1e-15);
      expectConsistent(r, e, 1.0);
      n_crossing += r.distance_m < 0;
    }
    EXPECT_GT(n_crossing, 5);
  }
}

// A segment across the minor axis through the centre: the deepest point is the centre (where
// the slope jumps), depth b; an oblique crossing is negative too.
TEST(SegmentEllipse, CrossingSegmentGivesTheDeepestPoint) {
  const Ellipse e = makeEllipse(1.0, 1.0, 0.5, 2.0, 1.0);
  const Vec2 minor = rotate(Vec2(0, 1), 0.5);
  const Proximity r = segmentEllipse(e.center - 3.0 * minor, e.center + 1.0 * minor, e);
  EXPECT_NEAR(r.distance_m, -1.0, 1e-12);
  EXPECT_NEAR(r.param, 0.75, 1e-12);
  expectConsistent(r, e, 2.0);

  const Proximity s = segmentEllipse(e.center + Vec2(-3, -0.4), e.center + Vec2(3, 0.9), e);
  EXPECT_LT(s.distance_m, -0.5);
  expectConsistent(s, e, 2.0);
}

// A segment crossing the medial axis (|x| < (a^2 - b^2)/a on the major axis) with its minimum on
// one side: all four mirror images and directions agree with each other (1e-15) and with brute
// force (1e-10), the parameter mirrored with the direction.
TEST(SegmentEllipse, CrossingTheMedialAxisBesideTheMinimum) {
  const Ellipse e = makeEllipse(0.0, 0.0, 0.0, 2.0, 1.0);
  const Vec2 p(0.0, -0.3), q(1.9, 0.2);
  const Vec2 flip(1.0, -1.0);
  const Proximity r = segmentEllipse(p, q, e);
  const auto f = [&](double s) { return pointEllipse(p + s * (q - p), e).distance_m; };
  EXPECT_NEAR(r.distance_m, bruteMinimum(f, 0.0, 1.0, 2000), 1e-10);
  expectConsistent(r, e, 2.0);
  const Proximity reversed = segmentEllipse(q, p, e);
  const Proximity mirrored = segmentEllipse(p.cwiseProduct(flip), q.cwiseProduct(flip), e);
  const Proximity both = segmentEllipse(q.cwiseProduct(flip), p.cwiseProduct(flip), e);
  for (const Proximity* other : {&reversed, &mirrored, &both}) {
    EXPECT_NEAR(other->distance_m, r.distance_m, 1e-15);
    expectConsistent(*other, e, 2.0);
  }
  EXPECT_NEAR(reversed.param, 1.0 - r.param, 1e-12);
  EXPECT_NEAR(mirrored.param, r.param, 1e-12);
  EXPECT_NEAR(both.param, 1.0 - r.param, 1e-12);
}

// A degenerate segment is its point; a segment pointing away ends at its nearer end exactly.
TEST(SegmentEllipse, DegenerateSegmentAndEndpoints) {
  const Ellipse e = makeEllipse(0.0, 0.0, 0.2, 1.0, 0.4);
  const Vec2 p(1.3, 0.9);
  const Proximity r = segmentEllipse(p, p, e);
  const Proximity q = pointEllipse(p, e);
  EXPECT_EQ(r.distance_m, q.distance_m);
  EXPECT_EQ(r.param, 0.0);
  EXPECT_EQ(r.point2, q.point2);

  const Proximity away = segmentEllipse(p, 2.0 * p, e);
  EXPECT_EQ(away.param, 0.0);
  EXPECT_EQ(away.distance_m, q.distance_m);
  const Proximity towards = segmentEllipse(2.0 * p, p, e);
  EXPECT_EQ(towards.param, 1.0);
  EXPECT_EQ(towards.distance_m, q.distance_m);
}

// ----------------------------------------------------------------------------------------------
// Ellipse - ellipse

// Random separated pairs (including circles and a/b = 100) against brute force from both
// boundaries (20000 samples each, polished): 1e-9 m on metre-sized ellipses.
TEST(EllipseEllipse, MatchesBruteForceWhenSeparated) {
  std::mt19937 rng(3);
  const double aspects[] = {1.0, 1.1, 2.0, 5.0, 20.0, 100.0};
  int n_tested = 0;
  for (int i = 0; n_tested < 120 && i < 1000; ++i) {
    const Ellipse e1 = randomEllipse(&rng, aspects[i % 6], 0.0);
    const Ellipse e2 = randomEllipse(&rng, aspects[(i / 6) % 6], 3.0);
    const double brute = bruteEllipseDistance(e1, e2);
    if (brute < 1e-6) continue;
    ++n_tested;
    const Proximity r = ellipseEllipse(e1, e2);
    EXPECT_NEAR(r.distance_m, brute, 1e-9) << "pair " << i;
    EXPECT_NEAR(implicitValue(e1, r.point1), 0.0, 1e-12);
    EXPECT_LT((r.normal - (r.point2 - r.point1) / r.distance_m).norm(), 1e-9);
    expectConsistent(r, e2, 1.0);
  }
  EXPECT_EQ(n_tested, 120);
}

// Two circles: |c2 - c1| - r1 - r2 exactly, separated or overlapping, normal along c2 - c1.
TEST(EllipseEllipse, TwoCirclesClosedForm) {
  for (const double dx : {3.0, 1.0, 0.2}) {
    const Ellipse c1 = makeEllipse(0.5, 0.5, 0.3, 1.0, 1.0);
    const Ellipse c2 = makeEllipse(0.5 + dx * 0.6, 0.5 + dx * 0.8, 1.1, 0.5, 0.5);
    const Proximity r = ellipseEllipse(c1, c2);
    EXPECT_NEAR(r.distance_m, dx - 1.5, 1e-15);
    EXPECT_LT((r.normal - Vec2(0.6, 0.8)).norm(), 1e-15);
    EXPECT_DOUBLE_EQ(r.radius2_m, 0.5);
    expectConsistent(r, c2, 1.0);
  }
}

// Two elongated ellipses side by side with the same angle: the distance is the gap between the
// flat sides (and its opposite when they overlap by that much), along the minor axis.
TEST(EllipseEllipse, ParallelSidesSideBySide) {
  const double a = 1.0, b = 0.05, angle = 0.3;
  const Vec2 minor = rotate(Vec2(0, 1), angle);
  for (const double gap : {1e-3, 1e-9, 0.0, -1e-3}) {
    const Ellipse e1 = makeEllipse(0.2, 0.1, angle, a, b);
    Ellipse e2 = e1;
    e2.center += (2 * b + gap) * minor;
    const Proximity r = ellipseEllipse(e1, e2);
    EXPECT_NEAR(r.distance_m, gap, 1e-15) << gap;
    EXPECT_LT((r.normal - minor).norm(), 1e-7) << gap;
    EXPECT_NEAR(r.radius2_m, a * a / b, 1e-9);
    expectConsistent(r, e2, 1.0);
  }
}

// Vertex against vertex, and vertex against a flat side: distance 0 (rounding, 1e-15).
TEST(EllipseEllipse, TouchingAtAVertex) {
  const Ellipse e1 = makeEllipse(0.0, 0.0, 0.0, 2.0, 1.0);
  const Proximity tips = ellipseEllipse(e1, makeEllipse(3.5, 0.0, 0.0, 1.5, 0.5));
  EXPECT_NEAR(tips.distance_m, 0.0, 1e-15);
  EXPECT_LT((tips.point1 - Vec2(2, 0)).norm(), 1e-7);
  EXPECT_LT((tips.normal - Vec2(1, 0)).norm(), 1e-7);
  const Proximity side = ellipseEllipse(e1, makeEllipse(2.5, 0.0, kPi / 2, 1.5, 0.5));
  EXPECT_NEAR(side.distance_m, 0.0, 1e-15);
  EXPECT_LT((side.point2 - Vec2(2, 0)).norm(), 1e-7);
}

// A far ellipse: facing vertices along the centre line, at exactly D - a1 - a2 (or - b2 when e2
// is turned), to the rounding of D (1e-12).
TEST(EllipseEllipse, FarAway) {
  const Ellipse e1 = makeEllipse(0.0, 0.0, 0.0, 2.0, 1.0);
  const Proximity tips = ellipseEllipse(e1, makeEllipse(1000.0, 0.0, 0.0, 1.5, 0.5));
  EXPECT_NEAR(tips.distance_m, 1000.0 - 3.5, 1e-12);
  EXPECT_LT((tips.normal - Vec2(1, 0)).norm(), 1e-12);
  const Proximity side = ellipseEllipse(e1, makeEllipse(1000.0, 0.0, kPi / 2, 1.5, 0.5));
  EXPECT_NEAR(side.distance_m, 1000.0 - 2.5, 1e-12);
  expectConsistent(side, makeEllipse(1000.0, 0.0, kPi / 2, 1.5, 0.5), 1.0);
}

// Random pairs placed so that e2's support point along -n sits at gap * n from e1's support
// point along n: for gap >= 0 the distance is exactly gap, even for near contact of a/b = 100.
TEST(EllipseEllipse, ConstructedContactsGiveTheGap) {
  std::mt19937 rng(4);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  const double aspects[] = {1.0, 1.5, 3.0, 10.0, 100.0};
  for (int i = 0; i < 500; ++i) {
    const Ellipse e1 = randomEllipse(&rng, aspects[i % 5], 1.0);
    Ellipse e2 = randomEllipse(&rng, aspects[(i / 5) % 5], 0.0);
    const double theta = 2 * kPi * unit(rng);
    const Vec2 n(std::cos(theta), std::sin(theta));
    const double gap = (i % 3 == 0) ? 0.0 : (i % 3 == 1 ? 1e-9 : 1e-3);
    // The support point of an ellipse along n is the boundary point with outward normal n.
    const auto support = [](const Ellipse& e, const Vec2& m) -> Vec2 {
      const Vec2 m_E = rotate(m, -e.angle_rad);
      const Vec2 x_E(e.a_m * e.a_m * m_E.x(), e.b_m * e.b_m * m_E.y());
      return e.center + rotate(x_E / std::sqrt(m_E.dot(x_E)), e.angle_rad);
    };
    e2.center += support(e1, n) + gap * n - support(e2, -n);
    const Proximity r = ellipseEllipse(e1, e2);
    EXPECT_NEAR(r.distance_m, gap, 1e-12) << "pair " << i;
    expectConsistent(r, e2, 1.0);
  }
}

// Overlapping pairs: negative distance; translating e2 by |distance| along the normal leaves
// them touching (brute force ~0: 1e-9), while 0.9 |distance| along any direction leaves them
// overlapping (the depth is the minimum translation).
TEST(EllipseEllipse, OverlapDepthIsTheMinimumSeparatingTranslation) {
  std::mt19937 rng(5);
  const double aspects[] = {1.0, 1.5, 3.0, 8.0};
  int n_tested = 0;
  for (int i = 0; n_tested < 16 && i < 100; ++i) {
    const Ellipse e1 = randomEllipse(&rng, aspects[i % 4], 0.0);
    const Ellipse e2 = randomEllipse(&rng, aspects[(i / 4) % 4], 0.8);
    const Proximity r = ellipseEllipse(e1, e2);
    if (r.distance_m > -1e-3) continue;
    ++n_tested;
    expectConsistent(r, e2, 1.0);
    Ellipse moved = e2;
    moved.center -= r.distance_m * r.normal;
    EXPECT_NEAR(bruteEllipseDistance(e1, moved), 0.0, 1e-9) << "pair " << i;
    for (int k = 0; k < 8; ++k) {
      const double phi = 2 * kPi * k / 8 + 0.1;
      Ellipse shifted = e2;
      shifted.center -= 0.9 * r.distance_m * Vec2(std::cos(phi), std::sin(phi));
      EXPECT_LT(bruteEllipseDistance(e1, shifted), 0.0) << "pair " << i << " dir " << k;
    }
  }
  EXPECT_EQ(n_tested, 16);
}

// Swapping the bodies gives the same distance (rounding: 1e-14) and the opposite normal, with
// the witness points swapped (1e-7: the maximising direction is found to ~1e-13 rad but its
// points move with the curvature radius, up to a^2/b = 200 m).
TEST(EllipseEllipse, SwappingBodiesFlipsTheNormal) {
  std::mt19937 rng(6);
  const double aspects[] = {1.0, 1.3, 4.0, 30.0};
  for (int i = 0; i < 200; ++i) {
    const Ellipse e1 = randomEllipse(&rng, aspects[i % 4], 0.0);
    const Ellipse e2 = randomEllipse(&rng, aspects[(i / 4) % 4], 3.0);
    const Proximity r12 = ellipseEllipse(e1, e2), r21 = ellipseEllipse(e2, e1);
    EXPECT_NEAR(r12.distance_m, r21.distance_m, 1e-14) << "pair " << i;
    EXPECT_LT((r12.normal + r21.normal).norm(), 1e-9) << "pair " << i;
    EXPECT_LT((r12.point1 - r21.point2).norm(), 1e-7) << "pair " << i;
    EXPECT_LT((r12.point2 - r21.point1).norm(), 1e-7) << "pair " << i;
  }
}

// The warm-started query (the narrow phase's, from the pair's last separating direction) gives
// the ring search's answer whatever the warm direction: near the true one (within and beyond
// the 0.05 rad bracket), opposite to it, or none, for separated and overlapping pairs (the
// distance to rounding, 1e-12; the normal to the refinement's angle tolerance, 1e-9); and it
// returns the direction of the normal it found.
TEST(EllipseEllipse, WarmStartedQueryMatchesTheRingSearch) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> offset(-0.2, 0.2);
  const double aspects[] = {1.3, 3.85, 8.0, 30.0};
  int n_overlapping = 0;
  for (int i = 0; i < 400; ++i) {
    const Ellipse e1 = randomEllipse(&rng, aspects[i % 4], 0.0);
    const Ellipse e2 = randomEllipse(&rng, aspects[(i / 4) % 4], i % 3 == 0 ? 0.8 : 3.0);
    const Proximity ring = ellipseEllipse(e1, e2);
    n_overlapping += ring.distance_m < 0 ? 1 : 0;
    const double theta_rad = std::atan2(ring.normal.y(), ring.normal.x());
    const double warm_starts[] = {theta_rad + 0.5 * offset(rng), theta_rad + offset(rng),
                                  theta_rad + kPi, std::nan("")};
    for (double warm_rad : warm_starts) {
      const Proximity r = ellipseEllipse(e1, e2, &warm_rad);
      EXPECT_NEAR(r.distance_m, ring.distance_m, 1e-12 * (1.0 + std::abs(ring.distance_m)))
          << "pair " << i;
      EXPECT_LT((r.normal - ring.normal).norm(), 1e-9) << "pair " << i;
      EXPECT_LT((Vec2(std::cos(warm_rad), std::sin(warm_rad)) - r.normal).norm(), 1e-12)
          << "pair " << i;
    }
  }
  EXPECT_GT(n_overlapping, 20);
}

// A circle on either side reduces to the circle query (exact, overlapping or not).
TEST(EllipseEllipse, CircleAgainstEllipse) {
  const Ellipse e = makeEllipse(0.0, 0.0, 0.6, 1.0, 0.3);
  for (const Vec2& c : {Vec2(1.5, 1.0), Vec2(0.2, 0.1), Vec2(-0.8, -0.9)}) {
    const Ellipse disc = makeEllipse(c.x(), c.y(), 0.0, 0.4, 0.4);
    const Proximity ref = circleEllipse(c, 0.4, e);
    const Proximity r = ellipseEllipse(disc, e), s = ellipseEllipse(e, disc);
    EXPECT_EQ(r.distance_m, ref.distance_m);
    EXPECT_EQ(s.distance_m, ref.distance_m);
    EXPECT_EQ(s.normal, Vec2(-ref.normal));
    EXPECT_EQ(s.point1, ref.point2);
    EXPECT_DOUBLE_EQ(s.radius2_m, 0.4);
    expectConsistent(r, e, 1.0);
  }
}

// ----------------------------------------------------------------------------------------------
// Plane, circle, curvature

// Half-plane y <= 0 against a rotated ellipse above it: the closed form h - sqrt(a^2 sin^2 +
// b^2 cos^2), and brute force over the boundary for tilted planes (1e-10).
TEST(PlaneEllipse, SupportPointAgainstClosedFormAndBruteForce) {
  const double a = 1.0, b = 0.4, angle = 0.5;
  const Ellipse e = makeEllipse(0.3, 0.6, angle, a, b);
  const Proximity r = planeEllipse(Vec2(-2.0, 0.0), Vec2(0.0, 1.0), e);
  const double s = std::sin(angle), c = std::cos(angle);
  EXPECT_NEAR(r.distance_m, 0.6 - std::sqrt(a * a * s * s + b * b * c * c), 1e-15);
  EXPECT_NEAR(r.point1.y(), 0.0, 1e-15);
  expectConsistent(r, e, 1.0);

  for (int k = 0; k < 16; ++k) {
    const double phi = 2 * kPi * k / 16 + 0.05;
    const Vec2 n(std::cos(phi), std::sin(phi)), p(0.1, -0.2);
    const Proximity q = planeEllipse(p, n, e);
    EXPECT_NEAR(q.distance_m,
                bruteMinOverTurn([&](double t) { return n.dot(boundaryPoint(e, t) - p); }), 1e-10);
    EXPECT_NEAR(n.dot(q.point1 - p), 0.0, 1e-15);
    EXPECT_EQ(q.normal, n);
    expectConsistent(q, e, 1.0);
  }
}

// A disc is its centre's query offset by r, with point1 on the disc (exact); brute force on a
// separated disc (1e-10).
TEST(CircleEllipse, OffsetPointQuery) {
  const Ellipse e = makeEllipse(0.0, 0.0, 1.0, 1.0, 0.25);
  for (const Vec2& c : {Vec2(2.0, -1.0), Vec2(0.1, 0.05), Vec2(0.0, 0.0)}) {
    const Proximity r = circleEllipse(c, 0.3, e);
    const Proximity p = pointEllipse(c, e);
    EXPECT_EQ(r.distance_m, p.distance_m - 0.3);
    EXPECT_LT((r.point1 - (c + 0.3 * r.normal)).norm(), 1e-15);
    expectConsistent(r, e, 1.0);
  }
  const Vec2 c(2.0, -1.0);
  EXPECT_NEAR(circleEllipse(c, 0.3, e).distance_m,
              bruteMinOverTurn([&](double t) { return (boundaryPoint(e, t) - c).norm(); }) - 0.3,
              1e-10);
}

// Radius of curvature: b^2/a at the a-vertex, a^2/b at the b-vertex, r for a circle, and the
// circle through three nearby boundary points elsewhere (1e-6 relative: the finite-difference
// error of a spacing of 1e-4 rad).
TEST(CurvatureRadius, VerticesCircleAndThreePointCircle) {
  const double a = 2.0, b = 0.5;
  const Ellipse e = makeEllipse(1.0, -1.0, 0.7, a, b);
  EXPECT_NEAR(ellipseCurvatureRadius(e, boundaryPoint(e, 0.0)), b * b / a, 1e-15);
  EXPECT_NEAR(ellipseCurvatureRadius(e, boundaryPoint(e, kPi)), b * b / a, 1e-15);
  EXPECT_NEAR(ellipseCurvatureRadius(e, boundaryPoint(e, kPi / 2)), a * a / b, 1e-13);
  EXPECT_NEAR(ellipseCurvatureRadius(e, boundaryPoint(e, -kPi / 2)), a * a / b, 1e-13);
  EXPECT_EQ(ellipseCurvatureRadius(makeEllipse(0, 0, 0, 0.3, 0.3), Vec2(0.3, 0.0)), 0.3);

  for (const double t : {0.3, 1.0, 2.0, 4.0}) {
    const Vec2 p0 = boundaryPoint(e, t - 1e-4), p1 = boundaryPoint(e, t),
               p2 = boundaryPoint(e, t + 1e-4);
    // Circumradius |p0 - p1| |p1 - p2| |p2 - p0| / (2 |cross|).
    const Vec2 u = p1 - p0, v = p2 - p0;
    const double circumradius =
        u.norm() * (p2 - p1).norm() * v.norm() / (2.0 * std::abs(u.x() * v.y() - u.y() * v.x()));
    const double rho = ellipseCurvatureRadius(e, p1);
    EXPECT_NEAR(rho, circumradius, 1e-6 * rho) << t;
    // The point query reports the same radius at its closest point.
    EXPECT_NEAR(pointEllipse(p1 + 0.1 * outwardNormal(e, p1), e).radius2_m, rho, 1e-12 * rho);
  }
}

// The memoised cosine and sine are the bits std::cos and std::sin give, on a miss, on a hit
// and after the slot was taken by another angle; +0 and -0 are different angles (sin differs in
// sign), and nearby angles do not share a value.
TEST(CosSinMemo, SameBitsAsTheLibraryOnHitsAndMisses) {
  auto same = [](double a, double b) { return std::memcmp(&a, &b, sizeof a) == 0; };
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> angle(-50.0, 50.0);
  std::vector<double> angles = {0.0, -0.0, kPi, 1e-300, -1e-300, 1.0, std::nextafter(1.0, 2.0)};
  for (int i = 0; i < 500; ++i) angles.push_back(angle(rng));
  for (int pass = 0; pass < 3; ++pass) {  // pass 0 fills, later passes hit or evict
    for (double a : angles) {
      const internal::CosSin cs = internal::cosSinOf(a);
      EXPECT_TRUE(same(cs.c, std::cos(a))) << a;
      EXPECT_TRUE(same(cs.s, std::sin(a))) << a;
    }
  }
  EXPECT_TRUE(std::signbit(internal::cosSinOf(-0.0).s));
  EXPECT_FALSE(std::signbit(internal::cosSinOf(0.0).s));
  EXPECT_NE(internal::cosSinOf(1.0).s, internal::cosSinOf(std::nextafter(1.0, 2.0)).s);
}

}  // namespace
}  // namespace threshing_sim
