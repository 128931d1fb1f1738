// threshing_sim core, private: the contact solve, one frictional complementarity problem per
// island of bodies coupled through contacts, and the generalised inverse mass it is built from
// (src/core/contact/contact_solve.cc).
#pragma once

#include <vector>

#include "../small_vec.h"
#include "threshing_sim/core/data.h"
#include "threshing_sim/core/lcp.h"
#include "threshing_sim/core/model.h"

namespace threshing_sim {
namespace internal {

// The island decomposition and the per-island problem of the contact solve
// (Workspace::solve). Its inputs and outputs (active, rows, b, lambda, y) are the Workspace's.
struct ContactSolveScratch {
  std::vector<int> island_of_body;         // island root of each active contact's kernel [-]
  std::vector<int> island_contacts;        // active contacts ordered by island [-]
  std::vector<int> island_parent;          // union-find over the bodies [-]
  MatX G_island;                           // Delassus matrix of one island [1/kg or mixed]
  VecX b_island, lambda_island, y_island;  // its right-hand side [m/s], impulses or forces
                                           // [N s or N] and velocities [m/s]
  std::vector<ContactRow> rows_island;     // its contact rows
  LcpWorkspace lcp;                        // the LCP solver's scratch
};

// Generalised inverse mass per body: teeth use tooth_minv[k] if given (time stepping's
// iteration matrix inverse) or the identity (mass-normalised modes); kernels diag(1/m,1/m,1/J).
// out += Minv_body * v for the body's block.
void applyInverseMass(const Model& m, const std::vector<MatX>* tooth_minv, int body,
                      const SmallVec& v, double scale, VecX* out);

// The free accelerations a = Minv f of the whole system (mass-normalised tooth modes: the
// identity; a large-deflection tooth: its tooth_minv block; kernels diag(1/m, 1/m, 1/J)),
// computed as applyInverseMass on a zero vector would, so that the two agree bit for bit.
void freeAcceleration(const Model& m, const std::vector<MatX>* tooth_minv, const VecX& f, VecX* a);
// w1^T Minv_body w2 for two Jacobian rows of the same body (Minv as in applyInverseMass).
double weightedDot(const Model& m, const std::vector<MatX>* tooth_minv, int body,
                   const SmallVec& w1, const SmallVec& w2);

// Solves one frictional contact problem per island (bodies coupled through contacts) for the
// contacts ws->active (indices into ws->geoms), with ws->rows and ws->b (2 per active contact,
// [N, T]) already filled. Fills ws->lambda and ws->y (same layout). Returns false if any
// island's LCP failed (its lambda is then zero).
bool solveContactIslands(const Model& m, const std::vector<MatX>* tooth_minv, Workspace* ws);

}  // namespace internal
}  // namespace threshing_sim
