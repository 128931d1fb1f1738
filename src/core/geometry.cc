// threshing_sim core: planar distance queries (see geometry.h and docs/physics.md section 5).
//
// Frames: W is world; E is an ellipse's own frame (origin at its centre, x along its a-axis).
// All queries are allocation-free and have bounded iteration counts.
#include "threshing_sim/core/geometry.h"

#include <cmath>
#include <limits>

namespace threshing_sim {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kEpsilon = std::numeric_limits<double>::epsilon();
constexpr double kGoldenFraction = 0.38196601125010515;  // (3 - sqrt(5)) / 2

// Eberly root: relative tolerance on u and iteration cap (each iteration halves the bracket).
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

// Rotation between an ellipse frame E and world W.
struct Rotation {
  explicit Rotation(double angle_rad) : c(std::cos(angle_rad)), s(std::sin(angle_rad)) {}
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
// the query point: g < 0 inside, g > 0 outside. F is convex and decreasing for u > 0.
double eberlyRoot(double n0, double z1, double d, double g) {
  if (g == 0) return 1.0;
  // Bracket: each term of F is at most 1 at the root, so u >= max(z1, n0 - d) where F >= 0;
  // F(1) = g; outside, F(|(n0, z1)|) <= 0.
  double u_lo = std::fmax(std::fmax(z1, n0 - d), g < 0 ? 0.0 : 1.0);
  double u_hi = g < 0 ? 1.0 : std::sqrt(n0 * n0 + z1 * z1);
  double f_lo = 0, df_lo = 0;
  const auto evaluate = [&](double u, double* f, double* df) {
    const double ratio0 = n0 / (u + d), ratio1 = z1 / u;
    *f = ratio0 * ratio0 + ratio1 * ratio1 - 1.0;
    *df = -2.0 * (ratio0 * ratio0 / (u + d) + ratio1 * ratio1 / u);
  };
  evaluate(u_lo, &f_lo, &df_lo);
  for (int i = 0; i < kMaxRootIterations; ++i) {
    const double width = u_hi - u_lo;
    // Newton from the lower end: below the root of a convex decreasing F it never overshoots.
    double u = u_lo - f_lo / df_lo;
    if (u - u_lo <= kRootRelTol * u_lo) return u;
    const bool is_newton = u < u_hi;
    if (!is_newton) u = 0.5 * (u_lo + u_hi);
    double f = 0, df = 0;
    evaluate(u, &f, &df);
    // In exact arithmetic a Newton point has F >= 0: F <= 0 means it is the root to rounding.
    if (f == 0 || (f < 0 && is_newton)) return u;
    if (f > 0) {
      u_lo = u, f_lo = f, df_lo = df;
    } else {
      u_hi = u;
    }
    // Far from the root Newton crawls; a geometric bisection then keeps the bracket halving.
    if (u_hi - u_lo > 0.5 * width) {
      u = std::sqrt(u_lo * u_hi);
      evaluate(u, &f, &df);
      if (f == 0) return u;
      if (f > 0) {
        u_lo = u, f_lo = f, df_lo = df;
      } else {
        u_hi = u;
      }
    }
    if (u_hi - u_lo <= kRootRelTol * u_lo) break;
  }
  return u_lo;
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

// Shape matrix M = R diag(a^2, b^2) R^T of an ellipse in world; its support function is
// h(n) = sqrt(n^T M n) about the centre.
Eigen::Matrix2d shapeMatrix(const Ellipse& e) {
  const Rotation rot(e.angle_rad);
  const double a2 = e.a_m * e.a_m, b2 = e.b_m * e.b_m;
  Eigen::Matrix2d m_m2;
  m_m2 << a2 * rot.c * rot.c + b2 * rot.s * rot.s, (a2 - b2) * rot.c * rot.s,
      (a2 - b2) * rot.c * rot.s, a2 * rot.s * rot.s + b2 * rot.c * rot.c;
  return m_m2;
}

// Gap of an ellipse pair along the direction n(theta) = (cos theta, sin theta):
// psi(theta) = n.(c2 - c1) - h1(n) - h2(-n), the width of the empty strip between the two
// supporting lines with normal n (negative: the overlap along n). Its maximum over theta is the
// signed distance (the translational penetration depth when negative).
struct GapFunction {
  Eigen::Matrix2d m1_m2, m2_m2;  // shape matrices of e1 and e2 in world [m^2]
  Vec2 dc_m;                     // c2 - c1 in world [m]

  double value(const Vec2& n) const {
    return n.dot(dc_m) - std::sqrt(n.dot(m1_m2 * n)) - std::sqrt(n.dot(m2_m2 * n));
  }

  // psi and its first two derivatives in theta.
  struct Derivatives {
    double value, slope, curvature;
  };
  Derivatives derivatives(double theta_rad) const {
    const Vec2 n(std::cos(theta_rad), std::sin(theta_rad)), t(-n.y(), n.x());
    Derivatives out{n.dot(dc_m), t.dot(dc_m), -n.dot(dc_m)};
    for (const Eigen::Matrix2d* m : {&m1_m2, &m2_m2}) {
      // h = sqrt(q), q = n^T M n; h' = t^T M n / h; h'' = (t^T M t - q) / h - (t^T M n)^2 / h^3.
      const double q = n.dot(*m * n), tmn = t.dot(*m * n), tmt = t.dot(*m * t);
      const double h = std::sqrt(q);
      out.value -= h;
      out.slope -= tmn / h;
      out.curvature -= (tmt - q) / h - tmn * tmn / (h * h * h);
    }
    return out;
  }
};

// Local maximum of psi in [lo, hi] starting from theta with psi(theta) >= psi(lo), psi(hi):
// Newton steps where psi is concave and the step stays in the nearer half of the bracket (so a
// rejected Newton step is not retried), golden-section steps uphill otherwise; the best point so
// far always stays bracketed, so the iteration cannot escape to another local maximum.
double maximiseGap(const GapFunction& gap, double lo_rad, double theta_rad, double hi_rad) {
  GapFunction::Derivatives at = gap.derivatives(theta_rad);
  for (int i = 0; i < kMaxRefineIterations; ++i) {
    const double uphill_rad = (at.slope > 0 ? hi_rad : lo_rad) - theta_rad;
    double step_rad = kGoldenFraction * uphill_rad;
    if (at.curvature < 0) {
      const double newton_rad = -at.slope / at.curvature;
      if (std::abs(newton_rad) < 0.5 * std::abs(uphill_rad)) step_rad = newton_rad;
    }
    if (std::abs(step_rad) <= kAngleTol_rad) return theta_rad + step_rad;
    // Accept an uphill step and shrink the bracket behind it; otherwise shrink it to the step.
    const double trial_rad = theta_rad + step_rad;
    const GapFunction::Derivatives at_trial = gap.derivatives(trial_rad);
    if (at_trial.value >= at.value) {
      (step_rad > 0 ? lo_rad : hi_rad) = theta_rad;
      theta_rad = trial_rad;
      at = at_trial;
    } else {
      (step_rad > 0 ? hi_rad : lo_rad) = trial_rad;
    }
  }
  return theta_rad;
}

// Ellipse pair where e1 is a circle: the disc of radius r1 against e2.
Proximity discEllipse(const Vec2& c, double r_m, const Ellipse& e) {
  Proximity out = pointEllipse(c, e);
  out.distance_m -= r_m;
  out.point1 = c + r_m * out.normal;
  return out;
}

}  // namespace

Proximity pointEllipse(const Vec2& p, const Ellipse& e) {
  Proximity out;
  out.point1 = p;
  // Circle: radial projection; the centre projects onto the a-axis vertex.
  if (e.a_m == e.b_m) {
    const Vec2 v_W = p - e.center;
    const double r_m = v_W.norm();
    const Vec2 outward_W =
        r_m > 0 ? Vec2(v_W / r_m) : Vec2(std::cos(e.angle_rad), std::sin(e.angle_rad));
    out.point2 = e.center + e.a_m * outward_W;
    out.distance_m = r_m - e.a_m;
    out.normal = -outward_W;
    out.radius2_m = e.a_m;
    return out;
  }
  // Reflect p into the first quadrant of the ellipse frame, project there and reflect back.
  const Rotation rot(e.angle_rad);
  const Vec2 p_E = rot.toEllipse(p - e.center);
  const Vec2 sign(p_E.x() < 0 ? -1.0 : 1.0, p_E.y() < 0 ? -1.0 : 1.0);
  const QuadrantProjection proj = projectInFirstQuadrant(e.a_m, e.b_m, p_E.cwiseAbs());
  const Vec2 outward_E = proj.outward_E.cwiseProduct(sign);
  out.point2 = e.center + rot.toWorld(proj.x_E.cwiseProduct(sign));
  out.distance_m = proj.distance_m;
  // The normal from p towards the ellipse is minus the outward normal, inside or outside.
  out.normal = -rot.toWorld(outward_E);
  out.radius2_m = curvatureRadiusForNormal(e.a_m, e.b_m, outward_E);
  return out;
}

Proximity segmentEllipse(const Vec2& p0, const Vec2& p1, const Ellipse& e) {
  // The signed distance f(s) of p0 + s d is convex; its slope f'(s) = outward . d = -normal . d is
  // monotone, so the minimum is at an end unless the slope changes sign inside.
  const Vec2 d_m = p1 - p0;
  Proximity lo = pointEllipse(p0, e);
  lo.param = 0.0;
  if (d_m.squaredNorm() == 0) return lo;
  double slope_lo = -lo.normal.dot(d_m);
  if (slope_lo >= 0) return lo;
  Proximity hi = pointEllipse(p1, e);
  hi.param = 1.0;
  double slope_hi = -hi.normal.dot(d_m);
  if (slope_hi <= 0) return hi;

  // Bracketed root of the slope: Illinois regula falsi, with a bisection whenever two steps did
  // not halve the bracket (the slope jumps where the segment crosses the ellipse's medial axis).
  double width_before_last = 2.0, width_last = 2.0;
  int kept_side = 0;  // -1: the lower end was moved last, +1: the upper end
  for (int i = 0; i < kMaxSegmentIterations && hi.param - lo.param > kSegmentParamTol; ++i) {
    const double width = hi.param - lo.param;
    double s = (lo.param * slope_hi - hi.param * slope_lo) / (slope_hi - slope_lo);
    if (width > 0.5 * width_before_last || !(s > lo.param && s < hi.param)) {
      s = 0.5 * (lo.param + hi.param);
    }
    width_before_last = width_last;
    width_last = width;
    Proximity at = pointEllipse(p0 + s * d_m, e);
    at.param = s;
    const double slope = -at.normal.dot(d_m);
    if (slope == 0) return at;
    // Move the end with the same slope sign; halve the stale end's slope if it stays twice.
    if (slope < 0) {
      lo = at, slope_lo = slope;
      if (kept_side == -1) slope_hi *= 0.5;
      kept_side = -1;
    } else {
      hi = at, slope_hi = slope;
      if (kept_side == 1) slope_lo *= 0.5;
      kept_side = 1;
    }
  }
  return lo.distance_m <= hi.distance_m ? lo : hi;
}

Proximity ellipseEllipse(const Ellipse& e1, const Ellipse& e2) {
  // A circle on either side: offset point-ellipse distance (exact, also when overlapping).
  if (e1.a_m == e1.b_m) return discEllipse(e1.center, e1.a_m, e2);
  if (e2.a_m == e2.b_m) {
    const Proximity swapped = discEllipse(e2.center, e2.a_m, e1);
    Proximity out;
    out.distance_m = swapped.distance_m;
    out.point1 = swapped.point2;
    out.point2 = swapped.point1;
    out.normal = -swapped.normal;
    out.radius2_m = e2.a_m;
    return out;
  }

  // General pair: maximise the gap psi(theta) over directions (see GapFunction).
  const GapFunction gap{shapeMatrix(e1), shapeMatrix(e2), e2.center - e1.center};

  // Sample psi on a uniform ring of directions, fine enough for the flattest side, and keep the
  // best few discrete local maxima as candidates (by rotating n, no trigonometry per sample).
  const double aspect = std::fmax(e1.a_m / e1.b_m, e2.a_m / e2.b_m);
  const int n_samples = static_cast<int>(
      std::fmin(kMaxDirectionSamples, std::fmax(kMinDirectionSamples, kSamplesPerAspect * aspect)));
  const double step_rad = 2.0 * kPi / n_samples;
  const double step_c = std::cos(step_rad), step_s = std::sin(step_rad);
  struct Candidate {
    double value;
    int index;
  };
  Candidate candidates[kMaxCandidates];
  int n_candidates = 0;
  const double first = gap.value(Vec2(1.0, 0.0));
  double previous = gap.value(Vec2(step_c, -step_s));  // sample n_samples - 1
  double current = first;
  Vec2 n(1.0, 0.0);
  for (int k = 0; k < n_samples; ++k) {
    n = Vec2(step_c * n.x() - step_s * n.y(), step_s * n.x() + step_c * n.y());
    const double next = k + 1 < n_samples ? gap.value(n) : first;
    if (current >= previous && current > next) {
      // Insert into the candidate list, sorted by decreasing value, dropping the worst.
      int slot = n_candidates < kMaxCandidates ? n_candidates++ : kMaxCandidates;
      while (slot > 0 && candidates[slot - 1].value < current) {
        if (slot < kMaxCandidates) candidates[slot] = candidates[slot - 1];
        --slot;
      }
      if (slot < kMaxCandidates) candidates[slot] = {current, k};
    }
    previous = current;
    current = next;
  }

  // Refine every candidate inside its neighbours' bracket and keep the best (psi constant over
  // all directions has no strict local maximum: then any direction, here theta = 0, is optimal).
  double best_theta_rad = 0.0;
  double best_value = -std::numeric_limits<double>::infinity();
  for (int i = 0; i < n_candidates; ++i) {
    const double theta_rad = candidates[i].index * step_rad;
    const double refined_rad =
        maximiseGap(gap, theta_rad - step_rad, theta_rad, theta_rad + step_rad);
    const double value = gap.value(Vec2(std::cos(refined_rad), std::sin(refined_rad)));
    if (value > best_value) best_value = value, best_theta_rad = refined_rad;
  }

  // Witness points: e1's support point along n and e2's along -n; point2 - point1 = psi n.
  Proximity out;
  out.normal = Vec2(std::cos(best_theta_rad), std::sin(best_theta_rad));
  const Vec2 m1n_m2 = gap.m1_m2 * out.normal, m2n_m2 = gap.m2_m2 * out.normal;
  const double h1_m = std::sqrt(out.normal.dot(m1n_m2)), h2_m = std::sqrt(out.normal.dot(m2n_m2));
  out.point1 = e1.center + m1n_m2 / h1_m;
  out.point2 = e2.center - m2n_m2 / h2_m;
  out.distance_m = out.normal.dot(gap.dc_m) - h1_m - h2_m;
  out.radius2_m = e2.a_m * e2.a_m * e2.b_m * e2.b_m / (h2_m * h2_m * h2_m);
  return out;
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
