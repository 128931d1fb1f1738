// Tests for Lemke's method and the planar frictional contact LCP (threshing_sim/core/lcp.h).
#include <gtest/gtest.h>

#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>
#include <random>
#include <sstream>
#include <vector>

#include "threshing_sim/core/lcp.h"

namespace threshing_sim {
namespace {

// Complementarity residuals are compared with this fraction of the magnitude of the terms that
// form them: Lemke's pivots on these well-conditioned problems leave errors near 1e-14, while a
// wrong active set gives errors of order one.
constexpr double kRelTol = 1e-9;

MatX randomMatrix(int rows, int cols, std::mt19937* rng) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  MatX A(rows, cols);
  for (int j = 0; j < cols; ++j) {
    for (int i = 0; i < rows; ++i) A(i, j) = u(*rng);
  }
  return A;
}

// Symmetric positive definite with eigenvalues in about [0.1, 1.5] (condition number <= 15).
MatX randomSpd(int n, std::mt19937* rng) {
  const MatX A = randomMatrix(n, n, rng);
  return A * A.transpose() / n + 0.1 * MatX::Identity(n, n);
}

// Checks w = M z + q >= 0, z >= 0 and w_i z_i = 0, relative to the size of the terms of w.
::testing::AssertionResult isLcpSolution(const MatX& M, const VecX& q, const VecX& z) {
  const VecX w = M * z + q;
  const double tol = kRelTol * (q.cwiseAbs().maxCoeff() + (M.cwiseAbs() * z.cwiseAbs()).maxCoeff());
  for (int i = 0; i < q.size(); ++i) {
    if (z(i) < 0 || w(i) < -tol || std::min(z(i), w(i)) > tol) {
      return ::testing::AssertionFailure()
             << "row " << i << ": z = " << z(i) << ", w = " << w(i) << " (tol " << tol << ")";
    }
  }
  return ::testing::AssertionSuccess();
}

// Enumerates all 2^n complementary bases (z_i basic for i in the subset); returns the number of
// solutions found and the last one in *z.
int bruteForceLcp(const MatX& M, const VecX& q, VecX* z) {
  const int n = static_cast<int>(q.size());
  int found = 0;
  for (unsigned mask = 0; mask < (1u << n); ++mask) {
    std::vector<int> act;
    for (int i = 0; i < n; ++i) {
      if (mask & (1u << i)) act.push_back(i);
    }
    const int a = static_cast<int>(act.size());
    MatX Maa(a, a);
    VecX qa(a);
    for (int r = 0; r < a; ++r) {
      qa(r) = q(act[r]);
      for (int c = 0; c < a; ++c) Maa(r, c) = M(act[r], act[c]);
    }
    VecX cand = VecX::Zero(n);
    const VecX za = Maa.llt().solve(-qa);
    for (int r = 0; r < a; ++r) cand(act[r]) = za(r);
    const VecX w = M * cand + q;
    if (cand.minCoeff() >= -1e-12 && w.minCoeff() >= -1e-12) {
      ++found;
      *z = cand;
    }
  }
  return found;
}

// Checks every condition of lcp.h's comment on solveContactProblem. Forces are compared with
// kRelTol times the largest force (at least 1), y with kRelTol times the size of the terms of
// G lambda + b.
::testing::AssertionResult isContactSolution(const MatX& G, const VecX& b,
                                             const std::vector<ContactRow>& rows,
                                             const VecX& lambda, const VecX& y) {
  const int k = static_cast<int>(rows.size());
  if (lambda.size() != 2 * k || y.size() != 2 * k) {
    return ::testing::AssertionFailure() << "wrong output sizes";
  }
  const double tol_l = kRelTol * std::max(1.0, lambda.cwiseAbs().maxCoeff());
  const double tol_y =
      kRelTol * (b.cwiseAbs().maxCoeff() + (G.cwiseAbs() * lambda.cwiseAbs()).maxCoeff());
  if ((G * lambda + b - y).cwiseAbs().maxCoeff() > tol_y) {
    return ::testing::AssertionFailure() << "y != G lambda + b";
  }
  for (int i = 0; i < k; ++i) {
    const ContactRow& r = rows[i];
    const double ln = lambda(2 * i), lt = lambda(2 * i + 1);
    const double yn = y(2 * i), yt = y(2 * i + 1);
    std::ostringstream where;
    where << "contact " << i << ": lambda = (" << ln << ", " << lt << "), y = (" << yn << ", " << yt
          << ")";
    // Normal: Signorini, or the fixed value.
    if (r.normal_unknown) {
      if (ln < -tol_l || yn < -tol_y || (ln > tol_l && std::abs(yn) > tol_y)) {
        return ::testing::AssertionFailure() << where.str() << ": normal complementarity";
      }
    } else if (std::abs(ln - r.lambda_n_fixed) > tol_l) {
      return ::testing::AssertionFailure() << where.str() << ": fixed normal changed";
    }
    // Friction: imposed slip force, or Coulomb's cone with stick / slip against y_T.
    if (r.slip_sign != 0) {
      if (std::abs(lt + r.slip_sign * r.mu * ln) > tol_l) {
        return ::testing::AssertionFailure() << where.str() << ": imposed slip force";
      }
      continue;
    }
    const double limit = r.mu * ln;
    if (std::abs(lt) > limit + tol_l) {
      return ::testing::AssertionFailure() << where.str() << ": outside the friction cone";
    }
    if (std::abs(yt) > tol_y && lt * yt > 0) {
      return ::testing::AssertionFailure() << where.str() << ": friction does not oppose y_T";
    }
    if (std::abs(lt) < limit - tol_l && std::abs(yt) > tol_y) {
      return ::testing::AssertionFailure() << where.str() << ": inside the cone but sliding";
    }
  }
  return ::testing::AssertionSuccess();
}

// ---------------------------------------------------------------- Lemke

TEST(Lemke, TrivialSolutionWhenQNonNegative) {
  LcpWorkspace ws;
  const MatX M = MatX::Identity(3, 3);
  const VecX q = (VecX(3) << 1.0, 0.0, 2.0).finished();
  VecX z;
  int pivots = -1;
  ASSERT_TRUE(solveLcpLemke(M, q, &z, &ws, 0, &pivots));
  EXPECT_EQ(pivots, 0);
  EXPECT_EQ(z, VecX::Zero(3));
}

TEST(Lemke, RandomSpdSatisfiesComplementarity) {
  std::mt19937 rng(12345);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  LcpWorkspace ws;
  for (int n = 1; n <= 30; ++n) {
    for (int trial = 0; trial < 10; ++trial) {
      const MatX M = randomSpd(n, &rng);
      const VecX q = VecX::NullaryExpr(n, [&]() { return u(rng); });
      VecX z;
      int pivots = 0;
      ASSERT_TRUE(solveLcpLemke(M, q, &z, &ws, 0, &pivots)) << "n = " << n;
      EXPECT_TRUE(isLcpSolution(M, q, z)) << "n = " << n;
      // Lemke's worst case is exponential (Murty), but random well-conditioned SPD problems
      // take at most n + 2 pivots here; 2n + 1 flags a regression such as degenerate stalling.
      EXPECT_LE(pivots, 2 * n + 1);
    }
  }
}

TEST(Lemke, MatchesBruteForceEnumeration) {
  std::mt19937 rng(777);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  LcpWorkspace ws;
  for (int n = 1; n <= 10; ++n) {
    for (int trial = 0; trial < 5; ++trial) {
      const MatX M = randomSpd(n, &rng);
      const VecX q = VecX::NullaryExpr(n, [&]() { return u(rng); });
      VecX z, z_ref;
      ASSERT_TRUE(solveLcpLemke(M, q, &z, &ws));
      // An SPD matrix is a P-matrix: exactly one complementary basis is feasible.
      ASSERT_EQ(bruteForceLcp(M, q, &z_ref), 1);
      // |z| <= |q| / lambda_min(M) ~ 10 and cond(M) <= 15, so 1e-11 is ~100x round-off.
      EXPECT_LT((z - z_ref).cwiseAbs().maxCoeff(), 1e-11) << "n = " << n;
    }
  }
}

TEST(Lemke, DegenerateProblemsTerminate) {
  LcpWorkspace ws;
  VecX z;
  // All rows identical (n coincident contacts) with equal q: every ratio test is a tie.
  for (int n = 1; n <= 12; ++n) {
    const MatX M = MatX::Ones(n, n);
    const VecX q = -VecX::Ones(n);
    ASSERT_TRUE(solveLcpLemke(M, q, &z, &ws)) << "n = " << n;
    EXPECT_TRUE(isLcpSolution(M, q, z));
    EXPECT_NEAR(z.sum(), 1.0, 1e-12);  // the total is determined; O(1) round-off only
  }
  // Duplicated rows and columns of an SPD matrix (a PSD matrix of half rank) with zeros in q.
  std::mt19937 rng(99);
  for (int trial = 0; trial < 50; ++trial) {
    const MatX S = randomSpd(3, &rng);
    MatX P = MatX::Zero(6, 3);
    for (int i = 0; i < 6; ++i) P(i, i % 3) = 1;
    const MatX M = P * S * P.transpose();
    VecX q = P * (VecX(3) << -1.0, 0.0, 0.5 * (trial % 3) - 0.5).finished();
    q(4) = 0;
    ASSERT_TRUE(solveLcpLemke(M, q, &z, &ws)) << "trial " << trial;
    EXPECT_TRUE(isLcpSolution(M, q, z));
  }
}

TEST(Lemke, InfeasibleProblemReturnsFalse) {
  LcpWorkspace ws;
  VecX z;
  // w = -z - 1 < 0 for every z >= 0.
  EXPECT_FALSE(solveLcpLemke(MatX::Constant(1, 1, -1.0), VecX::Constant(1, -1.0), &z, &ws));
  EXPECT_EQ(ws.status, LcpStatus::kRayTermination) << toString(ws.status);
  const MatX M = (MatX(2, 2) << -1.0, 0.5, 0.5, -1.0).finished();
  const VecX q = (VecX(2) << -1.0, -2.0).finished();
  EXPECT_FALSE(solveLcpLemke(M, q, &z, &ws));
  EXPECT_EQ(ws.status, LcpStatus::kRayTermination) << toString(ws.status);
}

TEST(Lemke, StatusTellsThePivotLimitFromARayAndFromASolution) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  LcpWorkspace ws;
  VecX z;
  const MatX M = randomSpd(12, &rng);
  const VecX q = VecX::NullaryExpr(12, [&]() { return -1.0 + 0.1 * u(rng); });  // all negative
  int pivots = 0;
  ASSERT_TRUE(solveLcpLemke(M, q, &z, &ws, 0, &pivots));
  EXPECT_EQ(ws.status, LcpStatus::kSolved);
  ASSERT_GT(pivots, 2);
  // The same problem with fewer pivots allowed than it needs stops on the limit.
  EXPECT_FALSE(solveLcpLemke(M, q, &z, &ws, pivots - 1));
  EXPECT_EQ(ws.status, LcpStatus::kPivotLimit) << toString(ws.status);
  EXPECT_STREQ(toString(LcpStatus::kPivotLimit), "pivot_limit");
}

TEST(Lemke, WorkspaceIsReusedWithoutReallocation) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  LcpWorkspace ws;
  VecX z;
  const MatX big = randomSpd(20, &rng);
  const VecX q_big = VecX::NullaryExpr(20, [&]() { return u(rng); });
  ASSERT_TRUE(solveLcpLemke(big, q_big, &z, &ws));
  const VecX z_first = z;
  const double* tableau = ws.tableau.data();
  const int* basis = ws.basis.data();
  // A smaller problem reuses the grown storage; the big one then gives the same answer.
  const MatX small = randomSpd(7, &rng);
  const VecX q_small = VecX::NullaryExpr(7, [&]() { return u(rng); });
  ASSERT_TRUE(solveLcpLemke(small, q_small, &z, &ws));
  ASSERT_TRUE(solveLcpLemke(big, q_big, &z, &ws));
  EXPECT_EQ(ws.tableau.data(), tableau);
  EXPECT_EQ(ws.basis.data(), basis);
  EXPECT_EQ(z, z_first);
}

// ---------------------------------------------------------------- one contact, G = I

// Unit-mass particle on a plane at velocity level: G = I, b = free velocity (v_N, v_T).
struct ParticleResult {
  bool ok;
  VecX lambda, y;
};

ParticleResult solveParticle(double b_n, double b_t, const ContactRow& row) {
  LcpWorkspace ws;
  ParticleResult r;
  const VecX b = (VecX(2) << b_n, b_t).finished();
  r.ok = solveContactProblem(MatX::Identity(2, 2), b, {row}, &r.lambda, &r.y, &ws);
  if (r.ok) {
    EXPECT_TRUE(isContactSolution(MatX::Identity(2, 2), b, {row}, r.lambda, r.y));
  }
  return r;
}

// Absolute tolerance for the O(1) particle problems: a few pivots leave round-off near 1e-16.
constexpr double kParticleTol = 1e-10;

TEST(ContactParticle, SticksForSmallTangentialSpeed) {
  ContactRow row;
  row.mu = 0.5;
  for (double vt : {0.3, -0.3, 0.0}) {
    const ParticleResult r = solveParticle(-1.0, vt, row);
    ASSERT_TRUE(r.ok);
    EXPECT_NEAR(r.lambda(0), 1.0, kParticleTol);
    EXPECT_NEAR(r.lambda(1), -vt, kParticleTol);
    EXPECT_NEAR(r.y(0), 0.0, kParticleTol);
    EXPECT_NEAR(r.y(1), 0.0, kParticleTol);
  }
}

TEST(ContactParticle, SlipsForLargeTangentialSpeed) {
  ContactRow row;
  row.mu = 0.5;
  for (double vt : {2.0, -2.0}) {
    const ParticleResult r = solveParticle(-1.0, vt, row);
    ASSERT_TRUE(r.ok);
    const double s = vt > 0 ? 1.0 : -1.0;
    EXPECT_NEAR(r.lambda(0), 1.0, kParticleTol);
    EXPECT_NEAR(r.lambda(1), -0.5 * s, kParticleTol);
    EXPECT_NEAR(r.y(0), 0.0, kParticleTol);
    EXPECT_NEAR(r.y(1), 1.5 * s, kParticleTol);  // same sign, reduced by mu lambda_N
  }
}

TEST(ContactParticle, SeparatingGivesZeroImpulse) {
  ContactRow row;
  row.mu = 0.5;
  const ParticleResult r = solveParticle(0.7, 3.0, row);
  ASSERT_TRUE(r.ok);
  EXPECT_EQ(r.lambda, VecX::Zero(2));
  EXPECT_EQ(r.y, (VecX(2) << 0.7, 3.0).finished());
}

TEST(ContactParticle, NormalRowWorksWithArbitraryFreeValue) {
  // b_N may hold any target (e.g. v_N + e v_N^-); the normal row enforces y_N >= 0 _|_ lambda_N.
  for (const ContactRow row : {ContactRow{true, 0, 0.0, 0}, ContactRow{true, 0, 0.4, 0}}) {
    for (double bn : {-3.0, -0.25, -1e-9, 0.0, 1e-9, 2.0}) {
      const ParticleResult r = solveParticle(bn, 0.0, row);
      ASSERT_TRUE(r.ok);
      EXPECT_NEAR(r.lambda(0), std::max(-bn, 0.0), kParticleTol) << "b_N = " << bn;
      EXPECT_NEAR(r.y(0), std::max(bn, 0.0), kParticleTol) << "b_N = " << bn;
    }
  }
}

TEST(ContactParticle, FrictionlessTangentialRowIsOutputOnly) {
  const ParticleResult r = solveParticle(-1.0, 0.8, ContactRow{});
  ASSERT_TRUE(r.ok);
  EXPECT_EQ(r.lambda(1), 0.0);
  EXPECT_NEAR(r.y(1), 0.8, kParticleTol);
}

TEST(ContactParticle, ImposedSlipSign) {
  for (int sign : {1, -1}) {
    ContactRow row;
    row.mu = 0.3;
    row.slip_sign = sign;
    const ParticleResult r = solveParticle(-2.0, 0.1 * sign, row);
    ASSERT_TRUE(r.ok);
    EXPECT_NEAR(r.lambda(0), 2.0, kParticleTol);
    EXPECT_EQ(r.lambda(1), -sign * 0.3 * r.lambda(0));  // substituted, so exact
  }
}

TEST(ContactParticle, FixedNormalStickAndSlip) {
  ContactRow row;
  row.normal_unknown = false;
  row.lambda_n_fixed = 2.0;
  row.mu = 0.25;  // friction limit 0.5
  // Stick: the needed tangential force 0.3 is inside the limit.
  ParticleResult r = solveParticle(0.1, -0.3, row);
  ASSERT_TRUE(r.ok);
  EXPECT_EQ(r.lambda(0), 2.0);
  EXPECT_NEAR(r.lambda(1), 0.3, kParticleTol);
  EXPECT_LT(std::abs(r.lambda(1)), 0.5);
  EXPECT_NEAR(r.y(1), 0.0, kParticleTol);
  // Slip: the limit is reached, y_T keeps its sign.
  r = solveParticle(0.1, -1.0, row);
  ASSERT_TRUE(r.ok);
  EXPECT_NEAR(r.lambda(1), 0.5, kParticleTol);
  EXPECT_NEAR(r.y(1), -0.5, kParticleTol);
  // A fixed normal of zero allows no friction.
  row.lambda_n_fixed = 0;
  r = solveParticle(0.1, -1.0, row);
  ASSERT_TRUE(r.ok);
  EXPECT_EQ(r.lambda, VecX::Zero(2));
  // Fixed normal with an imposed slip sign: everything is known, y = G lambda + b.
  row.lambda_n_fixed = 2.0;
  row.slip_sign = -1;
  r = solveParticle(0.1, -1.0, row);
  ASSERT_TRUE(r.ok);
  EXPECT_EQ(r.lambda(1), 0.5);
  EXPECT_NEAR(r.y(1), -0.5, kParticleTol);
}

TEST(ContactParticle, NoUnknownsGivesFreeValues) {
  LcpWorkspace ws;
  const MatX G = (MatX(2, 2) << 2.0, 0.5, 0.5, 1.0).finished();
  const VecX b = (VecX(2) << -1.0, 0.3).finished();
  ContactRow row;
  row.normal_unknown = false;  // fixed at zero, frictionless
  VecX lambda, y;
  ASSERT_TRUE(solveContactProblem(G, b, {row}, &lambda, &y, &ws));
  EXPECT_EQ(lambda, VecX::Zero(2));
  EXPECT_EQ(y, b);
  ASSERT_TRUE(solveContactProblem(MatX(0, 0), VecX(0), {}, &lambda, &y, &ws));
  EXPECT_EQ(lambda.size(), 0);
}

// ---------------------------------------------------------------- coupled contacts

// Jacobian column of a contact direction d acting at point p (relative to the body's centre)
// of a planar rigid body with coordinates (x, y, theta).
Eigen::Vector3d jacobianColumn(const Vec2& d, const Vec2& p) {
  return Eigen::Vector3d(d.x(), d.y(), p.x() * d.y() - p.y() * d.x());
}

// A disk of radius r touching planes with the given inward normals; W columns [N_i, T_i].
MatX diskJacobian(double r, const std::vector<Vec2>& normals) {
  MatX W(3, 2 * normals.size());
  for (size_t i = 0; i < normals.size(); ++i) {
    const Vec2 n = normals[i].normalized();
    const Vec2 t(-n.y(), n.x());
    const Vec2 p = -r * n;
    W.col(2 * i) = jacobianColumn(n, p);
    W.col(2 * i + 1) = jacobianColumn(t, p);
  }
  return W;
}

TEST(ContactCoupled, DiskInCornerIsOrderIndependent) {
  const double m = 2.0, r = 0.5, J = 0.5 * m * r * r;
  const Eigen::Vector3d m_inv(1 / m, 1 / m, 1 / J);
  // Floor and a wall inclined at 60 degrees: the normals are independent.
  const std::vector<Vec2> normals = {Vec2(0, 1),
                                     Vec2(std::cos(EIGEN_PI / 3), std::sin(EIGEN_PI / 3))};
  const MatX W = diskJacobian(r, normals);
  const MatX G = W.transpose() * m_inv.asDiagonal() * W;
  // Free velocities (vx, vy, omega) and friction coefficients. Each case has a unique solution
  // because no two contacts stick at once (a sticking pair admits the squeeze mode W lambda = 0
  // inside both friction cones).
  struct Case {
    Eigen::Vector3d u;
    double mu0, mu1;
  };
  const std::vector<Case> cases = {
      {{-1.0, -2.0, 0.0}, 0.0, 0.0},   // frictionless, both contacts active
      {{-1.0, -2.0, 3.0}, 0.0, 0.0},   // frictionless, both active, spin unchanged
      {{-1.0, -3.0, -8.0}, 0.3, 0.3},  // both active and sliding
      {{-1.0, -2.0, 8.0}, 0.3, 0.1},   // floor separates, wall slides
      {{-3.0, -1.0, 5.0}, 0.2, 0.1},   // floor separates, wall sticks
      {{0.5, -2.0, -4.0}, 0.3, 0.0}};  // floor sticks, wall separates
  LcpWorkspace ws;
  for (const Case& c : cases) {
    const VecX b = W.transpose() * c.u;
    std::vector<ContactRow> rows(2);
    rows[0].mu = c.mu0;
    rows[1].mu = c.mu1;
    VecX lambda, y;
    ASSERT_TRUE(solveContactProblem(G, b, rows, &lambda, &y, &ws));
    EXPECT_TRUE(isContactSolution(G, b, rows, lambda, y));
    EXPECT_GT(lambda(0) + lambda(2), 0.0);  // the disk is pushed out of the corner
    // Same problem with the contacts listed in the other order.
    Eigen::PermutationMatrix<Eigen::Dynamic> P(4);
    P.indices() << 2, 3, 0, 1;
    const MatX Gp = P.transpose() * G * P;
    const VecX bp = P.transpose() * b;
    const std::vector<ContactRow> rows_p = {rows[1], rows[0]};
    VecX lambda_p, y_p;
    ASSERT_TRUE(solveContactProblem(Gp, bp, rows_p, &lambda_p, &y_p, &ws));
    // The unique solution, reached along another pivot path: equal up to round-off (|lambda|~1).
    EXPECT_LT((P * lambda_p - lambda).cwiseAbs().maxCoeff(), 1e-12);
  }
}

TEST(ContactCoupled, CoincidentContactsShareTheImpulse) {
  // A unit-mass particle with four contacts of identical geometry: G is singular (rank 2) and
  // every ratio test ties. The total impulse must equal the single-contact answer, in slip
  // (v_T = 1.5) and in stick (v_T = 0.2); mu = 0.5, v_N = -1.
  const MatX W = MatX::Identity(2, 2).replicate(1, 4);
  const MatX G = W.transpose() * W;
  std::vector<ContactRow> rows(4);
  for (auto& row : rows) row.mu = 0.5;
  LcpWorkspace ws;
  for (double vt : {1.5, 0.2}) {
    const VecX b = W.transpose() * Vec2(-1.0, vt);
    VecX lambda, y;
    ASSERT_TRUE(solveContactProblem(G, b, rows, &lambda, &y, &ws));
    EXPECT_TRUE(isContactSolution(G, b, rows, lambda, y));
    // Only the total is determined (the split depends on the pivot path); O(1) values and a
    // handful of pivots leave round-off near 1e-16.
    const Vec2 total = W * lambda;
    EXPECT_NEAR(total(0), 1.0, 1e-12);
    EXPECT_NEAR(total(1), -std::min(vt, 0.5), 1e-12);
  }
}

TEST(ContactCoupled, OverconstrainedProblemsAreSolved) {
  // More contact rows than degrees of freedom (a kernel wedged between tooth and concave, many
  // contacts on one body): G is singular and the LCP degenerate. At velocity level b = W^T u is
  // in the range of W^T, so a solution exists (Anitescu-Potra) and must be found.
  std::mt19937 rng(31);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  LcpWorkspace ws;
  for (int trial = 0; trial < 600; ++trial) {
    const int ndof = 1 + trial % 6;
    const int k = 2 + trial % 11;
    const MatX W = randomMatrix(ndof, 2 * k, &rng);
    const MatX G = W.transpose() * randomSpd(ndof, &rng).llt().solve(W);
    const VecX b = W.transpose() * VecX::NullaryExpr(ndof, [&]() { return u(rng); });
    std::vector<ContactRow> rows(k);
    for (ContactRow& row : rows) {
      row.normal_unknown = u01(rng) < 0.85;
      row.lambda_n_fixed = row.normal_unknown ? 0.0 : u01(rng);
      row.mu = u01(rng) < 0.2 ? 0.0 : 1.5 * u01(rng);
    }
    VecX lambda, y;
    ASSERT_TRUE(solveContactProblem(G, b, rows, &lambda, &y, &ws)) << "trial " << trial;
    EXPECT_TRUE(isContactSolution(G, b, rows, lambda, y)) << "trial " << trial;
  }
}

TEST(ContactCoupled, RandomProblemsSatisfyCoulomb) {
  std::mt19937 rng(2024);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  LcpWorkspace ws;
  int solved = 0, solved_with_imposed_slip = 0;
  for (int trial = 0; trial < 400; ++trial) {
    const int k = 1 + trial % 8;
    const int ndof = 3 * k;
    // G = W^T M^-1 W for a random SPD mass matrix and a random contact Jacobian.
    const MatX W = randomMatrix(ndof, 2 * k, &rng);
    const MatX mass = randomSpd(ndof, &rng);
    const MatX G = W.transpose() * mass.llt().solve(W);
    const VecX b = 2.0 * VecX::NullaryExpr(2 * k, [&]() { return u(rng); });
    std::vector<ContactRow> rows(k);
    bool imposed_slip_on_unknown_normal = false;
    for (ContactRow& row : rows) {
      row.normal_unknown = u01(rng) < 0.8;
      row.lambda_n_fixed = row.normal_unknown ? 0.0 : (u01(rng) < 0.2 ? 0.0 : 2.0 * u01(rng));
      row.mu = u01(rng) < 0.2 ? 0.0 : 1.2 * u01(rng);
      const double s = u01(rng);
      row.slip_sign = s < 0.8 ? 0 : (s < 0.9 ? 1 : -1);
      if (row.slip_sign != 0 && row.normal_unknown) imposed_slip_on_unknown_normal = true;
    }
    VecX lambda, y;
    const bool ok = solveContactProblem(G, b, rows, &lambda, &y, &ws);
    // Without an imposed slip on an unknown normal the LCP is always solvable by Lemke
    // (Anitescu-Potra); with one it may have no solution (Painleve), and false is allowed.
    if (!imposed_slip_on_unknown_normal) {
      ASSERT_TRUE(ok) << "trial " << trial;
    }
    if (!ok) continue;
    ++solved;
    if (imposed_slip_on_unknown_normal) ++solved_with_imposed_slip;
    EXPECT_TRUE(isContactSolution(G, b, rows, lambda, y)) << "trial " << trial << ", k = " << k;
  }
  EXPECT_GT(solved_with_imposed_slip, 0);  // the imposed-slip path was actually exercised
  EXPECT_GE(solved, 300);
}

}  // namespace
}  // namespace threshing_sim
