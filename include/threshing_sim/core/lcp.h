// threshing_sim core: linear complementarity solvers for planar frictional contact.
#pragma once

#include <cstdint>
#include <vector>

#include "threshing_sim/core/model.h"

namespace threshing_sim {

// How the last solve ended (LcpWorkspace::status).
enum class LcpStatus : std::uint8_t {
  kSolved = 0,          // a solution, verified against w = M z + q
  kRayTermination = 1,  // no row blocks the entering variable (no solution found on this path)
  kPivotLimit = 2,      // max_pivots complementary pivots without z0 leaving
  kSingularBasis = 3,   // the tableau could not be rebuilt from the data (singular basis)
  kUnverified = 4,      // z0 left, but the solution failed its check even after a rebuild
};

// "solved", "ray_termination", ... (stable names, for logs and tests).
const char* toString(LcpStatus status);

// Scratch memory for the solvers; reused across calls so that no heap allocation happens once
// it has grown to the largest problem size seen.
struct LcpWorkspace {
  MatX tableau;
  VecX v1, v2, v3;
  std::vector<int> basis, ivec;
  MatX M;
  VecX q, z, w;
  LcpStatus status = LcpStatus::kSolved;  // how the last solve ended
};

// Lemke's complementary pivoting: finds z with w = M z + q, w >= 0, z >= 0, w.z = 0.
// Returns false on ray termination or when max_pivots is exceeded (z is then unspecified);
// ws->status says which. Pivots in the number of pivots performed (may be null).
bool solveLcpLemke(const MatX& M, const VecX& q, VecX* z, LcpWorkspace* ws, int max_pivots = 0,
                   int* pivots = nullptr);

// One contact of a planar frictional contact problem.
struct ContactRow {
  bool normal_unknown = true;  // true: 0 <= lambda_N  _|_  y_N >= 0;  false: lambda_N is fixed
  double lambda_n_fixed = 0;   // the fixed normal value when !normal_unknown (>= 0)
  double mu = 0;               // Coulomb coefficient (0 = frictionless)
  int slip_sign = 0;           // 0: friction complementary (stick or slip chosen by the solution);
                               // +1/-1: the contact slides with y_T of that sign and
                               // lambda_T = -slip_sign mu lambda_N is imposed
};

// Solves for lambda (size 2k, ordered [N_0, T_0, N_1, T_1, ...]) such that y = G lambda + b
// satisfies, for each contact i:
//   normal:   if normal_unknown: 0 <= lambda_N _|_ y_N >= 0; else lambda_N = lambda_n_fixed
//   friction: if slip_sign == 0: |lambda_T| <= mu lambda_N, and lambda_T y_T <= 0 with
//             y_T = 0 whenever |lambda_T| < mu lambda_N (stick), |lambda_T| = mu lambda_N
//             otherwise (slip against y_T); if slip_sign != 0: lambda_T = -slip_sign mu lambda_N.
// G is the 2k x 2k Delassus matrix W^T M^-1 W (symmetric positive semi-definite), b the free
// values (velocities or accelerations, with any restitution target added to the normal rows).
// Solved exactly as one LCP (Anitescu-Potra split of the friction cone) by Lemke's method.
// Returns false if Lemke fails (ray termination, e.g. the Painleve case at acceleration level;
// ws->status says how).
bool solveContactProblem(const MatX& G, const VecX& b, const std::vector<ContactRow>& rows,
                         VecX* lambda, VecX* y, LcpWorkspace* ws);
// The same on views (blocks of larger scratch storage); lambda and y must have size 2k. No heap
// allocation once ws has grown to the problem size.
bool solveContactProblem(const Eigen::Ref<const MatX>& G, const Eigen::Ref<const VecX>& b,
                         const std::vector<ContactRow>& rows, Eigen::Ref<VecX> lambda,
                         Eigen::Ref<VecX> y, LcpWorkspace* ws);

}  // namespace threshing_sim
