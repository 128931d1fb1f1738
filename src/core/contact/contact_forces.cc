// threshing_sim core: the forces of one contact (contact_forces.h): the velocity drift of its
// rows, its generalised forces, and the compliant normal law with a series spring.
#include "contact_forces.h"

#include <algorithm>
#include <array>
#include <cmath>

#include "../internal.h"
#include "planar.h"
#include "stations.h"
#include "threshing_sim/core/beam.h"

namespace threshing_sim {
namespace internal {
namespace {

// Drift of a pair of rigid convex surfaces (kernel-kernel, kernel-obstacle): body 0 (a kernel
// with centre c0 and speed omega0, or fixed) and body 1 (the kernel), with radii of curvature
// rho0, rho1 at p0, p1 and p1 - p0 = gap n. The normal turns at
//   phi' = (v_T + rho0 omega0 + rho1 omega1) / (rho0 + rho1 + gap)
// (the contact points slide over the surfaces at rho (phi' - omega)), so that
//   d(v_N)/dt = phi' v_T + omega1 [rho1 (phi' - omega1) - omega1 n.(p1 - c1)]
//                        + omega0 [rho0 (phi' - omega0) + omega0 n.(p0 - c0)],
//   d(v_T)/dt = -phi' v_N - omega1^2 t.(p1 - c1) + omega0^2 t.(p0 - c0).
Vec2 rigidPairDrift(const ContactGeom& g, const Vec2& c0, double omega0, const Vec2& c1,
                    double omega1) {
  const double rho0 = g.rho0_m, rho1 = g.rho1_m;
  double phi_rate = 0.0;  // a flat body 0 (fixed) keeps the normal
  if (std::isfinite(rho0))
    phi_rate = (g.vt + rho0 * omega0 + rho1 * omega1) / (rho0 + rho1 + g.gap_m);
  double dvn =
      phi_rate * g.vt + omega1 * (rho1 * (phi_rate - omega1) - omega1 * g.n.dot(g.p1 - c1));
  if (omega0 != 0.0) dvn += omega0 * (rho0 * (phi_rate - omega0) + omega0 * g.n.dot(g.p0 - c0));
  const double dvt = -phi_rate * g.vn - omega1 * omega1 * g.t.dot(g.p1 - c1) +
                     omega0 * omega0 * g.t.dot(g.p0 - c0);
  return Vec2(dvn, dvt);
}

// Drift of a tooth-kernel pair. The centreline point r(x) (distance d = gap + r_t from the
// ellipse, radius of curvature rho1 at the foot p1 = r + d n) moves relative to the kernel
// at w = r_dot - V1(r); v_N = -n.w and v_T = -t.w + omega1 d - r_t (Omega + psi_dot), psi the
// sections' rotation (w' for Euler-Bernoulli and a rod, shear-corrected by default). The
// closest point x* follows n.rt_x = 0 (the narrow phase's condition; fixed at an end of the
// tooth), the normal turns at phi' = omega1 - t.(w + r_x x*') / (rho1 + d), and
//   d(v_N)/dt = -phi' t.w - n.w',  d(v_T)/dt = phi' n.w - t.w' + omega1 d' - r_t (alpha +
//   psi'_dot x*'),  w' = r_ddot + r_dot_x x*' - omega1 J (r_dot + r_x x*' - v1),
// d' = -n.(w + r_x x*'), everything in world (the drum frame turned by theta).
Vec2 toothPairDrift(const Model& m, const VecX& z, const VecX& u, const Drive& drive,
                    const ContactGeom& g, Workspace* ws) {
  const ToothModel& tm = m.teeth[g.pair.a];
  const KernelModel& k = m.kernels[g.pair.b];
  const double x = g.tooth_x_m;
  const CentrelineMotion cm = centrelineMotion(m, g.pair.a, z, u, x, ws);
  const Rotation2 rot(drive.theta_rad);
  const double om = drive.omega_radps, al = drive.alpha_radps2;
  // World vectors of the centreline point (the drum turns them at Omega).
  const Vec2 r = rot * cm.r, r_x = rot * cm.r_x;
  const Vec2 r_dot = rot * (om * perp(cm.r) + cm.v);
  const Vec2 r_dot_x = rot * (om * perp(cm.r_x) + cm.v_x);
  const Vec2 r_ddot = rot * (al * perp(cm.r) - om * om * cm.r + 2.0 * om * perp(cm.v) + cm.a);
  const Vec2 rt_x = rot * cm.rt_x, rt_xx = rot * cm.rt_xx;
  const Vec2 rt_x_rate = rot * (om * perp(cm.rt_x) + cm.rt_x_rate);
  // The kernel.
  const Vec2 c1 = z.segment<2>(k.dof_offset), v1 = u.segment<2>(k.dof_offset);
  const double om1 = u[k.dof_offset + 2];
  const Vec2 w = r_dot - (v1 + om1 * perp(r - c1));
  const double r_t = 0.5 * tm.diameter_m;
  const double d = g.gap_m + r_t;
  const double kappa = 1.0 / (g.rho1_m + d);
  // Normal turning rate phi' = beta0 + beta1 x*'; x*' from d/dt (n.rt_x) = 0.
  const double beta0 = om1 - kappa * g.t.dot(w), beta1 = -kappa * g.t.dot(r_x);
  double x_rate = 0.0;
  if (x > 0.0 && x < tm.length_m) {
    const double den = beta1 * g.t.dot(rt_x) + g.n.dot(rt_xx);
    if (den != 0.0) x_rate = -(beta0 * g.t.dot(rt_x) + g.n.dot(rt_x_rate)) / den;
  }
  const double phi_rate = beta0 + beta1 * x_rate;
  const Vec2 move = r_dot + x_rate * r_x;  // velocity of the closest centreline point
  const Vec2 w_rate = r_ddot + x_rate * r_dot_x - om1 * perp(move - v1);
  const double dvn = -(phi_rate * g.t.dot(w) + g.n.dot(w_rate));
  const double dvt = phi_rate * g.n.dot(w) - g.t.dot(w_rate) - om1 * g.n.dot(w + x_rate * r_x) -
                     r_t * (al + cm.drotation_rate_dx * x_rate);
  return Vec2(dvn, dvt);
}

}  // namespace

Vec2 contactVelocityDrift(const Model& m, const VecX& z, const VecX& u, const Drive& drive,
                          const ContactGeom& g, Workspace* ws) {
  if (g.pair.kind == PairKind::kToothKernel) return toothPairDrift(m, z, u, drive, g, ws);
  const int kb = g.pair.kind == PairKind::kKernelObstacle ? g.pair.a : g.pair.b;
  const int o1 = m.kernels[kb].dof_offset;
  Vec2 c0 = Vec2::Zero();
  double omega0 = 0.0;
  if (g.pair.kind == PairKind::kKernelKernel) {
    const int o0 = m.kernels[g.pair.a].dof_offset;
    c0 = z.segment<2>(o0);
    omega0 = u[o0 + 2];
  }
  return rigidPairDrift(g, c0, omega0, z.segment<2>(o1), u[o1 + 2]);
}

void addGeneralised(const Model& m, const ContactGeom& g, double fn, double ft, VecX* f) {
  const double fr = residualForceFactor(g, fn);
  for (const BodyJac& s : g.side) {
    if (s.body < 0 || s.w_n.size() == 0) continue;
    f->segment(bodyDofOffset(m, s.body), s.w_n.size()) += fn * s.w_n + ft * s.w_t;
    if (fr != 0.0 && s.w_r.size() == s.w_n.size())
      f->segment(bodyDofOffset(m, s.body), s.w_r.size()) += fr * s.w_r;
  }
}

namespace {

// Fritsch-Butland slope of a monotone cubic Hermite interpolant at a node between the secants
// d_left and d_right [any unit]: their harmonic mean where they agree in sign, else 0.
double hermiteNodeSlope(double d_left, double d_right) {
  if (!(d_left * d_right > 0.0)) return 0.0;
  return 2.0 * d_left * d_right / (d_left + d_right);
}

}  // namespace

namespace {

// The monotone cubic Hermite interpolant at position f in [0, 1] of interval s of a table of
// last + 1 points spaced h_m [m], from the values v[s - 1 .. s + 2] (only those inside the
// table are read) [m/N]; its derivative in x into *d_dx [1/N].
double hermiteInInterval(const double* v, int last, int s, double f, double h_m, double* d_dx) {
  // Secants of the intervals s - 1, s, s + 1 (one-sided at the ends) [m/N per m].
  const double d_mid = (v[s + 1] - v[s]) / h_m;
  const double d_left = s > 0 ? (v[s] - v[s - 1]) / h_m : d_mid;
  const double d_right = s + 1 < last ? (v[s + 2] - v[s + 1]) / h_m : d_mid;
  const double m0 = s > 0 ? hermiteNodeSlope(d_left, d_mid) : d_mid;
  const double m1 = s + 1 < last ? hermiteNodeSlope(d_mid, d_right) : d_mid;
  const double f2 = f * f, f3 = f2 * f;
  *d_dx = 6.0 * (f - f2) * d_mid + (3.0 * f2 - 4.0 * f + 1.0) * m0 + (3.0 * f2 - 2.0 * f) * m1;
  return (2.0 * f3 - 3.0 * f2 + 1.0) * v[s] + (f3 - 2.0 * f2 + f) * h_m * m0 +
         (3.0 * f2 - 2.0 * f3) * v[s + 1] + (f3 - f2) * h_m * m1;
}

// The interval s of a table of last + 1 equally spaced points on [0, length_m] holding x_m
// (clamped to the tooth), and the position f in it.
void tableInterval(int last, double length_m, double x_m, int* s, double* f) {
  const double u = std::clamp(x_m / length_m, 0.0, 1.0) * last;
  *s = std::min(static_cast<int>(u), last - 1);
  *f = u - *s;
}

}  // namespace

double residualSmoothAt(const VecX& table, double length_m, double x_m, double* d_dx) {
  const int last = static_cast<int>(table.size()) - 1;
  int s = 0;
  double f = 0.0;
  tableInterval(last, length_m, x_m, &s, &f);
  return hermiteInInterval(table.data(), last, s, f, length_m / last, d_dx);
}

double residualSmoothAtSpeed(const ToothModel& tooth, double omega_radps, double x_m,
                             double* d_dx) {
  const int last = kResidualPoints - 1;
  int s = 0;
  double f = 0.0;
  tableInterval(last, tooth.length_m, x_m, &s, &f);
  // Only the points s - 1 .. s + 2 that exist are read at this speed.
  const int first = std::max(s - 1, 0), end = std::min(s + 2, last);
  std::array<double, kResidualPoints> table;
  residualWwAtSpeed(tooth, omega_radps, first, end - first + 1, table.data() + first);
  return hermiteInInterval(table.data(), last, s, f, tooth.length_m / last, d_dx);
}

namespace {

// The Hertz-Hunt-Crossley force with a spring of flexibility r [m/N] in series, as a function
// of the Hertz indentation x [m] at the approach rate rate_mps = d(delta)/dt:
//   Phi(x) = K x^{3/2} D(x),  D = 1 + chi rate / (1 + r s),  s = dF_e/dx = 3/2 K x^{1/2},
// with its partial derivatives in x and in the rate. Zero (no adhesion) where D <= 0.
struct SeriesHertz {
  double K, chi, r, rate;  // [N/m^{3/2}], [s/m], [m/N], [m/s]
  double force(double x, double* d_x, double* d_rate) const {
    const double sq = std::sqrt(x);
    const double split = 1.0 + r * 1.5 * K * sq;  // 1 + r s
    const double D = 1.0 + chi * rate / split;
    if (x <= 0.0 || D <= 0.0) {
      *d_x = *d_rate = 0.0;
      return 0.0;
    }
    *d_x = 1.5 * K * sq * D - chi * rate * r * 0.75 * K * K * x / (split * split);
    *d_rate = K * x * sq * chi / split;
    return K * x * sq * D;
  }
};

// Hertz indentation x in [0, delta] with x + r Phi(x) = delta, by Newton's method kept inside a
// shrinking bracket (bisection where a step leaves it); at most 60 iterations. A Newton step
// below 1e-15 delta ends it: it is tested before the bracket, since a converged step lands on
// the bracket's end that x just became, which is not inside it (that used to bisect the
// bracket down to 1e-15 delta: some 20 iterations more).
double seriesIndentation(const SeriesHertz& h, double delta) {
  double lo = 0.0, hi = delta, x = delta;
  for (int it = 0; it < 60; ++it) {
    double d_x, d_rate;
    const double res = x + h.r * h.force(x, &d_x, &d_rate) - delta;
    if (res > 0.0)
      hi = x;
    else
      lo = x;
    double next = x - res / (1.0 + h.r * d_x);
    if (std::abs(next - x) <= 1e-15 * delta && next >= 0.0 && next <= delta) return next;
    if (!(next > lo && next < hi)) next = 0.5 * (lo + hi);
    if (std::abs(next - x) <= 1e-15 * delta || hi - lo <= 1e-15 * delta) return next;
    x = next;
  }
  return x;
}

}  // namespace

double compliantNormalForce(const ContactGeom& g, double K, double v_in_mps, double v_floor_mps) {
  return compliantNormalForceAt(g, g.gap_m, g.vn, K, v_in_mps, v_floor_mps);
}

double compliantNormalForceAt(const ContactGeom& g, double gap_m, double vn_mps, double K,
                              double v_in_mps, double v_floor_mps) {
  const double delta = -gap_m;
  if (delta <= 0.0) return 0.0;
  // F = K delta^{3/2} (1 + chi d(delta)/dt), chi = c* / v_in, clamped: no adhesion.
  const double chi = g.params->hc_damping_factor / std::max(v_in_mps, v_floor_mps);
  if (g.residual_mpN <= 0.0) {
    const double f = K * delta * std::sqrt(delta) * (1.0 - chi * vn_mps);
    return std::max(f, 0.0);
  }
  const SeriesHertz h{K, chi, g.residual_mpN, -vn_mps};
  double d_x, d_rate;
  return h.force(seriesIndentation(h, delta), &d_x, &d_rate);
}

double compliantNormalForceSigned(const ContactGeom& g, double K, double v_in_mps,
                                  double v_floor_mps) {
  const double delta = std::max(-g.gap_m, 0.0);
  const double chi = g.params->hc_damping_factor / std::max(v_in_mps, v_floor_mps);
  if (g.residual_mpN <= 0.0 || delta <= 0.0)
    return K * delta * std::sqrt(delta) * (1.0 - chi * g.vn);
  // Where the damping would pull, the series spring carries no force: x = delta.
  const SeriesHertz h{K, chi, g.residual_mpN, -g.vn};
  const double x = seriesIndentation(h, delta);
  const double sq = std::sqrt(x);
  return K * x * sq * (1.0 + chi * h.rate / (1.0 + h.r * 1.5 * K * sq));
}

double compliantNormalForceRate(const ContactGeom& g, double K, double v_in_mps, double v_floor_mps,
                                double acc_n_mps2, double r_rate_mpNps) {
  const double delta = -g.gap_m;
  if (delta <= 0.0) return 0.0;
  const double chi = g.params->hc_damping_factor / std::max(v_in_mps, v_floor_mps);
  const SeriesHertz h{K, chi, std::max(g.residual_mpN, 0.0), -g.vn};
  const double x = h.r > 0.0 ? seriesIndentation(h, delta) : delta;
  double d_x, d_rate;
  const double f = h.force(x, &d_x, &d_rate);
  if (f <= 0.0) return 0.0;
  // Phi's derivative in r through the damping's split, D = 1 + chi rate / (1 + r s) [N^2/m].
  const double s = 1.5 * K * std::sqrt(x), split = 1.0 + h.r * s;
  const double d_r = -K * x * std::sqrt(x) * chi * h.rate * s / (split * split);
  // x + r Phi(x, rate, r) = delta differentiated in time: x' (1 + r Phi_x) = delta' - r Phi_rate
  // delta'' - r' (Phi + r Phi_r), with delta' = -g_N', delta'' = -g_N''.
  const double x_rate =
      (h.rate + h.r * d_rate * acc_n_mps2 - r_rate_mpNps * (f + h.r * d_r)) / (1.0 + h.r * d_x);
  return d_x * x_rate - d_rate * acc_n_mps2 + d_r * r_rate_mpNps;
}

}  // namespace internal
}  // namespace threshing_sim
