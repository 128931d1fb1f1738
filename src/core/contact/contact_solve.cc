// threshing_sim core: the contact solve (contact_solve.h): the generalised inverse mass, the
// island decomposition of the active contacts, and one complementarity problem per island.
#include "contact_solve.h"

#include <algorithm>

#include "../internal.h"

namespace threshing_sim {
namespace internal {

void applyInverseMass(const Model& m, const std::vector<MatX>* tooth_minv, int body,
                      const SmallVec& v, double scale, VecX* out) {
  if (body < 0 || v.size() == 0) return;
  const int off = bodyDofOffset(m, body);
  const int T = static_cast<int>(m.teeth.size());
  if (body < T) {
    if (tooth_minv) {
      out->segment(off, v.size()).noalias() += scale * ((*tooth_minv)[body] * v);
    } else {
      out->segment(off, v.size()) += scale * v;
    }
  } else {
    const KernelModel& k = m.kernels[body - T];
    (*out)[off] += scale * v[0] / k.mass_kg;
    (*out)[off + 1] += scale * v[1] / k.mass_kg;
    (*out)[off + 2] += scale * v[2] / k.inertia_kgm2;
  }
}

void freeAcceleration(const Model& m, const std::vector<MatX>* tooth_minv, const VecX& f, VecX* a) {
  a->resize(m.n_dof);
  for (size_t k = 0; k < m.teeth.size(); ++k) {
    const ToothModel& tm = m.teeth[k];
    if (tm.beam_model == ToothBeamModel::kLargeDeflection) {
      a->segment(tm.dof_offset, tm.n_modes).noalias() =
          (*tooth_minv)[k] * f.segment(tm.dof_offset, tm.n_modes);
      continue;
    }
    for (int i = 0; i < tm.n_modes; ++i) (*a)[tm.dof_offset + i] = 0.0 + f[tm.dof_offset + i];
  }
  for (const KernelModel& km : m.kernels) {
    const int o = km.dof_offset;
    (*a)[o] = 0.0 + f[o] / km.mass_kg;
    (*a)[o + 1] = 0.0 + f[o + 1] / km.mass_kg;
    (*a)[o + 2] = 0.0 + f[o + 2] / km.inertia_kgm2;
  }
}

double weightedDot(const Model& m, const std::vector<MatX>* tooth_minv, int body,
                   const SmallVec& w1, const SmallVec& w2) {
  const int T = static_cast<int>(m.teeth.size());
  if (body < T) {
    if (!tooth_minv) return w1.dot(w2);
    // The product into fixed-capacity storage: no heap temporary.
    SmallVec mw2(w2.size());
    mw2.noalias() = (*tooth_minv)[body] * w2;
    return w1.dot(mw2);
  }
  const KernelModel& k = m.kernels[body - T];
  return (w1[0] * w2[0] + w1[1] * w2[1]) / k.mass_kg + w1[2] * w2[2] / k.inertia_kgm2;
}

namespace {

int findRoot(std::vector<int>* parent, int i) {
  while ((*parent)[i] != i) i = (*parent)[i] = (*parent)[(*parent)[i]];
  return i;
}

// The islands of the k active contacts: ws->solve.island_contacts lists the contacts grouped
// by island, ws->solve.island_of_body[c] is the island (root body) of contact c.
void groupIslands(const Model& m, int k, Workspace* ws) {
  ContactSolveScratch& sv = ws->solve;
  // Union-find over bodies: two contacts sharing a moving body are in the same island.
  const int nb = numBodies(m);
  sv.island_parent.resize(nb);
  for (int i = 0; i < nb; ++i) sv.island_parent[i] = i;
  for (int c = 0; c < k; ++c) {
    const ContactGeom& g = ws->geoms[ws->active[c]];
    if (g.side[0].body >= 0) {
      const int r0 = findRoot(&sv.island_parent, g.side[0].body);
      const int r1 = findRoot(&sv.island_parent, g.side[1].body);
      sv.island_parent[r0] = r1;
    }
  }
  // Order the contacts by island root (stable, so the order inside an island is the input's).
  sv.island_contacts.resize(k);
  sv.island_of_body.resize(k);
  for (int c = 0; c < k; ++c) {
    sv.island_contacts[c] = c;
    sv.island_of_body[c] = findRoot(&sv.island_parent, ws->geoms[ws->active[c]].side[1].body);
  }
  // (std::stable_sort would allocate a buffer; ties broken by index give the same order.)
  std::sort(sv.island_contacts.begin(), sv.island_contacts.end(), [&](int a, int b) {
    return sv.island_of_body[a] < sv.island_of_body[b] ||
           (sv.island_of_body[a] == sv.island_of_body[b] && a < b);
  });
}

// Delassus matrix G = W^T Minv W of the island of the ki contacts from island_contacts[begin],
// and its right-hand side and rows.
void assembleIsland(const Model& m, const std::vector<MatX>* tooth_minv, int begin, int ki,
                    Workspace* ws) {
  ContactSolveScratch& sv = ws->solve;
  growTo(&sv.G_island, 2 * ki, 2 * ki);
  growTo(&sv.b_island, 2 * ki);
  growTo(&sv.lambda_island, 2 * ki);
  growTo(&sv.y_island, 2 * ki);
  auto G_island = sv.G_island.topLeftCorner(2 * ki, 2 * ki);
  G_island.setZero();
  sv.rows_island.resize(ki);
  for (int i = 0; i < ki; ++i) {
    const int ci = sv.island_contacts[begin + i];
    const ContactGeom& gi = ws->geoms[ws->active[ci]];
    sv.b_island.segment<2>(2 * i) = ws->b.segment<2>(2 * ci);
    sv.rows_island[i] = ws->rows[ci];
    for (int j = 0; j <= i; ++j) {
      const ContactGeom& gj = ws->geoms[ws->active[sv.island_contacts[begin + j]]];
      double nn = 0, nt = 0, tn = 0, tt = 0;
      for (const BodyJac& si : gi.side) {
        for (const BodyJac& sj : gj.side) {
          if (si.body < 0 || si.body != sj.body) continue;
          nn += weightedDot(m, tooth_minv, si.body, si.w_n, sj.w_n);
          nt += weightedDot(m, tooth_minv, si.body, si.w_n, sj.w_t);
          tn += weightedDot(m, tooth_minv, si.body, si.w_t, sj.w_n);
          tt += weightedDot(m, tooth_minv, si.body, si.w_t, sj.w_t);
        }
      }
      G_island(2 * i, 2 * j) = G_island(2 * j, 2 * i) = nn;
      G_island(2 * i, 2 * j + 1) = G_island(2 * j + 1, 2 * i) = nt;
      G_island(2 * i + 1, 2 * j) = G_island(2 * j, 2 * i + 1) = tn;
      G_island(2 * i + 1, 2 * j + 1) = G_island(2 * j + 1, 2 * i + 1) = tt;
    }
  }
}

// One complementarity problem over the island's contacts (assembled by assembleIsland); its
// solution scattered into ws->lambda and ws->y (zero impulses and the free velocities if it
// failed). Returns whether it was solved.
bool solveIsland(int begin, int ki, Workspace* ws) {
  ContactSolveScratch& sv = ws->solve;
  const bool ok = solveContactProblem(
      sv.G_island.topLeftCorner(2 * ki, 2 * ki), sv.b_island.head(2 * ki), sv.rows_island,
      sv.lambda_island.head(2 * ki), sv.y_island.head(2 * ki), &sv.lcp);
  for (int i = 0; i < ki; ++i) {
    const int ci = sv.island_contacts[begin + i];
    ws->lambda.segment<2>(2 * ci) = ok ? Vec2(sv.lambda_island.segment<2>(2 * i)) : Vec2::Zero();
    ws->y.segment<2>(2 * ci) =
        ok ? Vec2(sv.y_island.segment<2>(2 * i)) : Vec2(sv.b_island.segment<2>(2 * i));
  }
  return ok;
}

}  // namespace

bool solveContactIslands(const Model& m, const std::vector<MatX>* tooth_minv, Workspace* ws) {
  const int k = static_cast<int>(ws->active.size());
  growTo(&ws->lambda, 2 * k);
  growTo(&ws->y, 2 * k);
  ws->lambda.head(2 * k).setZero();
  if (k == 0) return true;
  groupIslands(m, k, ws);
  bool all_ok = true;
  for (int begin = 0; begin < k;) {
    int end = begin + 1;
    const int root = ws->solve.island_of_body[ws->solve.island_contacts[begin]];
    while (end < k && ws->solve.island_of_body[ws->solve.island_contacts[end]] == root) ++end;
    const int ki = end - begin;
    assembleIsland(m, tooth_minv, begin, ki, ws);
    const bool ok = solveIsland(begin, ki, ws);
    all_ok = all_ok && ok;
    begin = end;
  }
  return all_ok;
}

}  // namespace internal
}  // namespace threshing_sim
