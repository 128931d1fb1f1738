// threshing_sim core: exact static flexibility of the rotating cantilever (docs/model.md §9b).
//
// EI w'''' - (N w')' - rho A Omega^2 w = load, clamped at x = 0 and free at x = L, on cubic
// Hermite elements. The stiffness is symmetric and banded (half-bandwidth 3 in the dofs
// (w_1, h w'_1, w_2, h w'_2, ...)): it is assembled directly in band storage, factored by a
// banded L D L^T and the 2 x 2 diagonal blocks of its inverse are read off by the selected
// inversion recurrence (Takahashi et al. 1973), O(n_dof) in all: no dense matrix, no
// right-hand side per point.

#include <algorithm>
#include <array>
#include <cmath>
#include <sstream>
#include <stdexcept>
#include <vector>

#include "threshing_sim/core/beam.h"

namespace threshing_sim {
namespace {

constexpr int kBand = 3;  // half-bandwidth of the Hermite beam stiffness [dofs]

// The sweeps below run in long double (64-bit mantissa on x86): the condensation of stiff
// elements (EI / h^3) into the flexibility of a long segment (~L^3 / EI) cancels about
// (L / h)^3 ~ 1e7 of the stiffness, which double precision would leave at ~1e-9.
using Real = long double;
using Band = std::vector<std::array<Real, kBand + 1>>;  // band[i][k] = K(i + k, i)

// Integrals over an element in the unit coordinate s in [0, 1] of the Hermite shape functions
// N(s) = (1 - 3s^2 + 2s^3, s - 2s^2 + s^3, 3s^2 - 2s^3, s^3 - s^2) of the scaled dofs
// (w_a, h w'_a, w_b, h w'_b), exact (integers over a denominator): B = int N'' N''^T,
// M = int N N^T / 420, G_k = int s^k N' N'^T (denominators 30, 60, 210).
constexpr int kB[4][4] = {{12, 6, -12, 6}, {6, 4, -6, 2}, {-12, -6, 12, -6}, {6, 2, -6, 4}};
constexpr int kM[4][4] = {
    {156, 22, 54, -13}, {22, 4, 13, -3}, {54, 13, 156, -22}, {-13, -3, -22, 4}};
constexpr int kG0[4][4] = {{36, 3, -36, 3}, {3, 4, -3, -1}, {-36, -3, 36, -3}, {3, -1, -3, 4}};
constexpr int kG1[4][4] = {{36, 6, -36, 0}, {6, 2, -6, -1}, {-36, -6, 36, 0}, {0, -1, 0, 6}};
constexpr int kG2[4][4] = {{72, 15, -72, -6}, {15, 4, -15, -3}, {-72, -15, 72, 6}, {-6, -3, 6, 18}};

// Lower bands of the stiffness in the scaled dofs, root dofs removed: the bending part [N/m] and
// the rotational part per unit Omega^2 (axial force and centrifugal softening) [N s^2/m].
void assembleBands(const ToothModel& t, double R, int n_el, Band* bending, Band* rotation) {
  const Real L = t.length_m, h = L / n_el;
  const Real EI = static_cast<Real>(t.youngs_modulus_Pa) * t.second_moment_m4;
  const Real rhoA = t.mass_per_length_kgpm;
  bending->assign(2 * n_el, std::array<Real, kBand + 1>{});
  rotation->assign(2 * n_el, std::array<Real, kBand + 1>{});
  const Real stiffness = EI / (h * h * h), mass = rhoA * h / 420;
  for (int e = 0; e < n_el; ++e) {
    // Axial force per Omega^2, rho A [R (L - x) + (L^2 - x^2) / 2] at x = (e + s) h, as
    // a0 + a1 s + a2 s^2, divided by h (the slopes are N'(s) / h), with G_k's denominators.
    const Real x0 = e * h;
    const Real a0 = rhoA * (R * (L - x0) + (L * L - x0 * x0) / 2) / (30 * h);
    const Real a1 = -rhoA * (R + x0) / 60;
    const Real a2 = -rhoA * h / (2 * 210);
    const int first = 2 * e - 2;  // global index of the element's first dof
    for (int j = 0; j < 4; ++j) {
      if (first + j < 0) continue;  // root dofs
      for (int i = j; i < 4; ++i) {
        (*bending)[first + j][i - j] += stiffness * kB[i][j];
        (*rotation)[first + j][i - j] +=
            a0 * kG0[i][j] + a1 * kG1[i][j] + a2 * kG2[i][j] - mass * kM[i][j];
      }
    }
  }
}

[[noreturn]] void throwNotPositive(double omega_radps, double pivot, int dof) {
  std::ostringstream message;
  message << "tooth.stiffness: not positive definite at drum speed " << omega_radps
          << " rad/s (pivot " << pivot << " at dof " << dof << ")";
  throw std::invalid_argument(message.str());
}

// In-place banded L D L^T: band[j][0] becomes d_j, band[j][k] becomes L(j + k, j). Throws if a
// pivot is not positive (the tooth would buckle under its rotation).
void factorBand(double omega_radps, Band* band) {
  Band& b = *band;
  const int n = static_cast<int>(b.size());
  for (int j = 0; j < n; ++j) {
    if (j >= kBand && j + kBand < n) {
      // Interior column, the general loop below written out.
      const Real l0 = b[j - 3][3], l1 = b[j - 2][2], l2 = b[j - 1][1];
      const Real v0 = l0 * b[j - 3][0], v1 = l1 * b[j - 2][0], v2 = l2 * b[j - 1][0];
      const Real d = b[j][0] - l0 * v0 - l1 * v1 - l2 * v2;
      if (!(d > 0)) throwNotPositive(omega_radps, static_cast<double>(d), j);
      const Real inverse = 1 / d;
      b[j][0] = d;
      b[j][1] = (b[j][1] - b[j - 2][3] * v1 - b[j - 1][2] * v2) * inverse;
      b[j][2] = (b[j][2] - b[j - 1][3] * v2) * inverse;
      b[j][3] = b[j][3] * inverse;
      continue;
    }
    // v[p - p0] = L(j, p) d_p for the columns p0..j-1 that reach row j.
    const int p0 = std::max(0, j - kBand);
    Real v[kBand];
    Real d = b[j][0];
    for (int p = p0; p < j; ++p) {
      v[p - p0] = b[p][j - p] * b[p][0];
      d -= b[p][j - p] * v[p - p0];
    }
    if (!(d > 0)) throwNotPositive(omega_radps, static_cast<double>(d), j);
    b[j][0] = d;
    const Real inverse = 1 / d;
    for (int i = j + 1; i <= std::min(n - 1, j + kBand); ++i) {
      Real l = b[j][i - j];
      for (int p = std::max(p0, i - kBand); p < j; ++p) l -= b[p][i - p] * v[p - p0];
      b[j][i - j] = l * inverse;
    }
  }
}

// The band of Z = K^-1 from the factors, bottom up: Z = D^-1 L^-1 + (I - L^T) Z, whose band
// entries need only band entries of Z below them. z[i][k] = Z(i + k, i).
Band invertBand(const Band& f) {
  const int n = static_cast<int>(f.size());
  Band z(n, std::array<Real, kBand + 1>{});
  for (int i = n - 1; i >= 0; --i) {
    const int m = std::min(kBand, n - 1 - i);
    if (m == kBand) {
      // Interior row, the general loop below written out: Z(i + a, i) for a = 3, 2, 1.
      const Real f1 = f[i][1], f2 = f[i][2], f3 = f[i][3];
      z[i][3] = -(f1 * z[i + 1][2] + f2 * z[i + 2][1] + f3 * z[i + 3][0]);
      z[i][2] = -(f1 * z[i + 1][1] + f2 * z[i + 2][0] + f3 * z[i + 2][1]);
      z[i][1] = -(f1 * z[i + 1][0] + f2 * z[i + 1][1] + f3 * z[i + 1][2]);
      z[i][0] = 1 / f[i][0] - (f1 * z[i][1] + f2 * z[i][2] + f3 * z[i][3]);
      continue;
    }
    for (int a = m; a >= 1; --a) {
      Real s = 0;  // sum over b of L(i + b, i) Z(i + b, i + a)
      for (int b = 1; b <= m; ++b) s += f[i][b] * z[i + std::min(a, b)][std::abs(b - a)];
      z[i][a] = -s;
    }
    Real s = 0;
    for (int b = 1; b <= m; ++b) s += f[i][b] * z[i][b];
    z[i][0] = 1 / f[i][0] - s;
  }
  return z;
}

}  // namespace

StaticFlexibilitySolver::StaticFlexibilitySolver(const ToothModel& tooth, double drum_radius_m,
                                                 int n_points, int n_elements)
    : n_points_(n_points) {
  // Element count a multiple of the point intervals, so that every point is a node.
  per_ = n_elements > 0 ? std::max(1, n_elements / (n_points - 1))
                        : (256 + n_points - 2) / (n_points - 1);
  const int n_el = per_ * (n_points - 1);
  h_m_ = static_cast<long double>(tooth.length_m) / n_el;
  assembleBands(tooth, drum_radius_m, n_el, &bending_, &rotation_);
}

StationFlexibility StaticFlexibilitySolver::operator()(double omega_radps) const {
  const Real w2 = static_cast<Real>(omega_radps) * omega_radps;
  Band band(bending_.size());
  for (size_t i = 0; i < band.size(); ++i) {
    for (int k = 0; k <= kBand; ++k) band[i][k] = bending_[i][k] + w2 * rotation_[i][k];
  }
  factorBand(omega_radps, &band);
  const Band z = invertBand(band);
  StationFlexibility f;
  f.ww.setZero(n_points_);
  f.wt.setZero(n_points_);
  f.tt.setZero(n_points_);
  for (int s = 1; s < n_points_; ++s) {
    const int dof = 2 * (s * per_ - 1);  // w of node s * per (node 0, the root, is removed)
    // Back from the scaled rotation dof h w' to w'.
    f.ww[s] = static_cast<double>(z[dof][0]);
    f.wt[s] = static_cast<double>(z[dof][1] / h_m_);
    f.tt[s] = static_cast<double>(z[dof + 1][0] / (h_m_ * h_m_));
  }
  return f;
}

StationFlexibility staticFlexibility(const ToothModel& tooth, double drum_radius_m,
                                     double omega_radps, int n_points, int n_elements) {
  return StaticFlexibilitySolver(tooth, drum_radius_m, n_points, n_elements)(omega_radps);
}

}  // namespace threshing_sim
