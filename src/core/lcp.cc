// threshing_sim core: Lemke's method and the planar frictional contact LCP (see lcp.h).
#include "threshing_sim/core/lcp.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace threshing_sim {
namespace {

using Index = Eigen::Index;
using Tableau = Eigen::Block<MatX>;

// Tableau entries below this fraction of their column's largest magnitude are treated as zero
// when choosing a pivot (guards against pivoting on round-off).
constexpr double kPivotTol = 1e-11;
// Two ratios (or two lexicographic entries) closer than this relative amount count as a tie.
constexpr double kTieTol = 1e-9;
// Final check: w = M z + q must satisfy w >= 0 and w_i = 0 where z_i > 0 to this fraction of
// the magnitude of the terms that make up w (pivoting round-off is far below it, a wrong basis
// far above it).
constexpr double kResidualTol = 1e-9;
// A pivot smaller than this fraction of its column's largest entry triggers a rebuild of the
// tableau from the data before it is used.
constexpr double kRefactorTol = 1e-6;

// Grows (never shrinks) scratch storage so that a later smaller problem reuses the memory.
void growTo(MatX* m, Index rows, Index cols) {
  if (m->rows() < rows || m->cols() < cols) {
    m->resize(std::max(m->rows(), rows), std::max(m->cols(), cols));
  }
}

void growTo(VecX* v, Index n) {
  if (v->size() < n) v->resize(n);
}

// Gauss-Jordan pivot on T(r, c): makes column c the unit vector e_r. col is scratch (size n).
void pivot(Tableau T, Index r, Index c, Eigen::Ref<VecX> col) {
  // Normalise the pivot row.
  T.row(r) /= T(r, c);
  // Subtract multiples of the pivot row from every other row, one contiguous column at a time.
  col = T.col(c);
  col(r) = 0;
  for (Index j = 0; j < T.cols(); ++j) {
    const double a = T(r, j);
    if (a != 0) T.col(j) -= a * col;
  }
}

// Lexicographic minimum-ratio test for entering column c of the tableau [B^-1 | B^-1 A | rhs]
// (the first n columns hold B^-1). Returns the leaving row, or -1 if no row blocks (a ray).
Index leavingRow(const Tableau& T, Index c, Index z0_row) {
  const Index n = T.rows();
  const Index rhs = T.cols() - 1;
  // Blocking rows have an entry above the column-relative pivot tolerance.
  const double dmax = T.col(c).cwiseAbs().maxCoeff();
  const double piv_tol = kPivotTol * dmax;
  // Minimum ratio; basic values that round-off made slightly negative count as zero.
  double theta = std::numeric_limits<double>::infinity();
  for (Index i = 0; i < n; ++i) {
    if (T(i, c) > piv_tol) theta = std::min(theta, std::max(T(i, rhs), 0.0) / T(i, c));
  }
  if (!std::isfinite(theta)) return -1;
  const double rscale = T.col(rhs).cwiseAbs().maxCoeff();
  const double ratio_tol = kTieTol * (theta + rscale / dmax);
  auto ties = [&](Index i) {
    return T(i, c) > piv_tol && std::max(T(i, rhs), 0.0) / T(i, c) <= theta + ratio_tol;
  };
  // If the artificial variable can leave, take it: that ends the algorithm.
  if (ties(z0_row)) return z0_row;
  // Among tied rows take the lexicographic minimum of (B^-1 row) / d; B^-1 is non-singular, so
  // this is unique in exact arithmetic and prevents cycling. Entries are compared with a
  // tolerance relative to their size plus the scale of B^-1 / d (computed only if needed).
  Index best = -1;
  double lex_scale = -1;
  for (Index i = 0; i < n; ++i) {
    if (!ties(i)) continue;
    if (best < 0) {
      best = i;
      continue;
    }
    if (lex_scale < 0) lex_scale = T.leftCols(n).cwiseAbs().maxCoeff() / dmax;
    for (Index j = 0; j < n; ++j) {
      const double a = T(i, j) / T(i, c);
      const double b = T(best, j) / T(best, c);
      if (std::abs(a - b) > kTieTol * (std::abs(a) + std::abs(b) + lex_scale)) {
        if (a < b) best = i;
        break;
      }
    }
  }
  return best;
}

// Fills the initial tableau [I, -M, -e, q] of w - M z - e z0 = q (all slacks w basic).
void fillTableau(Tableau T, const Eigen::Ref<const MatX>& M, const Eigen::Ref<const VecX>& q) {
  const Index n = q.size();
  T.leftCols(n).setIdentity();
  T.middleCols(n, n) = -M;
  T.col(2 * n).setConstant(-1);
  T.col(2 * n + 1) = q;
}

// Rebuilds the tableau of the current basis from the data by Gauss-Jordan elimination with
// partial pivoting (basic variable basis[k] ends up in row k, so rows keep their meaning),
// discarding the round-off that the pivots so far have accumulated. False if B is singular.
bool refactor(Tableau T, const Eigen::Ref<const MatX>& M, const Eigen::Ref<const VecX>& q,
              const std::vector<int>& basis, Eigen::Ref<VecX> col) {
  const Index n = q.size();
  fillTableau(T, M, q);
  for (Index k = 0; k < n; ++k) {
    const Index v = basis[k];
    Index r;
    if (T.col(v).tail(n - k).cwiseAbs().maxCoeff(&r) == 0) return false;
    T.row(k).swap(T.row(k + r));
    pivot(T, k, v, col);
  }
  return true;
}

// Reads z from a complementary basis (non-basic variables are zero) and verifies w = M z + q
// >= 0 and w_i = 0 where z_i > 0, relative to the size of the terms that make up w.
bool readSolution(const Tableau& T, const Eigen::Ref<const MatX>& M,
                  const Eigen::Ref<const VecX>& q, const std::vector<int>& basis,
                  Eigen::Ref<VecX> z, Eigen::Ref<VecX> w) {
  const Index n = q.size();
  z.setZero();
  for (Index i = 0; i < n; ++i) {
    if (basis[i] >= n && basis[i] < 2 * n) z(basis[i] - n) = std::max(T(i, 2 * n + 1), 0.0);
  }
  w.noalias() = M * z;
  w += q;
  double scale = 0;
  for (Index i = 0; i < n; ++i) {
    double s = std::abs(q(i));
    for (Index j = 0; j < n; ++j) s += std::abs(M(i, j)) * z(j);
    scale = std::max(scale, s);
  }
  const double tol = kResidualTol * scale;
  for (Index i = 0; i < n; ++i) {
    if (w(i) < -tol || (z(i) > 0 && w(i) > tol)) return false;
  }
  return true;
}

// Lemke's algorithm on views, so that the contact solver can pass blocks of its workspace.
// Variables are numbered w_0..w_{n-1}, z_0..z_{n-1}, z0 = 2n; tableau column j belongs to
// variable j and column 2n+1 holds the basic values.
LcpStatus lemkeStatus(const Eigen::Ref<const MatX>& M, const Eigen::Ref<const VecX>& q,
                      Eigen::Ref<VecX> z, LcpWorkspace* ws, int max_pivots, int* pivots) {
  const Index n = q.size();
  if (pivots) *pivots = 0;
  z.setZero();
  // Trivial solution: q >= 0 is solved by z = 0. A q that is negative only within the tie
  // tolerance counts as zero too: pivoting on it would make the basis infeasible by round-off.
  if (n == 0 || q.minCoeff() >= -kTieTol * q.cwiseAbs().maxCoeff()) return LcpStatus::kSolved;
  if (max_pivots <= 0) max_pivots = static_cast<int>(50 * (n + 1) + 100);
  const Index z0 = 2 * n;

  // Tableau with all slacks w basic.
  growTo(&ws->tableau, n, 2 * n + 2);
  growTo(&ws->v1, n);
  growTo(&ws->v2, n);
  Tableau T = ws->tableau.topLeftCorner(n, 2 * n + 2);
  auto col = ws->v1.head(n);
  auto w = ws->v2.head(n);
  fillTableau(T, M, q);
  std::vector<int>& basis = ws->basis;
  basis.resize(n);
  for (Index i = 0; i < n; ++i) basis[i] = static_cast<int>(i);

  // z0 enters at the most negative q_r, which makes every basic value non-negative; among
  // (near) ties the largest index keeps the rows lexicographically positive.
  const double q_min = q.minCoeff();
  const double q_tol = kTieTol * q.cwiseAbs().maxCoeff();
  Index r = 0;
  for (Index i = 0; i < n; ++i) {
    if (q(i) <= q_min + q_tol) r = i;
  }
  pivot(T, r, z0, col);
  const Index z0_row = r;         // z0 stays basic in this row until it leaves
  Index entering = n + basis[r];  // the complement of the slack w_r that left
  basis[r] = static_cast<int>(z0);
  int count = 1;

  // Complementary pivoting: the complement of the variable that just left enters, until z0
  // leaves (solution) or no row blocks the entering variable (ray termination). A ray or a
  // pivot that is small against its column may be an artefact of accumulated round-off, so
  // the tableau is then rebuilt from the data once and the step repeated.
  bool fresh = false;
  while (count < max_pivots) {
    r = leavingRow(T, entering, z0_row);
    const bool suspicious =
        r < 0 || std::abs(T(r, entering)) < kRefactorTol * T.col(entering).cwiseAbs().maxCoeff();
    if (suspicious && !fresh) {
      if (!refactor(T, M, q, basis, col)) {
        if (pivots) *pivots = count;
        return LcpStatus::kSingularBasis;
      }
      fresh = true;
      continue;
    }
    if (r < 0) {
      if (pivots) *pivots = count;
      return LcpStatus::kRayTermination;
    }
    pivot(T, r, entering, col);
    fresh = false;
    ++count;
    const Index leaving = basis[r];
    basis[r] = static_cast<int>(entering);
    if (leaving == z0) {
      if (pivots) *pivots = count;
      // Accept the solution if it verifies, else once more from a rebuilt tableau.
      if (readSolution(T, M, q, basis, z, w)) return LcpStatus::kSolved;
      if (!refactor(T, M, q, basis, col)) return LcpStatus::kSingularBasis;
      return readSolution(T, M, q, basis, z, w) ? LcpStatus::kSolved : LcpStatus::kUnverified;
    }
    entering = leaving < n ? leaving + n : leaving - n;
  }
  if (pivots) *pivots = count;
  return LcpStatus::kPivotLimit;
}

// lemkeStatus, its status kept in ws->status: true when solved.
bool lemke(const Eigen::Ref<const MatX>& M, const Eigen::Ref<const VecX>& q, Eigen::Ref<VecX> z,
           LcpWorkspace* ws, int max_pivots, int* pivots) {
  ws->status = lemkeStatus(M, q, z, ws, max_pivots, pivots);
  return ws->status == LcpStatus::kSolved;
}

// Tangential force per unit normal force imposed on a contact that slides with a known sign.
double slipCoefficient(const ContactRow& row) {
  return row.slip_sign == 0 ? 0.0 : -(row.slip_sign > 0 ? 1.0 : -1.0) * row.mu;
}

}  // namespace

const char* toString(LcpStatus status) {
  switch (status) {
    case LcpStatus::kSolved:
      return "solved";
    case LcpStatus::kRayTermination:
      return "ray_termination";
    case LcpStatus::kPivotLimit:
      return "pivot_limit";
    case LcpStatus::kSingularBasis:
      return "singular_basis";
    case LcpStatus::kUnverified:
      return "unverified";
  }
  return "?";
}

bool solveLcpLemke(const MatX& M, const VecX& q, VecX* z, LcpWorkspace* ws, int max_pivots,
                   int* pivots) {
  z->resize(q.size());
  return lemke(M, q, *z, ws, max_pivots, pivots);
}

bool solveContactProblem(const MatX& G, const VecX& b, const std::vector<ContactRow>& rows,
                         VecX* lambda, VecX* y, LcpWorkspace* ws) {
  lambda->resize(2 * static_cast<Index>(rows.size()));
  y->resize(lambda->size());
  return solveContactProblem(Eigen::Ref<const MatX>(G), Eigen::Ref<const VecX>(b), rows,
                             Eigen::Ref<VecX>(*lambda), Eigen::Ref<VecX>(*y), ws);
}

namespace {

// Numbers the LCP unknowns contact by contact: idx[2i] is the normal unknown (-1: fixed),
// idx[2i+1] the first of the friction triple (lambda_T+, lambda_T-, beta) (-1: none). Friction
// is unknown only for mu > 0, no imposed slip sign and a normal that is not fixed at zero.
// Returns the number of unknowns.
int numberUnknowns(const std::vector<ContactRow>& rows, std::vector<int>* idx) {
  const Index k = static_cast<Index>(rows.size());
  idx->resize(2 * k);
  int m = 0;
  for (Index i = 0; i < k; ++i) {
    const ContactRow& row = rows[i];
    const bool friction =
        row.mu > 0 && row.slip_sign == 0 && (row.normal_unknown || row.lambda_n_fixed > 0);
    (*idx)[2 * i] = row.normal_unknown ? m++ : -1;
    (*idx)[2 * i + 1] = friction ? m : -1;
    if (friction) m += 3;
  }
  return m;
}

// The free values seen by the unknowns: ybar = G c + b, c the constant part of lambda from
// fixed normals (and the slip force they imply).
void freeValues(const Eigen::Ref<const MatX>& G, const Eigen::Ref<const VecX>& b,
                const std::vector<ContactRow>& rows, Eigen::Ref<VecX> ybar) {
  ybar = b;
  for (Index i = 0; i < static_cast<Index>(rows.size()); ++i) {
    if (rows[i].normal_unknown) continue;
    const double cn = rows[i].lambda_n_fixed;
    const double ct = slipCoefficient(rows[i]) * cn;
    if (cn != 0) ybar += cn * G.col(2 * i);
    if (ct != 0) ybar += ct * G.col(2 * i + 1);
  }
}

// Scale g of G: the slip-rate multiplier beta is replaced by g * beta' and its row multiplied
// by g, so every block of the LCP matrix has the magnitude of G and the relative tolerances of
// Lemke's method mean the same in every row and column (complementarity is unchanged).
double lcpScale(const Eigen::Ref<const MatX>& G) {
  double g = 0;
  for (Index i = 0; i < G.rows(); ++i) g = std::max(g, std::abs(G(i, i)));
  return g > 0 ? g : 1.0;
}

// Coupling blocks of the LCP matrix: row i holds w_N = y_N, w_T+ = y_T (+ g beta'), w_T- =
// -y_T (+ g beta'); column j moves lambda_Nj (and lambda_Tj = a_j lambda_Nj when j slides with
// a known sign) or lambda_Tj = lambda_T+ - lambda_T-.
void fillCoupling(const Eigen::Ref<const MatX>& G, const std::vector<ContactRow>& rows,
                  const std::vector<int>& idx, Eigen::Ref<MatX> M) {
  const Index k = static_cast<Index>(rows.size());
  for (Index i = 0; i < k; ++i) {
    const int ni = idx[2 * i];
    const int ti = idx[2 * i + 1];
    if (ni < 0 && ti < 0) continue;
    for (Index j = 0; j < k; ++j) {
      const int nj = idx[2 * j];
      const int tj = idx[2 * j + 1];
      const double gnn = G(2 * i, 2 * j), gnt = G(2 * i, 2 * j + 1);
      const double gtn = G(2 * i + 1, 2 * j), gtt = G(2 * i + 1, 2 * j + 1);
      if (nj >= 0) {
        const double aj = slipCoefficient(rows[j]);
        if (ni >= 0) M(ni, nj) = gnn + aj * gnt;
        if (ti >= 0) {
          M(ti, nj) = gtn + aj * gtt;
          M(ti + 1, nj) = -M(ti, nj);
        }
      }
      if (tj >= 0) {
        if (ni >= 0) {
          M(ni, tj) = gnt;
          M(ni, tj + 1) = -gnt;
        }
        if (ti >= 0) {
          M(ti, tj) = gtt;
          M(ti, tj + 1) = -gtt;
          M(ti + 1, tj) = -gtt;
          M(ti + 1, tj + 1) = gtt;
        }
      }
    }
  }
}

// Per contact: the slip-rate terms, the friction-cone row g (mu lambda_N - lambda_T+ -
// lambda_T-) and the free values q. No diagonal regularisation is added: the LCP is solvable
// as it stands (Anitescu-Potra; b in the range of W^T for a singular G), and an epsilon on the
// diagonal would create pivots below any safe pivot tolerance.
void fillFrictionRows(const std::vector<ContactRow>& rows, const std::vector<int>& idx,
                      const Eigen::Ref<const VecX>& ybar, double g, Eigen::Ref<MatX> M,
                      Eigen::Ref<VecX> q) {
  for (Index i = 0; i < static_cast<Index>(rows.size()); ++i) {
    const int ni = idx[2 * i];
    const int ti = idx[2 * i + 1];
    if (ni >= 0) q(ni) = ybar(2 * i);
    if (ti < 0) continue;
    const double mu = rows[i].mu;
    M(ti, ti + 2) = g;
    M(ti + 1, ti + 2) = g;
    M(ti + 2, ti) = -g;
    M(ti + 2, ti + 1) = -g;
    if (ni >= 0) M(ti + 2, ni) = g * mu;
    q(ti) = ybar(2 * i + 1);
    q(ti + 1) = -ybar(2 * i + 1);
    q(ti + 2) = ni >= 0 ? 0.0 : g * mu * rows[i].lambda_n_fixed;
  }
}

// The unknowns x mapped back to lambda (lambda_T+ and lambda_T- may both be positive; only
// their difference matters), round-off outside the friction cone clipped.
void mapBack(const std::vector<ContactRow>& rows, const std::vector<int>& idx,
             const Eigen::Ref<const VecX>& x, Eigen::Ref<VecX> lambda) {
  for (Index i = 0; i < static_cast<Index>(rows.size()); ++i) {
    const int ni = idx[2 * i];
    const int ti = idx[2 * i + 1];
    const double ln = ni >= 0 ? x(ni) : rows[i].lambda_n_fixed;
    double lt = slipCoefficient(rows[i]) * ln;
    if (ti >= 0) lt = std::clamp(x(ti) - x(ti + 1), -rows[i].mu * ln, rows[i].mu * ln);
    lambda(2 * i) = ln;
    lambda(2 * i + 1) = lt;
  }
}

}  // namespace

bool solveContactProblem(const Eigen::Ref<const MatX>& G, const Eigen::Ref<const VecX>& b,
                         const std::vector<ContactRow>& rows, Eigen::Ref<VecX> lambda,
                         Eigen::Ref<VecX> y, LcpWorkspace* ws) {
  const Index k = static_cast<Index>(rows.size());
  const int m = numberUnknowns(rows, &ws->ivec);
  growTo(&ws->w, 2 * k);
  auto ybar = ws->w.head(2 * k);
  freeValues(G, b, rows, ybar);
  const double g = lcpScale(G.topLeftCorner(2 * k, 2 * k));
  growTo(&ws->M, m, m);
  growTo(&ws->q, m);
  growTo(&ws->z, m);
  auto M = ws->M.topLeftCorner(m, m);
  auto q = ws->q.head(m);
  auto x = ws->z.head(m);
  M.setZero();
  fillCoupling(G, rows, ws->ivec, M);
  fillFrictionRows(rows, ws->ivec, ybar, g, M, q);
  // Solve (nothing to solve leaves only the constant part of lambda).
  ws->status = LcpStatus::kSolved;
  if (m > 0 && !lemke(M, q, x, ws, 0, nullptr)) return false;
  mapBack(rows, ws->ivec, x, lambda);
  y.noalias() = G * lambda;
  y += b;
  return true;
}

}  // namespace threshing_sim
