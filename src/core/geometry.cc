// threshing_sim core: planar distance queries (see geometry.h and docs/model.md §5).
//
// Frames: W is world; E is an ellipse's own frame (origin at its centre, x along its a-axis).
// All queries are allocation-free and have bounded iteration counts.
//
// Overlap depth of two ellipses: the translational penetration depth, i.e. the length of the
// shortest translation of e2 that separates the pair, with the normal along that translation.
// It is the maximum over directions n of the gap between the supporting lines with normal n, the
// same formula that gives the true distance of a separated pair, so the signed distance is
// continuous through contact and symmetric under swapping the bodies.
#include "threshing_sim/core/geometry.h"

#include <array>
#include <cmath>
#include <limits>

#include "cos_sin_memo.h"
#include "threshing_sim/core/constants.h"

namespace threshing_sim {
namespace {

constexpr double kEpsilon = std::numeric_limits<double>::epsilon();
constexpr double kGoldenFraction = 0.38196601125010515;  // (3 - sqrt(5)) / 2

// Eberly root: relative tolerance on u and iteration cap (each iteration a Newton step or a
// bisection).
constexpr double kRootRelTol = 8.0 * kEpsilon;
constexpr int kMaxRootIterations = 80;

// Segment: tolerance on the parameter s (fraction of the segment length) and iteration cap.
constexpr double kSegmentParamTol = 1e-12;
constexpr int kMaxSegmentIterations = 100;

// Ellipse pair: direction samples per unit aspect ratio a/b (the sharpest feature of the gap
// function is about b/a rad wide), their bounds, candidates refined, and the refinement's
// angular tolerance and iteration cap.
constexpr double kSamplesPerAspect = 8.0;
constexpr int kMinDirectionSamples = 24;
constexpr int kMaxDirectionSamples = 1024;
constexpr int kMaxCandidates = 4;
constexpr double kAngleTol_rad = 1e-13;
constexpr int kMaxRefineIterations = 60;

// Unit a-axis of an ellipse at angle_rad in world, (cos, sin) memoised [-].
Vec2 axisOf(double angle_rad) {
  const internal::CosSin cs = internal::cosSinOf(angle_rad);
  return Vec2(cs.c, cs.s);
}

// Rotation between an ellipse frame E and world W.
struct Rotation {
  explicit Rotation(double angle_rad) : Rotation(internal::cosSinOf(angle_rad)) {}
  explicit Rotation(const internal::CosSin& cs) : c(cs.c), s(cs.s) {}
  Rotation(double cos_angle, double sin_angle) : c(cos_angle), s(sin_angle) {}
  Vec2 toWorld(const Vec2& v_E) const {
    return {c * v_E.x() - s * v_E.y(), s * v_E.x() + c * v_E.y()};
  }
  Vec2 toEllipse(const Vec2& v_W) const {
    return {c * v_W.x() + s * v_W.y(), -s * v_W.x() + c * v_W.y()};
  }
  double c, s;
};

// Support value h = sqrt(m^T diag(a^2, b^2) m) of an ellipse for a unit direction m_E.
double supportValue(double a_m, double b_m, const Vec2& m_E) {
  return std::sqrt(a_m * a_m * m_E.x() * m_E.x() + b_m * b_m * m_E.y() * m_E.y());
}

// Radius of curvature at the boundary point whose outward unit normal is m_E: a^2 b^2 / h^3.
double curvatureRadiusForNormal(double a_m, double b_m, const Vec2& m_E) {
  const double h_m = supportValue(a_m, b_m, m_E);
  return a_m * a_m * b_m * b_m / (h_m * h_m * h_m);
}

// Root u > 0 of Eberly's F(u) = (n0 / (u + d))^2 + (z1 / u)^2 - 1, written in u = 1 + t / e1^2
// so that the root is found to a relative tolerance. g = F(1) is the implicit ellipse function of
// the query point: g < 0 inside, g > 0 outside. Eberly bisects F; here the same bracket drives a
// Newton iteration on phi^(-1/2) = 1 with phi = F + 1, which is increasing and concave in u
// (phi phi'' >= 3/2 phi'^2 by Cauchy-Schwarz) and nearly linear (exactly so for a circle).
double eberlyRoot(double n0, double z1, double d, double g) {
  if (g == 0) return 1.0;
  // Bracket: each term of F is at most 1 at the root, so u >= max(z1, n0 - d) where F >= 0;
  // F(1) = g; outside, F(|(n0, z1)|) <= 0.
  double u_lo = std::fmax(std::fmax(z1, n0 - d), g < 0 ? 0.0 : 1.0);
  double u_hi = g < 0 ? 1.0 : std::sqrt(n0 * n0 + z1 * z1);
  // Start at the lower end: Newton on a concave increasing function then climbs monotonically.
  double u = u_lo;
  for (int i = 0; i < kMaxRootIterations; ++i) {
    // phi and its slope; the sign of phi - 1 tightens the bracket.
    const double inv0 = 1.0 / (u + d), inv1 = 1.0 / u;
    const double ratio0_sq = n0 * n0 * inv0 * inv0, ratio1_sq = z1 * z1 * inv1 * inv1;
    const double phi = ratio0_sq + ratio1_sq;
    const double dphi = -2.0 * (ratio0_sq * inv0 + ratio1_sq * inv1);
    if (phi == 1.0) return u;
    (phi > 1.0 ? u_lo : u_hi) = u;
    if (u_hi - u_lo <= kRootRelTol * u) return u;
    // Newton step; done when it is below the tolerance or below the rounding of phi (a few eps)
    // over its slope; should rounding push it out of the bracket, a geometric bisection instead.
    const double u_newton = u + 2.0 * phi * (1.0 - std::sqrt(phi)) / dphi;
    if (std::abs(u_newton - u) <= kRootRelTol * u + 8.0 * kEpsilon / std::abs(dphi)) {
      return u_newton;
    }
    u = u_newton > u_lo && u_newton < u_hi ? u_newton : std::sqrt(u_lo * u_hi);
  }
  return u;
}

// Closest boundary point of the ellipse (x0/e0)^2 + (x1/e1)^2 = 1 (e0 >= e1) to a point y_E in
// the closed first quadrant, following Eberly: the closest point lies in the same quadrant.
struct QuadrantProjection {
  Vec2 x_E;           // closest boundary point [m]
  Vec2 outward_E;     // outward unit normal at x_E [-]
  double distance_m;  // signed distance of y_E (negative inside) [m]
};

QuadrantProjection projectInFirstQuadrant(double e0_m, double e1_m, const Vec2& y_E) {
  const double y0 = y_E.x(), y1 = y_E.y();
  const double focal_sq_m2 = (e0_m - e1_m) * (e0_m + e1_m);  // e0^2 - e1^2
  if (y1 > 0) {
    if (y0 > 0) {
      // Generic point: x = (r0 w0, w1) with w = (y0 / (u + d), y1 / u) along the outward normal,
      // and y - x = (u - 1) w, so the signed distance is (u - 1) |w|.
      const double z0 = y0 / e0_m, z1 = y1 / e1_m;
      const double r0 = (e0_m / e1_m) * (e0_m / e1_m);
      const double d = focal_sq_m2 / (e1_m * e1_m);  // r0 - 1, free of cancellation
      const double u = eberlyRoot(r0 * z0, z1, d, z0 * z0 + z1 * z1 - 1.0);
      const Vec2 w_m(y0 / (u + d), y1 / u);
      const double w_norm_m = w_m.norm();
      return {Vec2(r0 * w_m.x(), w_m.y()), w_m / w_norm_m, (u - 1.0) * w_norm_m};
    }
    // On the minor axis the closest point is the b-vertex.
    return {Vec2(0.0, e1_m), Vec2(0.0, 1.0), y1 - e1_m};
  }
  // On the major axis, close to the centre, the closest point leaves the axis.
  if (e0_m * y0 < focal_sq_m2) {
    const double x0_over_e0 = e0_m * y0 / focal_sq_m2;
    const double x1_over_e1 = std::sqrt(1.0 - x0_over_e0 * x0_over_e0);
    const Vec2 x_E(e0_m * x0_over_e0, e1_m * x1_over_e1);
    const Vec2 outward_E = Vec2(x0_over_e0 / e0_m, x1_over_e1 / e1_m).normalized();
    return {x_E, outward_E, -(x_E - y_E).norm()};
  }
  // Otherwise it is the a-vertex.
  return {Vec2(e0_m, 0.0), Vec2(1.0, 0.0), y0 - e0_m};
}

// Shape of an ellipse in world: the quadratic form x^T M y of M = R diag(a^2, b^2) R^T, summed
// along the axes so that it keeps full relative accuracy for eccentric ellipses (the entries of
// M are ~a^2 while n^T M n may be ~b^2). Its support function is h(n) = sqrt(n^T M n).
struct EllipseShape {
  explicit EllipseShape(const Ellipse& e)
      : axis_a(axisOf(e.angle_rad)), a_sq_m2(e.a_m * e.a_m), b_sq_m2(e.b_m * e.b_m) {}
  // x^T M y.
  double form(const Vec2& x, const Vec2& y) const {
    const Vec2 axis_b(-axis_a.y(), axis_a.x());
    return a_sq_m2 * x.dot(axis_a) * y.dot(axis_a) + b_sq_m2 * x.dot(axis_b) * y.dot(axis_b);
  }
  // M n; the support point along n is the centre plus M n / h(n).
  Vec2 apply(const Vec2& n) const {
    const Vec2 axis_b(-axis_a.y(), axis_a.x());
    return a_sq_m2 * n.dot(axis_a) * axis_a + b_sq_m2 * n.dot(axis_b) * axis_b;
  }
  Vec2 axis_a;              // unit a-axis in world [-]
  double a_sq_m2, b_sq_m2;  // a^2, b^2 [m^2]
};

// Gap of an ellipse pair along the direction n(theta) = (cos theta, sin theta):
// psi(theta) = n.(c2 - c1) - h1(n) - h2(-n), the width of the empty strip between the two
// supporting lines with normal n (negative: the overlap along n). Its maximum over theta is the
// signed distance (the translational penetration depth when negative).
struct GapFunction {
  EllipseShape shape1, shape2;
  Vec2 dc_m;  // c2 - c1 in world [m]

  // h1(n) + h2(-n), the same for n and -n.
  double support(const Vec2& n) const {
    return std::sqrt(shape1.form(n, n)) + std::sqrt(shape2.form(n, n));
  }

  // psi [m] and its first two derivatives in theta [m/rad, m/rad^2], and the rounding error of
  // the value [m].
  struct Derivatives {
    double value, slope, curvature, rounding;
  };
  // Along the unit direction n = n(theta).
  Derivatives derivativesAlong(const Vec2& n) const {
    const Vec2 t(-n.y(), n.x());
    Derivatives out{n.dot(dc_m), t.dot(dc_m), -n.dot(dc_m), std::abs(n.dot(dc_m))};
    for (const EllipseShape* shape : {&shape1, &shape2}) {
      // h = sqrt(q), q = n^T M n; h' = t^T M n / h; h'' = (t^T M t - q) / h - (t^T M n)^2 / h^3.
      const double q = shape->form(n, n), tmn = shape->form(t, n), tmt = shape->form(t, t);
      const double h = std::sqrt(q);
      out.value -= h;
      out.slope -= tmn / h;
      out.curvature -= (tmt - q) / h - tmn * tmn / (h * h * h);
      out.rounding += h;
    }
    out.rounding *= 16.0 * kEpsilon;
    return out;
  }
};

// A local maximum of the gap: its direction and value.
struct GapMaximum {
  double theta_rad, value_m;
};

// The unit direction n turned by step_rad. A small turn (every Newton step near convergence)
// takes its cosine and sine from their Taylor series, exact to rounding below kSmallTurn_rad
// (the first omitted terms, step^10 / 10! and step^11 / 11!, are below 1e-19), and rotates n;
// a larger one evaluates the direction of theta + step afresh.
constexpr double kSmallTurn_rad = 0.0625;
Vec2 turned(const Vec2& n, double theta_rad, double step_rad) {
  if (std::abs(step_rad) > kSmallTurn_rad) {
    return Vec2(std::cos(theta_rad + step_rad), std::sin(theta_rad + step_rad));
  }
  const double d2 = step_rad * step_rad;
  const double c = 1.0 - d2 / 2 * (1.0 - d2 / 12 * (1.0 - d2 / 30 * (1.0 - d2 / 56)));
  const double s = step_rad * (1.0 - d2 / 6 * (1.0 - d2 / 20 * (1.0 - d2 / 42 * (1.0 - d2 / 72))));
  return Vec2(c * n.x() - s * n.y(), s * n.x() + c * n.y());
}

// Local maximum of psi in [lo, hi] starting from theta with psi(theta) >= psi(lo), psi(hi):
// Newton steps where psi is concave and the step stays in the nearer half of the bracket (so a
// rejected Newton step is not retried), golden-section steps uphill otherwise; the best point so
// far always stays bracketed, so the iteration cannot escape to another local maximum.
GapMaximum maximiseGap(const GapFunction& gap, double lo_rad, double theta_rad, double hi_rad) {
  Vec2 n = axisOf(theta_rad);  // direction of theta, turned along with it
  GapFunction::Derivatives at = gap.derivativesAlong(n);
  for (int i = 0; i < kMaxRefineIterations; ++i) {
    const double uphill_rad = (at.slope > 0 ? hi_rad : lo_rad) - theta_rad;
    double step_rad = kGoldenFraction * uphill_rad;
    if (at.curvature < 0) {
      const double newton_rad = -at.slope / at.curvature;
      if (std::abs(newton_rad) < 0.5 * std::abs(uphill_rad)) step_rad = newton_rad;
    }
    // Converged: the next step is below the angular tolerance.
    if (std::abs(step_rad) <= kAngleTol_rad) return {theta_rad + step_rad, at.value};
    // Accept an uphill step, or a level one (within rounding, where only the slope still steers)
    // that flattens the slope, and shrink the bracket behind it; otherwise shrink it to the step.
    const double trial_rad = theta_rad + step_rad;
    const Vec2 n_trial = turned(n, theta_rad, step_rad);
    const GapFunction::Derivatives at_trial = gap.derivativesAlong(n_trial);
    const bool level = std::abs(at_trial.value - at.value) <= at.rounding;
    if (at_trial.value > at.value + at.rounding ||
        (level && std::abs(at_trial.slope) <= std::abs(at.slope))) {
      (step_rad > 0 ? lo_rad : hi_rad) = theta_rad;
      theta_rad = trial_rad;
      n = n_trial;
      at = at_trial;
    } else {
      (step_rad > 0 ? hi_rad : lo_rad) = trial_rad;
    }
  }
  return {theta_rad, at.value};
}

// Point query against a circle: radial projection; the centre projects onto the a-axis vertex.
Proximity projectOntoCircle(const Vec2& p, const Ellipse& e) {
  Proximity out;
  out.point1 = p;
  const Vec2 v_W = p - e.center;
  const double r_m = v_W.norm();
  const Vec2 outward_W = r_m > 0 ? Vec2(v_W / r_m) : axisOf(e.angle_rad);
  out.point2 = e.center + e.a_m * outward_W;
  out.distance_m = r_m - e.a_m;
  out.normal = -outward_W;
  out.radius2_m = e.a_m;
  return out;
}

// Point query against a proper ellipse whose rotation is given.
Proximity projectOntoEllipse(const Vec2& p, const Ellipse& e, const Rotation& rot) {
  // Reflect p into the first quadrant of the ellipse frame, project there and reflect back.
  const Vec2 p_E = rot.toEllipse(p - e.center);
  const Vec2 sign(p_E.x() < 0 ? -1.0 : 1.0, p_E.y() < 0 ? -1.0 : 1.0);
  const QuadrantProjection proj = projectInFirstQuadrant(e.a_m, e.b_m, p_E.cwiseAbs());
  const Vec2 outward_E = proj.outward_E.cwiseProduct(sign);
  Proximity out;
  out.point1 = p;
  out.point2 = e.center + rot.toWorld(proj.x_E.cwiseProduct(sign));
  out.distance_m = proj.distance_m;
  // The normal from p towards the ellipse is minus the outward normal, inside or outside.
  out.normal = -rot.toWorld(outward_E);
  out.radius2_m = curvatureRadiusForNormal(e.a_m, e.b_m, outward_E);
  return out;
}

// Disc of radius r at c against the ellipse: the point query of c offset by r, exact also when
// overlapping (growing a convex set by a disc moves each boundary point by r along its normal).
Proximity discEllipse(const Vec2& c, double r_m, const Ellipse& e) {
  Proximity out = pointEllipse(c, e);
  out.distance_m -= r_m;
  out.point1 = c + r_m * out.normal;
  return out;
}

}  // namespace

Proximity pointEllipse(const Vec2& p, const Ellipse& e) {
  if (e.a_m == e.b_m) return projectOntoCircle(p, e);
  return projectOntoEllipse(p, e, Rotation(e.angle_rad));
}

Proximity pointEllipse(const Vec2& p, const Ellipse& e, double cos_angle, double sin_angle) {
  if (e.a_m == e.b_m) return projectOntoCircle(p, e);
  return projectOntoEllipse(p, e, Rotation(cos_angle, sin_angle));
}

Proximity segmentEllipse(const Vec2& p0, const Vec2& p1, const Ellipse& e) {
  const Vec2 d_m = p1 - p0;
  const double length_sq_m2 = d_m.squaredNorm();
  // Circle: the closest (or deepest) point is the segment point closest to the centre.
  if (e.a_m == e.b_m) {
    const double s = length_sq_m2 > 0
                         ? std::fmin(1.0, std::fmax(0.0, (e.center - p0).dot(d_m) / length_sq_m2))
                         : 0.0;
    Proximity out = projectOntoCircle(p0 + s * d_m, e);
    out.param = s;
    return out;
  }
  const Rotation rot(e.angle_rad);
  const auto at = [&](double s) {
    Proximity out = projectOntoEllipse(p0 + s * d_m, e, rot);
    out.param = s;
    return out;
  };
  // The signed distance f(s) of p0 + s d is convex; its slope f'(s) = outward . d = -normal . d is
  // monotone, so the minimum is at an end unless the slope changes sign inside.
  const auto slope = [&](const Proximity& r) { return -r.normal.dot(d_m); };
  Proximity lo = at(0.0);
  if (length_sq_m2 == 0 || slope(lo) >= 0) return lo;
  Proximity hi = at(1.0);
  if (slope(hi) <= 0) return hi;

  // The slope jumps where the segment crosses the medial axis (the major axis between the
  // centres of curvature of the a-vertices): there the closest point flips to its mirror image
  // across the major axis. Split the bracket at the crossing, which is the minimum itself when
  // the one-sided slopes straddle zero.
  const Vec2 p0_E = rot.toEllipse(p0 - e.center), d_E = rot.toEllipse(d_m);
  const double s_axis = -p0_E.y() / d_E.y();
  const double medial_half_length_m = (e.a_m - e.b_m) * (e.a_m + e.b_m) / e.a_m;
  if (s_axis > 0 && s_axis < 1 && std::abs(p0_E.x() + s_axis * d_E.x()) < medial_half_length_m) {
    Proximity axis = at(s_axis);
    const Vec2 outward_E = rot.toEllipse(-axis.normal);
    const double along_m = outward_E.x() * d_E.x(), across_m = std::abs(outward_E.y() * d_E.y());
    const double slope_before_m = along_m - across_m, slope_after_m = along_m + across_m;
    if (slope_before_m <= 0 && slope_after_m >= 0) return axis;
    // Keep the side holding the minimum, its closest point mirrored onto that side if needed.
    const bool after = slope_after_m < 0;
    const double side_y = after == (d_E.y() > 0) ? 1.0 : -1.0;
    const Vec2 point2_E = rot.toEllipse(axis.point2 - e.center);
    if (point2_E.y() * side_y < 0) {
      axis.point2 = e.center + rot.toWorld(Vec2(point2_E.x(), -point2_E.y()));
      axis.normal = -rot.toWorld(Vec2(outward_E.x(), -outward_E.y()));
    }
    (after ? lo : hi) = axis;
  }

  // Bracketed Newton on the slope from the end with the smaller slope, with f''(s) =
  // (tangent . d)^2 / (rho + f), the Hessian of the distance to a curve of curvature radius rho.
  // Bisect when Newton leaves the bracket or its steps stop halving (near the evolute, where that
  // Hessian blows up); step at least the tolerance, so that a converged Newton iterate closes the
  // bracket.
  Proximity current = -slope(lo) <= slope(hi) ? lo : hi;
  double step_before_last = 1.0, step_last = 1.0;
  for (int i = 0; i < kMaxSegmentIterations && hi.param - lo.param > kSegmentParamTol; ++i) {
    const double tangential_m = current.normal.x() * d_m.y() - current.normal.y() * d_m.x();
    const double curvature_m =
        tangential_m * tangential_m / (current.radius2_m + current.distance_m);
    double step = -slope(current) / curvature_m;
    if (std::abs(step) < kSegmentParamTol) step = std::copysign(kSegmentParamTol, step);
    double s = current.param + step;
    if (!(s > lo.param && s < hi.param) || std::abs(step) > 0.5 * step_before_last) {
      s = 0.5 * (lo.param + hi.param);
    }
    step_before_last = step_last;
    step_last = std::abs(s - current.param);
    current = at(s);
    const double slope_s = slope(current);
    if (slope_s == 0) return current;
    (slope_s < 0 ? lo : hi) = current;
  }
  return lo.distance_m <= hi.distance_m ? lo : hi;
}

namespace {

// The ellipse-ellipse gap psi sampled on a uniform ring of an even number of directions, fine
// enough for the flattest side: n_samples values into psi_m, step_rad apart from theta = 0.
// Opposite directions share the support term, so each pair costs one evaluation of it; n is
// rotated from sample to sample rather than recomputed by trigonometry.
struct GapRing {
  double psi_m[kMaxDirectionSamples];  // psi at theta = k step_rad [m]
  int n_samples = 0;                   // samples around the ring [-]
  double step_rad = 0;                 // angle between samples [rad]
};
// Ring step 2 pi / n_samples and its cosine and sine for every even sample count up to
// kMaxDirectionSamples (index n_samples / 2), computed once: no trigonometry per pair query.
struct RingStep {
  double step_rad, cos_step, sin_step;
};
const std::array<RingStep, kMaxDirectionSamples / 2 + 1>& ringSteps() {
  static const std::array<RingStep, kMaxDirectionSamples / 2 + 1> table = [] {
    std::array<RingStep, kMaxDirectionSamples / 2 + 1> t{};
    for (int n_pairs = 1; n_pairs <= kMaxDirectionSamples / 2; ++n_pairs) {
      const double step_rad = 2.0 * kPi / (2 * n_pairs);
      t[n_pairs] = {step_rad, std::cos(step_rad), std::sin(step_rad)};
    }
    return t;
  }();
  return table;
}

void sampleGapRing(const GapFunction& gap, double aspect, GapRing* ring) {
  const int n_pairs = static_cast<int>(
      std::fmin(kMaxDirectionSamples / 2,
                std::fmax(kMinDirectionSamples / 2, kSamplesPerAspect * aspect / 2)));
  ring->n_samples = 2 * n_pairs;
  const RingStep& step = ringSteps()[n_pairs];
  ring->step_rad = step.step_rad;
  const double step_c = step.cos_step, step_s = step.sin_step;
  Vec2 n(1.0, 0.0);
  for (int k = 0; k < n_pairs; ++k) {
    const double support_m = gap.support(n), along_m = n.dot(gap.dc_m);
    ring->psi_m[k] = along_m - support_m;
    ring->psi_m[k + n_pairs] = -along_m - support_m;
    n = Vec2(step_c * n.x() - step_s * n.y(), step_s * n.x() + step_c * n.y());
  }
}

// A discrete local maximum of the ring: its value [m] and sample index.
struct Candidate {
  double value_m;
  int index;
};

// The best few discrete local maxima around the ring, sorted by decreasing value; returns how
// many (at most kMaxCandidates).
int localMaxima(const GapRing& ring, Candidate* candidates) {
  const int n = ring.n_samples;
  int n_candidates = 0;
  for (int k = 0; k < n; ++k) {
    const double value_m = ring.psi_m[k];
    if (value_m < ring.psi_m[(k + n - 1) % n] || value_m <= ring.psi_m[(k + 1) % n]) continue;
    int slot = n_candidates < kMaxCandidates ? n_candidates++ : kMaxCandidates;
    while (slot > 0 && candidates[slot - 1].value_m < value_m) {
      if (slot < kMaxCandidates) candidates[slot] = candidates[slot - 1];
      --slot;
    }
    if (slot < kMaxCandidates) candidates[slot] = {value_m, k};
  }
  return n_candidates;
}

// Witness points of the gap's maximum along direction theta: e1's support point along n and
// e2's along -n; point2 - point1 = psi n.
Proximity witnessPoints(const Ellipse& e1, const Ellipse& e2, const GapFunction& gap,
                        double theta_rad) {
  Proximity out;
  out.normal = Vec2(std::cos(theta_rad), std::sin(theta_rad));
  const double h1_m = std::sqrt(gap.shape1.form(out.normal, out.normal));
  const double h2_m = std::sqrt(gap.shape2.form(out.normal, out.normal));
  out.point1 = e1.center + gap.shape1.apply(out.normal) / h1_m;
  out.point2 = e2.center - gap.shape2.apply(out.normal) / h2_m;
  out.distance_m = out.normal.dot(gap.dc_m) - h1_m - h2_m;
  out.radius2_m = e2.a_m * e2.a_m * e2.b_m * e2.b_m / (h2_m * h2_m * h2_m);
  return out;
}

}  // namespace

namespace {

// Direction [rad] of the global maximum of the general pair's gap psi (ellipses, neither a
// circle), from a uniform ring of directions.
double ringMaximum(const Ellipse& e1, const Ellipse& e2, const GapFunction& gap) {
  GapRing ring;
  sampleGapRing(gap, std::fmax(e1.a_m / e1.b_m, e2.a_m / e2.b_m), &ring);
  Candidate candidates[kMaxCandidates];
  const int n_candidates = localMaxima(ring, candidates);
  // Refine every candidate inside its neighbours' bracket and keep the best (psi constant over
  // all directions has no strict local maximum: then any direction, here theta = 0, is optimal).
  // A candidate whose bracket cannot beat the best refined value is skipped: with
  // |psi''| <= C = |c2 - c1| + a1^2/b1 + a2^2/b2 (psi'' = -n.dc - h1'' - h2'' and |h''| =
  // |rho - h| <= a^2/b), psi stays below its largest sample plus C step^2 / 8 between samples,
  // and a candidate is the largest of its three samples. Candidates come in decreasing order.
  const double step_rad = ring.step_rad;
  const double curvature_bound_m =
      gap.dc_m.norm() + e1.a_m * e1.a_m / e1.b_m + e2.a_m * e2.a_m / e2.b_m;
  const double rise_bound_m = curvature_bound_m * step_rad * step_rad / 8.0;
  GapMaximum best{0.0, -std::numeric_limits<double>::infinity()};
  for (int i = 0; i < n_candidates; ++i) {
    if (candidates[i].value_m + rise_bound_m < best.value_m) break;
    const double theta_rad = candidates[i].index * step_rad;
    const GapMaximum refined =
        maximiseGap(gap, theta_rad - step_rad, theta_rad, theta_rad + step_rad);
    if (refined.value_m > best.value_m) best = refined;
  }
  return best.theta_rad;
}

// Half-width of the bracket a warm-started query refines in [rad] (below kSmallTurn_rad: its
// ends are turned from the warm direction without trigonometry).
constexpr double kWarmBracket_rad = 0.05;

// The general pair warm-started from direction theta_rad: the local maximum psi* of psi in
// [theta - w, theta + w] if psi at theta is at least its values at both ends and psi* >= -R,
// R = b1^2/a1 + b2^2/a2, else NaN. Such a local maximum is the global one. psi(n) = -h_K(n),
// h_K the support function of the convex K = E1 - E2 - dc (the origin outside K: apart). If
// psi* > 0, {n : psi(n) > c}, c >= 0, is the trace on the unit circle of the convex cone
// {n : n.k + c |n| < 0 for all k in K}: one arc, one local maximum. If -R <= psi* <= 0 (overlap
// of depth d = -psi* <= R): at the local maximum n*, p = d n* is a point of K's boundary with
// outward normal n*, and K contains the disc of radius R inside it at p (each ellipse rolls a
// disc of its least curvature radius b^2/a inside, their Minkowski sum the sum), whose centre
// is (d - R) n*; the origin lies in that disc at depth d, so the distance from the origin to
// K's boundary, the global minimum of h_K, is d.
double warmMaximum(const Ellipse& e1, const Ellipse& e2, const GapFunction& gap, double theta_rad) {
  const Vec2 n = axisOf(theta_rad);
  const auto psi = [&](const Vec2& m) { return m.dot(gap.dc_m) - gap.support(m); };
  const double mid_m = psi(n);
  if (!(mid_m >= psi(turned(n, theta_rad, -kWarmBracket_rad))) ||
      !(mid_m >= psi(turned(n, theta_rad, kWarmBracket_rad))))
    return std::numeric_limits<double>::quiet_NaN();
  const GapMaximum refined =
      maximiseGap(gap, theta_rad - kWarmBracket_rad, theta_rad, theta_rad + kWarmBracket_rad);
  const double rolling_radius_m = e1.b_m * e1.b_m / e1.a_m + e2.b_m * e2.b_m / e2.a_m;
  return refined.value_m >= -rolling_radius_m ? refined.theta_rad
                                              : std::numeric_limits<double>::quiet_NaN();
}

// A circle on either side: offset point-ellipse distance (exact, also when overlapping).
Proximity discPair(const Ellipse& e1, const Ellipse& e2) {
  if (e1.a_m == e1.b_m) return discEllipse(e1.center, e1.a_m, e2);
  const Proximity swapped = discEllipse(e2.center, e2.a_m, e1);
  Proximity out;
  out.distance_m = swapped.distance_m;
  out.point1 = swapped.point2;
  out.point2 = swapped.point1;
  out.normal = -swapped.normal;
  out.radius2_m = e2.a_m;
  return out;
}

}  // namespace

Proximity ellipseEllipse(const Ellipse& e1, const Ellipse& e2) {
  if (e1.a_m == e1.b_m || e2.a_m == e2.b_m) return discPair(e1, e2);
  // General pair: maximise the gap psi(theta) over directions (see GapFunction).
  const GapFunction gap{EllipseShape(e1), EllipseShape(e2), e2.center - e1.center};
  return witnessPoints(e1, e2, gap, ringMaximum(e1, e2, gap));
}

Proximity ellipseEllipse(const Ellipse& e1, const Ellipse& e2, double* warm_theta_rad) {
  if (e1.a_m == e1.b_m || e2.a_m == e2.b_m) return discPair(e1, e2);
  const GapFunction gap{EllipseShape(e1), EllipseShape(e2), e2.center - e1.center};
  double theta_rad = std::isfinite(*warm_theta_rad) ? warmMaximum(e1, e2, gap, *warm_theta_rad)
                                                    : std::numeric_limits<double>::quiet_NaN();
  if (!std::isfinite(theta_rad)) theta_rad = ringMaximum(e1, e2, gap);
  *warm_theta_rad = theta_rad;
  return witnessPoints(e1, e2, gap, theta_rad);
}

Proximity planeEllipse(const Vec2& p, const Vec2& n, const Ellipse& e) {
  // The ellipse's support point along -n is its deepest point towards the half-plane.
  const Rotation rot(e.angle_rad);
  const Vec2 n_E = rot.toEllipse(n);
  const double h_m = supportValue(e.a_m, e.b_m, n_E);
  const Vec2 x_E(-e.a_m * e.a_m * n_E.x() / h_m, -e.b_m * e.b_m * n_E.y() / h_m);
  Proximity out;
  out.point2 = e.center + rot.toWorld(x_E);
  out.distance_m = n.dot(out.point2 - p);
  out.point1 = out.point2 - out.distance_m * n;
  out.normal = n;
  out.radius2_m = curvatureRadiusForNormal(e.a_m, e.b_m, n_E);
  return out;
}

Proximity circleEllipse(const Vec2& c, double r, const Ellipse& e) { return discEllipse(c, r, e); }

double ellipseCurvatureRadius(const Ellipse& e, const Vec2& q) {
  if (e.a_m == e.b_m) return e.a_m;
  // Outward normal of the ellipse homothetic to e through q, i.e. q is projected radially onto
  // the boundary; the centre maps to the a-vertex.
  const Vec2 q_E = Rotation(e.angle_rad).toEllipse(q - e.center);
  const Vec2 gradient_E(q_E.x() / (e.a_m * e.a_m), q_E.y() / (e.b_m * e.b_m));
  const double gradient_norm = gradient_E.norm();
  const Vec2 outward_E = gradient_norm > 0 ? Vec2(gradient_E / gradient_norm) : Vec2::UnitX();
  return curvatureRadiusForNormal(e.a_m, e.b_m, outward_E);
}

}  // namespace threshing_sim
