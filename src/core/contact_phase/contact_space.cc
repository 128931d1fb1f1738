// The contact phase's contact space: the closed contacts' normal and slip velocities and their
// couplings through the bodies they share (the Delassus operator W = J M^-1 J^T of the rows, with
// the residual gradient's column), so that the normal and friction solves of one kick are
// Gauss-Seidel sweeps over a few scalars per contact; the velocity vector and the acceleration are
// changed once, when the solves are done.
#include "contact_phase.h"

namespace threshing_sim {
namespace internal {
namespace contact_phase {

using event_driven::Ctx;

namespace {

// The Jacobian of one side along direction e (0 normal, 1 tangent, 2 residual gradient).
const SmallVec& direction(const BodyJac& b, int e) {
  return e == 0 ? b.w_n : e == 1 ? b.w_t : b.w_r;
}

// The couplings of row j (contact gj) with row i (contact gi) over the bodies they share; false
// if they share none.
bool couple(const Model& m, const ContactGeom& gj, const ContactGeom& gi, int j, int i, MatX* W) {
  bool shared = false;
  for (int d = 0; d < 2; ++d)
    for (int e = 0; e < 3; ++e) (*W)(2 * j + d, 3 * i + e) = 0.0;
  for (const BodyJac& sj : gj.side) {
    if (sj.body < 0 || sj.w_n.size() == 0) continue;
    for (const BodyJac& si : gi.side) {
      if (si.body != sj.body || si.w_n.size() == 0) continue;
      shared = true;
      for (int d = 0; d < 2; ++d)
        for (int e = 0; e < 3; ++e) {
          const SmallVec& wi = direction(si, e);
          if (wi.size() == 0) continue;
          (*W)(2 * j + d, 3 * i + e) += weightedDot(m, nullptr, sj.body, direction(sj, d), wi);
        }
    }
  }
  return shared;
}

}  // namespace

void buildContactSpace(const Ctx& c, const VecX& fn, const VecX& u, const VecX& u_eval) {
  const Model& m = c.m;
  const Workspace& ws = c.ws;
  ContactPhaseScratch::ContactSpace& cs = c.ws.cp.cs;
  const size_t n = ws.candidates.size();
  cs.cand.clear();
  cs.row_of.assign(n, -1);
  for (size_t i = 0; i < n; ++i) {
    if (fn[i] <= 0.0) continue;
    cs.row_of[i] = static_cast<int>(cs.cand.size());
    cs.cand.push_back(static_cast<int>(i));
  }
  const int k = static_cast<int>(cs.cand.size());
  growTo(&cs.W, 2 * k, 3 * k);
  cs.vn.resize(k);
  cs.vt.resize(k);
  cs.dfn.assign(k, 0.0);
  cs.dft.assign(k, 0.0);
  cs.dfr.assign(k, 0.0);
  for (int j = 0; j < k; ++j) {
    const ContactGeom& gj = ws.geoms[cs.cand[j]];
    cs.vn[j] = normalVelocity(m, gj, u, u_eval);
    cs.vt[j] = slipVelocity(m, gj, u, u_eval);
  }
  // Column i: the rows a change of row i's forces moves.
  cs.coupled_start.resize(k + 1);
  cs.coupled.clear();
  for (int i = 0; i < k; ++i) {
    cs.coupled_start[i] = static_cast<int>(cs.coupled.size());
    const ContactGeom& gi = ws.geoms[cs.cand[i]];
    for (int j = 0; j < k; ++j)
      if (couple(m, ws.geoms[cs.cand[j]], gi, j, i, &cs.W)) cs.coupled.push_back(j);
  }
  cs.coupled_start[k] = static_cast<int>(cs.coupled.size());
}

void addForceChange(ContactPhaseScratch::ContactSpace* cs, int r, double dfn_N, double dft_N,
                    double dfr, double half_h_s) {
  const MatX& W = cs->W;
  for (int c = cs->coupled_start[r]; c < cs->coupled_start[r + 1]; ++c) {
    const int j = cs->coupled[c];
    cs->vn[j] += half_h_s * (W(2 * j, 3 * r) * dfn_N + W(2 * j, 3 * r + 1) * dft_N +
                             W(2 * j, 3 * r + 2) * dfr);
    cs->vt[j] += half_h_s * (W(2 * j + 1, 3 * r) * dfn_N + W(2 * j + 1, 3 * r + 1) * dft_N +
                             W(2 * j + 1, 3 * r + 2) * dfr);
  }
  cs->dfn[r] += dfn_N;
  cs->dft[r] += dft_N;
  cs->dfr[r] += dfr;
}

void applyContactSpace(const Ctx& c, double half_h_s, VecX* a, VecX* u) {
  const Model& m = c.m;
  ContactPhaseScratch::ContactSpace& cs = c.ws.cp.cs;
  for (size_t r = 0; r < cs.cand.size(); ++r) {
    if (cs.dfn[r] == 0.0 && cs.dft[r] == 0.0 && cs.dfr[r] == 0.0) continue;
    for (const BodyJac& b : c.ws.geoms[cs.cand[r]].side) {
      const double f[3] = {cs.dfn[r], cs.dft[r], cs.dfr[r]};
      for (int e = 0; e < 3; ++e) {
        if (f[e] == 0.0) continue;
        applyInverseMass(m, nullptr, b.body, direction(b, e), f[e], a);
        applyInverseMass(m, nullptr, b.body, direction(b, e), half_h_s * f[e], u);
      }
    }
    cs.dfn[r] = cs.dft[r] = cs.dfr[r] = 0.0;
  }
}

}  // namespace contact_phase
}  // namespace internal
}  // namespace threshing_sim
