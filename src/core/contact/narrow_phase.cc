// threshing_sim core: the narrow phase (narrow_phase.h). evaluateContact is a short driver: it
// fills what every pair shares, calls the pair function of the pair's kind from a small table
// (kPairFunctions, in the manner of a collision function table), then adds the kernel's side,
// the relative velocities and the Hertz constant.
#include "narrow_phase.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "../internal.h"
#include "contact_forces.h"
#include "planar.h"
#include "stations.h"
#include "threshing_sim/core/geometry.h"

namespace threshing_sim {
namespace internal {
namespace {

// Effective modulus E* of two bodies in contact [Pa].
double effectiveModulus(double E1, double nu1, double E2, double nu2) {
  return 1.0 / ((1.0 - nu1 * nu1) / E1 + (1.0 - nu2 * nu2) / E2);
}
// Series combination of two radii of curvature (inf = flat) [m].
double seriesRadius(double r1, double r2) {
  const double k = (std::isfinite(r1) ? 1.0 / r1 : 0.0) + (std::isfinite(r2) ? 1.0 / r2 : 0.0);
  return k > 0.0 ? 1.0 / k : std::numeric_limits<double>::infinity();
}
// Hertz point-contact constant K = 4/3 E* sqrt(R*), with R* = sqrt(R' R'') from the in-plane
// and out-of-plane relative radii (Johnson, Contact Mechanics, eq. 4.24 equivalent sphere).
double hertzConstant(double E_star, double r_in, double r_out) {
  const double r_star = std::sqrt(r_in * r_out);
  return 4.0 / 3.0 * E_star * std::sqrt(r_star);
}

// Half-width of an ellipse along the unit direction n (its support value h(n)) [m].
struct EllipseWidth {
  explicit EllipseWidth(const Ellipse& e) : axis(unitVector(e.angle_rad)), a_m(e.a_m), b_m(e.b_m) {}
  double operator()(const Vec2& n) const {
    const double na = a_m * n.dot(axis), nb = b_m * cross(axis, n);
    return std::sqrt(na * na + nb * nb);
  }
  Vec2 axis;        // unit a-axis in world [-]
  double a_m, b_m;  // semi-axes [m]
};

// Lower bound of the signed distance between the ellipse and a convex body whose nearest point
// to the ellipse's centre is p: with n from p to the centre, the body lies behind the line
// through p normal to n, and the ellipse reaches at most h(n) towards it. (Any direction gives
// a lower bound, the supporting-line gap; this one is cheap and tight for nearby bodies.)
double gapLowerBound(const Ellipse& e, const EllipseWidth& width, const Vec2& p) {
  const Vec2 d = e.center - p;
  const double dist = d.norm();
  if (!(dist > 0.0)) return -e.a_m;
  return dist - width(d / dist);
}

// Kernel contact point Jacobian rows: d(v_point . dir)/d(vx, vy, omega).
void kernelRow(const Vec2& p_W, const Vec2& c_W, const Vec2& dir, double sign, SmallVec* w) {
  w->resize(3);
  (*w)[0] = sign * dir.x();
  (*w)[1] = sign * dir.y();
  (*w)[2] = sign * cross(p_W - c_W, dir);
}

// What every pair function is given: the pair and its evaluation's arguments (see
// evaluateContact), and the kernel of the pair (body 1) as an ellipse.
struct NarrowInput {
  const Model& m;             // the model
  const VecX& z;              // configuration [m, rad or sqrt(kg) m]
  const Drive& drive;         // the drum at that instant
  const PairId& pair;         // the pair evaluated
  Workspace* ws;              // stations (updateStations for z) and scratch
  double far_m;               // a pair whose gap bound exceeds it is far [m]
  bool tight_bound;           // supporting-line bounds for exact shapes [-]
  double* warm_x_m;           // tooth pairs: warm start, receives the closest point [m]
  double* warm_theta_rad;     // kernel pairs: warm start of ellipseEllipse, or nullptr [rad]
  const KernelModel& kern;    // the kernel of the pair (body 1)
  const Ellipse& e;           // its ellipse
  const EllipseWidth& width;  // and its support function
};

// The Hertz law's inputs of one pair: the relative radii of curvature in the plane and across
// it [m], and the effective modulus [Pa].
struct HertzInputs {
  double r_in = 0, r_out = 0, E_star = 0;  // [m], [m], [Pa]
};

// A pair whose lower bound of the gap exceeds far_m: only that bound is stored.
bool isFar(double bound, double far_m, ContactGeom* g) {
  if (!(bound > far_m)) return false;
  g->gap_m = bound;
  g->far = true;
  return true;
}

// --- tooth against kernel -------------------------------------------------------------------

// The closest-point condition h(x) = n(x) . r'(x) on a tooth's deformed centreline against
// the kernel's ellipse, at material coordinate x; keeps the centreline point r_x of the last
// evaluation (and the mode values in ws->centreline.scratch_phi/dphi), *p its proximity to the
// ellipse.
struct CentrelineProbe {
  CentrelineProbe(const NarrowInput& in, const ToothModel& tm, StationPair* direct_stations)
      : tm(tm),
        tooth(in.pair.a),
        q(in.z.segment(tm.dof_offset, tm.n_modes)),
        rot(in.drive.theta_rad),
        ws(in.ws),
        e(in.e),
        width(in.width),
        direct(direct_stations) {}
  double operator()(double x, Proximity* p) {
    Vec2 dr_dx;
    r_x = centrelinePoint(tm, tooth, q, rot, x, ws, &dr_dx, direct);
    *p = pointEllipse(r_x, e, width.axis.x(), width.axis.y());
    return p->normal.dot(dr_dx);
  }
  const ToothModel& tm;       // the tooth
  int tooth;                  // tooth index [-]
  Eigen::Ref<const VecX> q;   // its coordinates [sqrt(kg) m; a rod's: rad]
  Rotation2 rot;              // the drum's rotation [-]
  Workspace* ws;              // stations and mode scratch
  const Ellipse& e;           // the kernel
  const EllipseWidth& width;  // its support function
  StationPair* direct;        // stations computed directly (warm start), else nullptr
  Vec2 r_x = Vec2::Zero();    // centreline point of the last evaluation [m]
};

// Closest approach of the deformed centreline polyline to the ellipse: sets g->tooth_x_m and
// *best; false if the pair is far (only its bound stored).
bool polylineClosestPoint(const NarrowInput& in, const ToothModel& tm, ContactGeom* g,
                          Proximity* best) {
  const Ellipse& e = in.e;
  const int s0 = in.ws->centreline.station_offset[in.pair.a];
  const std::vector<Vec2>& st = in.ws->centreline.stations_W;
  best->distance_m = std::numeric_limits<double>::infinity();
  int best_seg = 0;
  // Segments are visited nearest first by a cheap lower bound (distance to the ellipse's
  // centre minus a); once the bound passes the best distance the rest cannot win.
  // Segments are ordered by the supporting-line gap (gapLowerBound); "far" is decided by the
  // coarser bounding-circle bound (centre distance minus a) as it always was: the polyline
  // only approximates the deformed centreline between stations, which the margin covers.
  const int n_seg = tm.n_stations - 1;
  double lower[64];
  int order[64];
  double circle_bound = std::numeric_limits<double>::infinity();
  for (int s = 0; s < n_seg; ++s) {
    const Vec2& a = st[s0 + s];
    const Vec2 ab = st[s0 + s + 1] - a;
    const double f = std::clamp((e.center - a).dot(ab) / ab.squaredNorm(), 0.0, 1.0);
    const Vec2 p = a + f * ab;
    lower[s] = gapLowerBound(e, in.width, p);
    circle_bound = std::min(circle_bound, (e.center - p).norm() - e.a_m);
    order[s] = s;
  }
  std::sort(order, order + n_seg, [&](int i, int j) { return lower[i] < lower[j]; });
  if (isFar(circle_bound - 0.5 * tm.diameter_m, in.far_m, g)) return false;
  for (int o = 0; o < n_seg; ++o) {
    const int s = order[o];
    if (lower[s] > best->distance_m) break;
    const Proximity p = segmentEllipse(st[s0 + s], st[s0 + s + 1], e);
    if (p.distance_m < best->distance_m) {
      *best = p;
      best_seg = s;
    }
  }
  const double x0 = tm.station_x_m[best_seg], x1 = tm.station_x_m[best_seg + 1];
  g->tooth_x_m = x0 + best->param * (x1 - x0);
  return true;
}

// Warm start: the last closest point is within the motion since it was found, so the
// secant starts with a short probe (1e-9 L) and stops once its next correction is
// below the tolerance (1e-15 L) without evaluating it; not converged in 20 iterations
// (or equal slopes apart), the polyline search decides (false returned, nothing set).
bool warmClosestPoint(const ToothModel& tm, double warm_x_m, CentrelineProbe* slopeAt,
                      ContactGeom* g, Proximity* best) {
  const double r_t = 0.5 * tm.diameter_m;
  double xa = warm_x_m;
  double xb = std::min(tm.length_m, xa + 1e-9 * tm.length_m);
  if (xb == xa) xb = xa - 1e-9 * tm.length_m;
  Proximity pa, pb;
  double ha = (*slopeAt)(xa, &pa), hb = (*slopeAt)(xb, &pb);
  bool converged = false;
  for (int it = 0; it < 20 && hb != ha; ++it) {
    const double xn = std::clamp(xb - hb * (xb - xa) / (hb - ha), 0.0, tm.length_m);
    converged = std::abs(xn - xb) <= 1e-15 * tm.length_m;
    if (converged) break;
    xa = xb, ha = hb;
    xb = xn;
    hb = (*slopeAt)(xb, &pb);
  }
  // A warm point that says the bodies are apart is checked by the polyline search,
  // which decides for separated pairs: the secant can settle on another stationary
  // point of the distance than the closest one (a kernel near the round tip), and a
  // pair that separates there would touch again at once (an endless impact chatter).
  if (!converged || pb.distance_m > r_t) return false;
  g->tooth_x_m = xb;
  *best = pb;
  best->point1 = slopeAt->r_x;
  return true;
}

// Refine on the exact deformed centreline (the polyline only brackets it), so that the
// gap and the modal Jacobian below describe the same curve: secant iterations on the
// closest-point condition h(x) = n(x) . r'(x) = 0, started from the polyline's answer.
// Secant iterations on h(x) = n(x) . r'(x) = 0 from xa (with a probe at xa + dx), x kept in
// [lo, hi]; returns the iterations made. *pa: the proximity at the start xa; *pb: at the end
// *xb_out (the last evaluation, whose values the probe's scratch holds).
int closestPointSecant(const ToothModel& tm, CentrelineProbe* slopeAt, double xa, double lo,
                       double hi, double* xb_out, Proximity* pa, Proximity* pb) {
  double xb = std::min(hi, xa + 1e-6 * tm.length_m);
  if (xb == xa) xb = xa - 1e-6 * tm.length_m;
  double ha = (*slopeAt)(xa, pa), hb = (*slopeAt)(xb, pb);
  int iterations = 0;
  for (; iterations < 20 && hb != ha && std::abs(xb - xa) > 1e-15 * tm.length_m; ++iterations) {
    const double xn = std::clamp(xb - hb * (xb - xa) / (hb - ha), lo, hi);
    xa = xb, ha = hb;
    xb = xn;
    hb = (*slopeAt)(xb, pb);
  }
  // No secant step (equal slopes at both points, e.g. a flank square to the axis at the
  // tip): xb is only the probe; keep the polyline's point if it is the closer one, and
  // evaluate there again so that r_x and the mode values in scratch_phi/dphi describe it.
  if (iterations == 0 && pa->distance_m < pb->distance_m) {
    xb = xa;
    (*slopeAt)(xb, pb);
  }
  *xb_out = xb;
  return iterations;
}

void refineClosestPoint(const ToothModel& tm, CentrelineProbe* slopeAt, ContactGeom* g,
                        Proximity* best) {
  const double x0 = g->tooth_x_m;
  double xb = x0;
  Proximity pa, pb;
  closestPointSecant(tm, slopeAt, x0, 0.0, tm.length_m, &xb, &pa, &pb);
  // The secant may run off to another stationary point of the distance, far from the
  // polyline's (a strongly bent rod pressed against an elongated kernel: the iteration ran to
  // the root, and the pair, 0.36 mm deep, read 59.5 mm apart for one step, so that it opened
  // and closed every 1e-11 s). A point farther than the polyline's by more than the tooth's
  // radius is such a run-off (a converged point lies within the polyline's chord error of it;
  // a deep overlap may move it by micrometres, which is kept): then the search is kept to one
  // station interval about the polyline's point, and failing that that point itself is taken.
  const double d0_m = pa.distance_m;  // the first evaluation was at x0
  const double run_off_m = d0_m + 0.5 * tm.diameter_m;
  if (pb.distance_m > run_off_m) {
    const double dx = tm.length_m / std::max(1, tm.n_stations - 1);
    closestPointSecant(tm, slopeAt, x0, std::max(0.0, x0 - dx), std::min(tm.length_m, x0 + dx), &xb,
                       &pa, &pb);
    if (pb.distance_m > run_off_m) {
      xb = x0;
      (*slopeAt)(xb, &pb);
    }
  }
  // The last evaluation was at xb (r_x, pb, and the mode values in scratch_phi/dphi).
  g->tooth_x_m = xb;
  *best = pb;
  best->point1 = slopeAt->r_x;
}

// The closest point of a tooth-kernel pair, into g->tooth_x_m and *best. A pair in contact
// starts from its last closest point (in.warm_x_m) on the exact centreline; should that
// refinement not converge, the polyline search is the fallback. (Not for a large-deflection
// rod: a strongly bent rod alongside an elongated kernel can have two local minima of the
// distance, and the warm start and the search must not pick different ones, or the pair would
// close and open at once.) *direct receives the warm start's stations (the workspace's may be
// stale then) and *from_warm whether the closest point came from the warm start. False if the
// pair is far.
bool toothClosestPoint(const NarrowInput& in, const ToothModel& tm, StationPair* direct,
                       bool* from_warm, ContactGeom* g, Proximity* best) {
  const bool warm = in.warm_x_m != nullptr && *in.warm_x_m >= 0.0 && tm.n_modes > 0 &&
                    tm.beam_model == ToothBeamModel::kModal &&
                    in.far_m == std::numeric_limits<double>::infinity();
  if (warm) {
    CentrelineProbe slopeAt(in, tm, direct);
    *from_warm = warmClosestPoint(tm, *in.warm_x_m, &slopeAt, g, best);
    if (*from_warm) return true;
    updateToothStations(in.m, in.z, in.drive.theta_rad, in.pair.a, in.ws);
  }
  if (!polylineClosestPoint(in, tm, g, best)) return false;
  if (tm.n_modes > 0) {
    CentrelineProbe slopeAt(in, tm, nullptr);
    refineClosestPoint(tm, &slopeAt, g, best);
  }
  return true;
}

// Rod: the centreline point moves at A E (dr/dq) qdot, the surface offset r_t n turns
// with the section angle theta(x) = phi(x) . q.
void rodToothSide(const NarrowInput& in, const ToothModel& tm, ContactGeom* g) {
  const double r_t = 0.5 * tm.diameter_m;
  BodyJac& s = g->side[0];
  const int n = tm.n_modes;
  LdJac jac;
  ldPoint(tm, ldConfigOf(in.m, in.pair.a, in.z, in.ws), g->tooth_x_m, nullptr, nullptr, &jac);
  double theta_shape[kLdMaxShapes], phi[kLdMaxShapes];
  ldShapes(tm, g->tooth_x_m, theta_shape, nullptr);
  // The section's turn per coordinate: phi^T S (S = I for Euler-Bernoulli sections).
  for (int i = 0; i < n; ++i) {
    phi[i] = 0.0;
    for (int k = 0; k < n; ++k) phi[i] += theta_shape[k] * tm.ld_rotation_filter(k, i);
  }
  const Rotation2 rot(in.drive.theta_rad);
  const Vec2 e1 = rot * tm.e1_D, e2 = rot * tm.e2_D;
  const Vec2 jr = perp(r_t * g->n);
  const double jrn = jr.dot(g->n), jrt = jr.dot(g->t);
  for (int i = 0; i < n; ++i) {
    const Vec2 col = jac(0, i) * e1 + jac(1, i) * e2;
    s.w_n[i] = -(col.dot(g->n) + jrn * phi[i]);
    s.w_t[i] = -(col.dot(g->t) + jrt * phi[i]);
  }
}

// The closest point's response to a motion of a tooth pair: the implicit function theorem on
// the narrow phase's condition n . rt_x(x*) = 0 (as in the velocity drift, contact_forces.cc).
// For the centreline point at x* moving at w relative to the kernel's material point there,
// the condition's tangent rt_x(x*) changing at rtx_rate at fixed x*, and the kernel turning at
// om1, the closest point moves at x*' and the normal turns at phi' = om1 - kappa t.(w + r_x x*').
struct ClosestPointSensitivity {
  Vec2 n, t;              // contact normal and tangent, world [-]
  Vec2 r_x;               // d r / dx of the centreline point, world [-]
  Vec2 rt_x, rt_xx;       // the condition's tangent [-] and its x-derivative [1/m], world
  double kappa = 0;       // 1 / (rho1 + d): the normal's turn per relative motion [1/m]
  bool interior = false;  // x* inside (0, L) moves; at an end of the tooth it stays
  void rates(const Vec2& w, const Vec2& rtx_rate, double om1, double* x_rate,
             double* phi_rate) const {
    const double beta0 = om1 - kappa * t.dot(w), beta1 = -kappa * t.dot(r_x);
    double xr = 0.0;
    if (interior) {
      const double den = beta1 * t.dot(rt_x) + n.dot(rt_xx);
      if (den != 0.0) xr = -(beta0 * t.dot(rt_x) + n.dot(rtx_rate)) / den;
    }
    *x_rate = xr;
    *phi_rate = beta0 + beta1 * xr;
  }
};

// What the residual's gradient needs of a modal tooth pair besides the contact frame.
struct ResidualInputs {
  double r_ww_mpN = 0;           // residual table at x*, w under a force [m/N]
  double dr_ww_dx_mpNpm = 0;     // its derivative in x (C^1 interpolant) [1/N]
  double wc_slope = 0;           // d w_c / dx of the stations' foreshortening at x* [-]
  const double* hq = nullptr;    // H(x*) q per mode, blended as the narrow phase does [1/sqrt(kg)]
  const double* phi = nullptr;   // phi(x*) per mode [1/sqrt(kg)]
  const double* dphi = nullptr;  // phi'(x*) per mode [1/(sqrt(kg) m)]
  double w1 = 0, w2 = 0;         // w'(x*) = phi' . q [-], w''(x*) = phi'' . q [1/m]
  Vec2 e1 = Vec2::UnitX(), e2 = Vec2::UnitY();  // the tooth's axes in world at the drum angle [-]
};

// The residual flexibility along n, R = (e2.n)^2 r_ww(x*) (docs/model.md §9b), differentiated
// along every coordinate (the sides' w_r) and the drum angle (residual_dtheta_mpNprad): R moves
// with the normal's direction (dR/dphi = 2 (e2.n)(e2.t) r_ww) and with the closest point
// (dR/dx* = (e2.n)^2 r_ww'), both given by ClosestPointSensitivity.
void residualGradient(const Vec2& kernel_center_m, const ToothModel& tm, const ResidualInputs& ri,
                      ContactGeom* g) {
  const int n_modes = tm.n_modes;
  const double x = g->tooth_x_m, r_t = 0.5 * tm.diameter_m;
  const Vec2& e1 = ri.e1;
  const Vec2& e2 = ri.e2;
  const double* phi = ri.phi;
  const double* dphi = ri.dphi;
  const double w1 = ri.w1, w2 = ri.w2;  // w', w'' [-, 1/m]
  ClosestPointSensitivity cp;
  cp.n = g->n;
  cp.t = g->t;
  cp.r_x = (1.0 + ri.wc_slope) * e1 + w1 * e2;
  cp.rt_x = (1.0 - 0.5 * w1 * w1) * e1 + w1 * e2;
  cp.rt_xx = -w1 * w2 * e1 + w2 * e2;
  cp.kappa = 1.0 / (g->rho1_m + g->gap_m + r_t);
  cp.interior = x > 0.0 && x < tm.length_m;
  const double c = e2.dot(g->n);
  const double dR_dphi = 2.0 * c * e2.dot(g->t) * ri.r_ww_mpN;  // [m/(N rad)]
  const double dR_dx = c * c * ri.dr_ww_dx_mpNpm;               // [1/N]
  const auto rate = [&](const Vec2& w, const Vec2& rtx_rate, double om1) {
    double x_rate, phi_rate;
    cp.rates(w, rtx_rate, om1, &x_rate, &phi_rate);
    return dR_dphi * phi_rate + dR_dx * x_rate;
  };
  BodyJac& s0 = g->side[0];
  s0.w_r.resize(n_modes);
  for (int i = 0; i < n_modes; ++i)
    s0.w_r[i] = rate(phi[i] * e2 - ri.hq[i] * e1, dphi[i] * (e2 - w1 * e1), 0.0);
  // The kernel (body 1): the centreline point moves relative to it against its motion.
  const Vec2 p_W = g->p0 - r_t * g->n;  // centreline point [m]
  BodyJac& s1 = g->side[1];
  s1.w_r.resize(3);
  s1.w_r[0] = rate(-Vec2::UnitX(), Vec2::Zero(), 0.0);
  s1.w_r[1] = rate(-Vec2::UnitY(), Vec2::Zero(), 0.0);
  s1.w_r[2] = rate(-perp(p_W - kernel_center_m), Vec2::Zero(), 1.0);
  // The drum turning the tooth (point, tangent and e2) past the kernel.
  g->residual_dtheta_mpNprad =
      rate(perp(p_W), perp(cp.rt_x), 0.0) + 2.0 * c * ri.r_ww_mpN * perp(e2).dot(g->n);
}

// Modal tooth: phi and phi' at x are still in the scratch from the refinement's last
// evaluation; the surface point turns with the section, psi_i = rotation_factor_i phi_i'; H(x) q
// is blended from the stations like H(x) itself (from *direct after a warm start). Also the
// residual flexibility along n in series with the Hertz law, and its gradient.
void modalToothSide(const NarrowInput& in, const ToothModel& tm, bool from_warm,
                    StationPair* direct, ContactGeom* g) {
  Workspace* ws = in.ws;
  const double r_t = 0.5 * tm.diameter_m;
  BodyJac& s = g->side[0];
  const int n = tm.n_modes;
  int s_h = 0;
  double t_h = 0;
  stationInterval(tm, g->tooth_x_m, &s_h, &t_h);
  const int col_h = ws->centreline.station_offset[in.pair.a] + s_h;
  if (from_warm) direct->update(tm, s_h, in.z.data() + tm.dof_offset);
  const Rotation2 rot(in.drive.theta_rad);
  const Vec2 e1 = rot * tm.e1_D, e2 = rot * tm.e2_D;
  const Vec2 jr = perp(r_t * g->n);
  const double e2n = e2.dot(g->n), e1n = e1.dot(g->n), jrn = jr.dot(g->n);
  const double e2t = e2.dot(g->t), e1t = e1.dot(g->t), jrt = jr.dot(g->t);
  double hq[kMaxModes];  // H(x) q [1/sqrt(kg)]
  for (int i = 0; i < n; ++i) {
    hq[i] = from_warm ? (1.0 - t_h) * direct->hq0[i] + t_h * direct->hq1[i]
                      : (1.0 - t_h) * ws->centreline.station_Hq(i, col_h) +
                            t_h * ws->centreline.station_Hq(i, col_h + 1);
    const double psi = tm.rotation_factor[i] * ws->centreline.scratch_dphi[i];  // section turn
    s.w_n[i] = -(e2n * ws->centreline.scratch_phi[i] - e1n * hq[i] + jrn * psi);
    s.w_t[i] = -(e2t * ws->centreline.scratch_phi[i] - e1t * hq[i] + jrt * psi);
  }
  if (!tm.static_correction) return;
  // The truncated modes' compliance along n: the load e2.n on w (C^1 in x, so that its
  // gradient, part of the contact force, is continuous).
  // The table at the drum's current speed (the compiled one, or main's interpolation in
  // Omega^2), so that the gradient below is that of the R the step uses.
  ResidualInputs ri;
  ri.r_ww_mpN = residualSmoothAtSpeed(tm, in.drive.omega_radps, g->tooth_x_m, &ri.dr_ww_dx_mpNpm);
  g->residual_mpN = e2n * e2n * ri.r_ww_mpN;
  const double dx_m = tm.station_x_m[s_h + 1] - tm.station_x_m[s_h];
  ri.wc_slope =
      from_warm
          ? (direct->wc1 - direct->wc0) / dx_m
          : (ws->centreline.station_wc_m[col_h + 1] - ws->centreline.station_wc_m[col_h]) / dx_m;
  ri.hq = hq;
  evaluateModeCurvatures(tm, g->tooth_x_m, &ws->centreline.scratch_ddphi);
  const auto q = in.z.segment(tm.dof_offset, n);
  ri.phi = ws->centreline.scratch_phi.data();
  ri.dphi = ws->centreline.scratch_dphi.data();
  ri.w1 = ws->centreline.scratch_dphi.dot(q);
  ri.w2 = ws->centreline.scratch_ddphi.dot(q);
  ri.e1 = e1;
  ri.e2 = e2;
  residualGradient(in.e.center, tm, ri, g);
}

// The contact frame of a tooth pair from its closest point's proximity (point1: the centreline
// point): gap, normal, tangent, the contact points on the tooth's surface and the kernel's, and
// the kernel's radius of curvature there.
void setToothContactFrame(const Proximity& best, double r_t, ContactGeom* g) {
  g->gap_m = best.distance_m - r_t;
  g->rho1_m = best.radius2_m;
  g->n = best.normal;
  g->t = perp(g->n);
  g->p0 = best.point1 + r_t * g->n;
  g->p1 = best.point2;
}

// A tooth pair whose frame is set: the rheonomic term of the drum turning at omega_radps and
// the Hertz inputs.
void toothRheonomicAndHertz(const ToothModel& tm, const KernelModel& kern, const Ellipse& e,
                            double omega_radps, ContactGeom* g, HertzInputs* h) {
  const double r_t = 0.5 * tm.diameter_m;
  // Rheonomic term: the drum carries the tooth point at Omega J p0.
  g->wtilde_n = -omega_radps * cross(g->p0, g->n);
  g->wtilde_t = -omega_radps * cross(g->p0, g->t);
  // Hertz: tooth flat along its side in plane (round at the tip), round (r_t) across.
  const bool at_tip = g->tooth_x_m >= tm.length_m * (1.0 - 1e-9);
  h->r_in = seriesRadius(at_tip ? r_t : std::numeric_limits<double>::infinity(),
                         ellipseCurvatureRadius(e, g->p1));
  h->r_out = seriesRadius(r_t, kern.semi_axis_b_m);
  h->E_star = effectiveModulus(tm.youngs_modulus_Pa, tm.poisson_ratio, kern.youngs_modulus_Pa,
                               kern.poisson_ratio);
}

// Tooth (body 0) against a kernel: the closest point of the deformed centreline, the tooth's
// side of the Jacobians, the drum's rheonomic term and the Hertz inputs.
bool toothKernel(const NarrowInput& in, ContactGeom* g, HertzInputs* h) {
  const ToothModel& tm = in.m.teeth[in.pair.a];
  Proximity best;
  best.distance_m = std::numeric_limits<double>::infinity();
  const double r_t = 0.5 * tm.diameter_m;
  StationPair direct;      // the warm start's stations (the workspace's may be stale then)
  bool from_warm = false;  // the closest point came from the warm start
  if (!toothClosestPoint(in, tm, &direct, &from_warm, g, &best)) return false;
  if (in.warm_x_m != nullptr) *in.warm_x_m = g->tooth_x_m;
  setToothContactFrame(best, r_t, g);

  // Tooth side: velocity of the surface point = Omega J p0 + Jq qdot, with
  // Jq = A(theta) (e2 phi^T - e1 (H q)^T) + (J r_t n) psi^T (psi: the sections' rotation).
  BodyJac& s = g->side[0];
  s.body = toothBody(in.pair.a);
  const int n = tm.n_modes;
  s.w_n.resize(n);
  s.w_t.resize(n);
  if (n > 0 && tm.beam_model == ToothBeamModel::kLargeDeflection)
    rodToothSide(in, tm, g);
  else if (n > 0)
    modalToothSide(in, tm, from_warm, &direct, g);
  toothRheonomicAndHertz(tm, in.kern, in.e, in.drive.omega_radps, g, h);
  return true;
}

// --- kernel against kernel ------------------------------------------------------------------

// The contact frame of a pair of exact shapes from their proximity p: gap, normal from body 1
// to body 2, tangent t = J n and the closest points (no tooth coordinate).
void setContactFrame(const Proximity& p, ContactGeom* g) {
  g->gap_m = p.distance_m;
  g->n = p.normal;
  g->t = perp(g->n);
  g->p0 = p.point1;
  g->p1 = p.point2;
  g->tooth_x_m = 0;
}

// Ellipse a against ellipse b; normal from a to b.
bool kernelKernel(const NarrowInput& in, ContactGeom* g, HertzInputs* h) {
  const Ellipse& e = in.e;
  const KernelModel& ka = in.m.kernels[in.pair.a];
  const Ellipse ea = kernelEllipse(in.m, in.z, in.pair.a);
  // Supporting-line gap along the line of centres.
  const Vec2 d_ab = e.center - ea.center;
  const double dist_ab = d_ab.norm();
  const double bound =
      !in.tight_bound
          ? dist_ab - e.a_m - ea.a_m
          : (dist_ab > 0.0 ? dist_ab - in.width(d_ab / dist_ab) - EllipseWidth(ea)(d_ab / dist_ab)
                           : -e.a_m - ea.a_m);
  if (isFar(bound, in.far_m, g)) return false;
  const Proximity p =
      in.warm_theta_rad ? ellipseEllipse(ea, e, in.warm_theta_rad) : ellipseEllipse(ea, e);
  setContactFrame(p, g);
  BodyJac& s = g->side[0];
  s.body = kernelBody(in.m, in.pair.a);
  kernelRow(g->p0, ea.center, g->n, -1.0, &s.w_n);
  kernelRow(g->p0, ea.center, g->t, -1.0, &s.w_t);
  g->rho0_m = ellipseCurvatureRadius(ea, g->p0);
  g->rho1_m = p.radius2_m;
  h->r_in = seriesRadius(g->rho0_m, p.radius2_m);
  h->r_out = seriesRadius(ka.semi_axis_b_m, in.kern.semi_axis_b_m);
  h->E_star = effectiveModulus(ka.youngs_modulus_Pa, ka.poisson_ratio, in.kern.youngs_modulus_Pa,
                               in.kern.poisson_ratio);
  return true;
}

// --- kernel against a fixed obstacle, one function per obstacle type ------------------------
// Fixed obstacle against the kernel; normal from the obstacle to the kernel.

// What the obstacles share once the proximity p is known: the surface's own curvature rho0
// (a plate: flat along it, round with its radius at either end), the obstacle's in-plane
// radius r_obst for the Hertz law (inf: flat) [m].
void obstacleContact(const NarrowInput& in, const ObstacleModel& o, const Proximity& p,
                     double rho0_m, double r_obst, ContactGeom* g, HertzInputs* h) {
  g->rho0_m = rho0_m;
  g->rho1_m = p.radius2_m;
  setContactFrame(p, g);
  h->r_in = seriesRadius(r_obst, p.radius2_m);
  h->r_out = in.kern.semi_axis_b_m;  // bars and plates are straight along the drum axis
  h->E_star = effectiveModulus(o.youngs_modulus_Pa, o.poisson_ratio, in.kern.youngs_modulus_Pa,
                               in.kern.poisson_ratio);
}

bool kernelPlane(const NarrowInput& in, ContactGeom* g, HertzInputs* h) {
  const ObstacleModel& o = in.m.obstacles[in.pair.b];
  const Ellipse& e = in.e;
  const double bound =
      o.normal.dot(e.center - o.point_m) - (!in.tight_bound ? e.a_m : in.width(o.normal));
  if (isFar(bound, in.far_m, g)) return false;
  const Proximity p = planeEllipse(o.point_m, o.normal, e);
  const double inf = std::numeric_limits<double>::infinity();
  obstacleContact(in, o, p, inf, inf, g, h);
  return true;
}

// A plate (segment with a radius).
bool kernelPlate(const NarrowInput& in, ContactGeom* g, HertzInputs* h) {
  const ObstacleModel& o = in.m.obstacles[in.pair.b];
  const Ellipse& e = in.e;
  const Vec2 ab = o.point_b_m - o.point_m;
  const double f = std::clamp((e.center - o.point_m).dot(ab) / ab.squaredNorm(), 0.0, 1.0);
  const Vec2 c = o.point_m + f * ab;
  const double bound =
      (!in.tight_bound ? (e.center - c).norm() - e.a_m : gapLowerBound(e, in.width, c)) -
      o.radius_m;
  if (isFar(bound, in.far_m, g)) return false;
  Proximity p = segmentEllipse(o.point_m, o.point_b_m, e);
  p.distance_m -= o.radius_m;
  p.point1 += o.radius_m * p.normal;
  const double inf = std::numeric_limits<double>::infinity();
  obstacleContact(in, o, p, p.param <= 0.0 || p.param >= 1.0 ? o.radius_m : inf, inf, g, h);
  return true;
}

// A bar (circle).
bool kernelBar(const NarrowInput& in, ContactGeom* g, HertzInputs* h) {
  const ObstacleModel& o = in.m.obstacles[in.pair.b];
  const Ellipse& e = in.e;
  const double bound = (!in.tight_bound ? (e.center - o.center_m).norm() - e.a_m
                                        : gapLowerBound(e, in.width, o.center_m)) -
                       o.radius_m;
  if (isFar(bound, in.far_m, g)) return false;
  const Proximity p = circleEllipse(o.center_m, o.radius_m, e);
  obstacleContact(in, o, p, o.radius_m, o.radius_m, g, h);
  return true;
}

// --- the dispatch table ---------------------------------------------------------------------

// A pair function fills g's gap, normal, tangent, contact points and curvatures, body 0's side
// of the Jacobians and the rheonomic terms, and the Hertz inputs; false if the pair is far
// (only g->gap_m and g->far set).
using PairFunction = bool (*)(const NarrowInput& in, ContactGeom* g, HertzInputs* h);

// One function per pair kind, kernel-obstacle pairs one per obstacle type: indexed by
// PairKind, then (kKernelObstacle + ObstacleType) for the obstacles.
constexpr PairFunction kPairFunctions[] = {
    toothKernel,   // PairKind::kToothKernel
    kernelKernel,  // PairKind::kKernelKernel
    kernelPlane,   // PairKind::kKernelObstacle + ObstacleType::kPlane
    kernelPlate,   // PairKind::kKernelObstacle + ObstacleType::kSegment
    kernelBar,     // PairKind::kKernelObstacle + ObstacleType::kCircle
};
static_assert(static_cast<int>(PairKind::kToothKernel) == 0 &&
                  static_cast<int>(PairKind::kKernelKernel) == 1 &&
                  static_cast<int>(PairKind::kKernelObstacle) == 2,
              "kPairFunctions is indexed by PairKind");
static_assert(static_cast<int>(ObstacleType::kPlane) == 0 &&
                  static_cast<int>(ObstacleType::kSegment) == 1 &&
                  static_cast<int>(ObstacleType::kCircle) == 2,
              "kPairFunctions is indexed by ObstacleType after kKernelObstacle");

int pairFunctionIndex(const Model& m, const PairId& pair) {
  const int kind = static_cast<int>(pair.kind);
  if (pair.kind != PairKind::kKernelObstacle) return kind;
  return kind + static_cast<int>(m.obstacles[pair.b].type);
}

// Kernel side (body 1) and the relative velocities.
void kernelSide(const Model& m, const VecX& u, int kb, const Ellipse& e, ContactGeom* g) {
  BodyJac& s1 = g->side[1];
  s1.body = kernelBody(m, kb);
  kernelRow(g->p1, e.center, g->n, 1.0, &s1.w_n);
  kernelRow(g->p1, e.center, g->t, 1.0, &s1.w_t);
  g->vn = g->wtilde_n;
  g->vt = g->wtilde_t;
  for (const BodyJac& s : g->side) {
    if (s.body < 0 || s.w_n.size() == 0) continue;
    const auto ub = u.segment(bodyDofOffset(m, s.body), s.w_n.size());
    g->vn += s.w_n.dot(ub);
    g->vt += s.w_t.dot(ub);
  }
}

// What every evaluation of a pair starts from: nothing known yet.
void resetGeom(const Model& m, const PairId& pair, ContactGeom* g) {
  g->pair = pair;
  g->far = false;
  g->params = &m.contact[static_cast<int>(pair.kind)];
  g->wtilde_n = g->wtilde_t = 0.0;
  g->rho0_m = g->rho1_m = std::numeric_limits<double>::infinity();
  g->residual_mpN = 0.0;
  g->residual_dtheta_mpNprad = 0.0;
  g->side[1].w_r.resize(0);
  g->side[0].w_r.resize(0);
  g->side[0].body = -1;
  g->side[0].w_n.resize(0);
  g->side[0].w_t.resize(0);
}

// --- tooth against kernel, warm (the contact phase) -------------------------------------------

// Newton steps on the closest-point condition of a warm pair: at most this many evaluations
// [-], stopped once the next correction is below kWarmTol_L of the tooth's length [-] (the
// point evaluated last is kept: within that of the root) or taken without a new projection
// below kWarmPolish_L (polish), and no farther from the warm start than kWarmMaxMove_intervals
// station intervals [-].
constexpr int kWarmMaxEvaluations = 5;
constexpr double kWarmTol_L = 1e-13;
constexpr double kWarmMaxMove_intervals = 0.25;

// What the warm closest point's evaluations share: the tooth, its coordinates, its frame, the
// kernel with the cosine and sine of its angle, and the stations bracketing the last point.
struct WarmQuery {
  // (A constructor: aggregate initialisation would value-initialise, i.e. zero, the stations'
  // arrays, a kilobyte per pair.)
  WarmQuery(const ToothModel& tooth, const double* coordinates, const ToothFrame& tooth_frame,
            const Ellipse& kernel, double cos_angle, double sin_angle)
      : tm(tooth),
        q(coordinates),
        frame(tooth_frame),
        e(kernel),
        cos_e(cos_angle),
        sin_e(sin_angle) {}
  const ToothModel& tm;           // the tooth
  const double* q;                // its modal coordinates [sqrt(kg) m]
  const ToothFrame& frame;        // its axes in world at the drum angle
  const Ellipse& e;               // the kernel
  double cos_e, sin_e;            // cos and sin of the kernel's angle [-]
  StationPair stations;           // H q and w_c at the stations bracketing the last point
  DeflectionInterval deflection;  // the mode table's interval of the last point, times q
};

// The deformed centreline of a modal tooth at material coordinate x_m against the kernel:
// everything the closest-point condition h = n . rt_x and its derivative need.
struct WarmPoint {
  double x_m = 0;            // material coordinate [m]
  int s = 0;                 // station interval holding x [-]
  double t = 0;              // blend weight of its station s + 1 [-]
  double w1 = 0, w2 = 0;     // w' [-], w'' [1/m]
  double wc_slope = 0;       // d w_c / dx [-]
  Vec2 r = Vec2::Zero();     // centreline point, world [m]
  Vec2 rt_x = Vec2::Zero();  // the condition's tangent (1 - w'^2/2) e1 + w' e2, world [-]
  Proximity p;               // the centreline point against the kernel
  double h = 0;              // the condition n . rt_x [-]
  double dh = 0;             // its derivative in x [1/m]
};

// The centreline at x_m into *pt (the stations' H q and w_c computed directly), not its
// proximity.
void warmCentrelineAt(WarmQuery* wq, double x_m, WarmPoint* pt) {
  const ToothModel& tm = wq->tm;
  pt->x_m = x_m;
  double w = 0;  // deflection [m]
  interpolateDeflection(tm, wq->q, x_m, &wq->deflection, &w, &pt->w1, &pt->w2);
  stationInterval(tm, x_m, &pt->s, &pt->t);
  wq->stations.update(tm, pt->s, wq->q);
  const StationPair& st = wq->stations;
  const double wc = (1.0 - pt->t) * st.wc0 + pt->t * st.wc1;
  pt->wc_slope = (st.wc1 - st.wc0) / (tm.station_x_m[pt->s + 1] - tm.station_x_m[pt->s]);
  const Vec2& e1 = wq->frame.e1_W;
  const Vec2& e2 = wq->frame.e2_W;
  pt->r = wq->frame.root_W + (x_m + wc) * e1 + w * e2;
  pt->rt_x = (1.0 - 0.5 * pt->w1 * pt->w1) * e1 + pt->w1 * e2;
}

// The closest-point condition h = n . rt_x at the point *pt (its centreline from
// warmCentrelineAt, its proximity in pt->p) and its derivative dh/dx.
void warmCondition(const WarmQuery& wq, WarmPoint* pt) {
  const Vec2& e1 = wq.frame.e1_W;
  const Vec2& e2 = wq.frame.e2_W;
  const Vec2& n_W = pt->p.normal;
  pt->h = n_W.dot(pt->rt_x);
  // dh/dx = n' . rt_x + n . rt_xx; the normal turns at n' = -kappa (t . r_x) t as the point
  // moves along r_x (kappa = 1 / (rho + d), the ellipse's curvature seen from the point).
  const Vec2 r_x = (1.0 + pt->wc_slope) * e1 + pt->w1 * e2;
  const Vec2 rt_xx = -pt->w1 * pt->w2 * e1 + pt->w2 * e2;
  const Vec2 t_W = perp(n_W);
  const double kappa = 1.0 / (pt->p.radius2_m + pt->p.distance_m);
  pt->dh = -kappa * t_W.dot(r_x) * t_W.dot(pt->rt_x) + n_W.dot(rt_xx);
}

// Whether the point evaluated is a minimum of the distance along the tooth at an end of it: the
// distance falls out of [0, L] there (its slope is -h).
bool atEndMinimum(const ToothModel& tm, const WarmPoint& pt) {
  return (pt.x_m >= tm.length_m && pt.h >= 0.0) || (pt.x_m <= 0.0 && pt.h <= 0.0);
}

// Newton steps from x_warm_m on the closest-point condition (the distance's minimum: dh < 0
// inside the tooth, or an end where the distance falls out of it); false where the guard
// doubts the answer. *pt: the point evaluated last, the closest point.
// The centreline at x_m and its proximity, with the condition (a full evaluation).
void warmPointAt(WarmQuery* wq, double x_m, WarmPoint* pt) {
  warmCentrelineAt(wq, x_m, pt);
  pt->p = pointEllipse(pt->r, wq->e, wq->cos_e, wq->sin_e);
  warmCondition(*wq, pt);
}

// The last Newton step, when it is below kWarmPolish_L of the tooth's length [-], moves the
// point's proximity to first order instead of projecting it again: with the move delta of the
// centreline point, the distance d - n.delta + kappa (t.delta)^2 / 2 and the normal turned by
// -kappa t.delta (kappa = 1 / (rho + d)) are exact but for O(kappa |delta|^2), ~1e-18 m and
// ~1e-15 rad at 1e-9 L on a 60 mm tooth against a 1.3 mm radius of curvature.
constexpr double kWarmPolish_L = 1e-9;

// The proximity *p of the centreline point moved by delta_m [m], to first order (second in the
// distance); the ellipse's radius of curvature at the new foot point from its normal.
void movedProximity(const WarmQuery& wq, const Vec2& delta_m, Proximity* p) {
  const Vec2 n0 = p->normal, t0 = perp(n0);
  const double kappa = 1.0 / (p->radius2_m + p->distance_m);  // [1/m]
  const double along = t0.dot(delta_m);                       // [m]
  const double turn = -kappa * along;                         // [rad]
  p->distance_m += -n0.dot(delta_m) + 0.5 * kappa * along * along;
  p->normal = (1.0 - 0.5 * turn * turn) * n0 + turn * t0;
  p->point1 += delta_m;
  p->point2 = p->point1 + p->distance_m * p->normal;
  // Outward normal -n in the ellipse's frame; rho = a^2 b^2 / h^3, h its support value.
  const double na = -(wq.cos_e * p->normal.x() + wq.sin_e * p->normal.y());
  const double nb = -(-wq.sin_e * p->normal.x() + wq.cos_e * p->normal.y());
  const double a = wq.e.a_m, b = wq.e.b_m;
  const double h = std::sqrt(a * a * na * na + b * b * nb * nb);
  p->radius2_m = a * a * b * b / (h * h * h);
}

// The last Newton step to x_m [m]: the centreline there, its proximity moved to first order.
void polish(WarmQuery* wq, double x_m, WarmPoint* pt) {
  const Vec2 r_before = pt->r;
  const Proximity p_before = pt->p;
  warmCentrelineAt(wq, x_m, pt);
  pt->p = p_before;
  movedProximity(*wq, pt->r - r_before, &pt->p);
}

// Whether the distance from the tooth's centreline to the kernel has one local minimum over
// the tooth, so that the warm answer at centreline distance d_m is the pair's closest point even
// where the bodies are apart. At a critical point of the distance f(x) (the centreline's
// tangent normal to the line to the ellipse), f'' >= 1 / (rho + d) - kappa, rho the ellipse's
// radius of curvature at the foot (at most a^2 / b), d the distance there (at most d_m + L) and
// kappa the centreline's curvature (at most sum |q_i| max |phi_i''|): with f'' > 0 at every
// critical point there is no interior maximum, hence at most one minimum, ends included. Held
// with a factor 2 to spare.
bool singleMinimum(const WarmQuery& wq, double d_m) {
  const ToothModel& tm = wq.tm;
  double kappa_bound = 0.0;  // [1/m]
  for (int i = 0; i < tm.n_modes; ++i) kappa_bound += std::abs(wq.q[i]) * tm.ddphi_bound[i];
  const double rho_max_m = wq.e.a_m * wq.e.a_m / wq.e.b_m;
  return 2.0 * kappa_bound * (rho_max_m + d_m + tm.length_m) < 1.0;
}

bool warmNewton(WarmQuery* wq, double x_warm_m, bool apart_ok, WarmPoint* pt) {
  const ToothModel& tm = wq->tm;
  const double L = tm.length_m;
  const double max_move_m = kWarmMaxMove_intervals * L / std::max(1, tm.n_stations - 1);
  double x = std::clamp(x_warm_m, 0.0, L);
  for (int it = 0; it < kWarmMaxEvaluations; ++it) {
    warmPointAt(wq, x, pt);
    if (std::abs(x - x_warm_m) > max_move_m) return false;
    // Apart: the full path decides, unless the distance has a single minimum.
    if (atEndMinimum(tm, *pt))
      return pt->p.distance_m <= 0.5 * tm.diameter_m ||
             (apart_ok && singleMinimum(*wq, pt->p.distance_m));
    if (!(pt->dh < 0.0)) return false;  // not a strict minimum of the distance
    const double x_next = std::clamp(x - pt->h / pt->dh, 0.0, L);
    if (std::abs(x_next - x) <= kWarmPolish_L * L) {
      if (std::abs(x_next - x) > kWarmTol_L * L) polish(wq, x_next, pt);
      return pt->p.distance_m <= 0.5 * tm.diameter_m ||
             (apart_ok && singleMinimum(*wq, pt->p.distance_m));
    }
    x = x_next;
  }
  return false;
}

// The tooth's side of a warm pair's Jacobians and its residual flexibility, as modalToothSide
// gives them, from the closest point *pt (its w'' from the mode table: interpolateDeflection).
void warmToothSide(const WarmQuery& wq, const WarmPoint& pt, double omega_radps, int tooth,
                   ContactGeom* g) {
  const ToothModel& tm = wq.tm;
  const StationPair& st = wq.stations;
  const int n = tm.n_modes;
  const double r_t = 0.5 * tm.diameter_m;
  BodyJac& s = g->side[0];
  s.body = toothBody(tooth);
  s.w_n.resize(n);
  s.w_t.resize(n);
  const Vec2& e1 = wq.frame.e1_W;
  const Vec2& e2 = wq.frame.e2_W;
  const Vec2 jr = perp(r_t * g->n);
  const double e2n = e2.dot(g->n), e1n = e1.dot(g->n), jrn = jr.dot(g->n);
  const double e2t = e2.dot(g->t), e1t = e1.dot(g->t), jrt = jr.dot(g->t);
  double phi[kMaxModes], dphi[kMaxModes];  // [1/sqrt(kg)], [1/(sqrt(kg) m)]
  interpolateModes(tm, pt.x_m, phi, dphi);
  double hq[kMaxModes];  // H(x) q [1/sqrt(kg)]
  for (int i = 0; i < n; ++i) {
    hq[i] = (1.0 - pt.t) * st.hq0[i] + pt.t * st.hq1[i];
    const double psi = tm.rotation_factor[i] * dphi[i];  // section turn
    s.w_n[i] = -(e2n * phi[i] - e1n * hq[i] + jrn * psi);
    s.w_t[i] = -(e2t * phi[i] - e1t * hq[i] + jrt * psi);
  }
  if (!tm.static_correction) return;
  ResidualInputs ri;
  ri.r_ww_mpN = residualSmoothAtSpeed(tm, omega_radps, pt.x_m, &ri.dr_ww_dx_mpNpm);
  g->residual_mpN = e2n * e2n * ri.r_ww_mpN;
  ri.wc_slope = pt.wc_slope;
  ri.hq = hq;
  ri.phi = phi;
  ri.dphi = dphi;
  ri.w1 = pt.w1;
  ri.w2 = pt.w2;
  ri.e1 = e1;
  ri.e2 = e2;
  residualGradient(wq.e.center, tm, ri, g);
}
}  // namespace

void evaluateContact(const Model& m, const VecX& z, const VecX& u, const Drive& drive,
                     const PairId& pair, Workspace* ws, ContactGeom* g, double far_m,
                     bool tight_bound, double* warm_x_m, double* warm_theta_rad) {
  resetGeom(m, pair, g);
  const int kb = pair.kind == PairKind::kKernelObstacle ? pair.a : pair.b;
  const Ellipse e = kernelEllipse(m, z, kb);
  const EllipseWidth width(e);
  const NarrowInput in{m,           z,        drive,          pair,          ws, far_m,
                       tight_bound, warm_x_m, warm_theta_rad, m.kernels[kb], e,  width};
  HertzInputs h;
  if (!kPairFunctions[pairFunctionIndex(m, pair)](in, g, &h)) return;
  kernelSide(m, u, kb, e, g);
  g->hertz_K = hertzConstant(h.E_star, h.r_in, h.r_out);
}

void ToothFrame::update(const Model& m, int tooth_index, double drum_angle_rad) {
  if (tooth == tooth_index && theta_rad == drum_angle_rad) return;
  tooth = tooth_index;
  theta_rad = drum_angle_rad;
  const ToothModel& tm = m.teeth[tooth_index];
  const Rotation2 rot(drum_angle_rad);
  e1_W = rot * tm.e1_D;
  e2_W = rot * tm.e2_D;
  root_W = rot * tm.p_DR_D;
}

bool evaluateWarmToothKernel(const Model& m, const VecX& z, const VecX& u, const Drive& drive,
                             const PairId& pair, const ToothFrame& frame, double warm_x_m,
                             ContactGeom* g, bool apart_ok) {
  const ToothModel& tm = m.teeth[pair.a];
  if (tm.n_modes == 0 || tm.beam_model != ToothBeamModel::kModal || !(warm_x_m >= 0.0))
    return false;
  const Ellipse e = kernelEllipse(m, z, pair.b);
  const CosSin cs = cosSinOf(e.angle_rad);  // the kernel's angle, once per evaluation
  WarmQuery wq(tm, z.data() + tm.dof_offset, frame, e, cs.c, cs.s);
  WarmPoint pt;
  if (!warmNewton(&wq, warm_x_m, apart_ok, &pt)) return false;
  resetGeom(m, pair, g);
  g->tooth_x_m = pt.x_m;
  Proximity best = pt.p;
  best.point1 = pt.r;
  setToothContactFrame(best, 0.5 * tm.diameter_m, g);
  warmToothSide(wq, pt, drive.omega_radps, pair.a, g);
  HertzInputs h;
  toothRheonomicAndHertz(tm, m.kernels[pair.b], e, drive.omega_radps, g, &h);
  kernelSide(m, u, pair.b, e, g);
  g->hertz_K = hertzConstant(h.E_star, h.r_in, h.r_out);
  return true;
}

}  // namespace internal
}  // namespace threshing_sim
