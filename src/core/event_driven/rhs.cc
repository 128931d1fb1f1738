// The event-driven integrator's right-hand side under fixed index sets: smooth forces, known
// contact forces, and the multipliers of closed rigid normals and sticking tangents from
// g'' = 0.
#include <cmath>
#include <limits>
#include <utility>
#include <vector>

#include "context.h"

namespace threshing_sim {
namespace internal {
namespace event_driven {

namespace {

// Solves the leading n x n block of ws->ed.A for the right-hand side ws->ed.rc into ws->ed.lam
// by Gaussian elimination with complete pivoting, in place (ed.A and ed.rc are overwritten).
// Returns false if the matrix is singular: a pivot at or below n eps times the largest entry,
// the rank test of Eigen's FullPivLU.
bool solveSquare(Workspace* ws, int n) {
  auto A = ws->ed.A.topLeftCorner(n, n);
  auto r = ws->ed.rc.head(n);
  growTo(&ws->ed.lam, n);
  std::vector<int>& col_of = ws->ed.col_perm;  // unknown held by column j
  col_of.resize(n);
  for (int j = 0; j < n; ++j) col_of[j] = j;
  double max_pivot = 0.0;
  for (int k = 0; k < n; ++k) {
    // Largest remaining entry as the pivot: swap it to (k, k).
    Eigen::Index pr = 0, pc = 0;
    const double p = A.bottomRightCorner(n - k, n - k).cwiseAbs().maxCoeff(&pr, &pc);
    if (k == 0) max_pivot = p;
    if (!(p > max_pivot * std::numeric_limits<double>::epsilon() * n)) return false;
    pr += k;
    pc += k;
    A.row(k).swap(A.row(pr));
    std::swap(r[k], r[pr]);
    A.col(k).swap(A.col(pc));
    std::swap(col_of[k], col_of[pc]);
    // Eliminate below the pivot.
    for (int i = k + 1; i < n; ++i) {
      const double f = A(i, k) / A(k, k);
      if (f == 0.0) continue;
      A.row(i).tail(n - k - 1) -= f * A.row(k).tail(n - k - 1);
      r[i] -= f * r[k];
    }
  }
  // Back substitution, then undo the column permutation.
  for (int k = n - 1; k >= 0; --k) {
    double v = r[k];
    for (int j = k + 1; j < n; ++j) v -= A(k, j) * r[j];
    r[k] = v / A(k, k);
  }
  for (int k = 0; k < n; ++k) ws->ed.lam[col_of[k]] = r[k];
  return true;
}

// Contact forces per geom (ws.ed.fn, ws.ed.ft) from the multipliers of the last rhs(), stored
// in the pair memory if asked; returns the contact torque on the drum [N m].
double finishRhs(const Ctx& c, bool store_forces) {
  Workspace& ws = c.ws;
  const int k = static_cast<int>(ws.active.size());
  double torque = 0.0;
  const int n_geoms = static_cast<int>(ws.geoms.size());
  growTo(&ws.ed.fn, n_geoms);
  growTo(&ws.ed.ft, n_geoms);
  ws.ed.fn.head(n_geoms).setZero();
  ws.ed.ft.head(n_geoms).setZero();
  for (int i = 0; i < k; ++i) {
    const ContactGeom& g = ws.geoms[ws.active[i]];
    ws.ed.fn[ws.active[i]] = ws.lambda[2 * i];
    ws.ed.ft[ws.active[i]] = ws.lambda[2 * i + 1];
    if (g.pair.kind == PairKind::kToothKernel) {
      const Vec2& p = g.p0;
      torque += -ws.lambda[2 * i] * (p.x() * g.n.y() - p.y() * g.n.x()) -
                ws.lambda[2 * i + 1] * (p.x() * g.t.y() - p.y() * g.t.x());
      // A compliant force's residual spring: -dV/dtheta = (F^2/2) dR/dtheta (docs/model.md §9b).
      if (!ws.rows[i].normal_unknown)
        torque += residualForceFactor(g, ws.lambda[2 * i]) * g.residual_dtheta_mpNprad;
    }
    if (store_forces) {
      PairMemory& mem = candidateMemory(ws, ws.active[i]);
      mem.normal_force_N = ws.lambda[2 * i];
      mem.tangential_force_N = ws.lambda[2 * i + 1];
    }
  }
  return torque;
}

// The active contacts of the current index sets, as rows in ws.active / ws.rows: the known
// forces are compliant normals and every sliding friction with a known normal.
void collectActiveRows(const Ctx& c) {
  const Model& m = c.m;
  Workspace& ws = c.ws;
  ws.active.clear();
  ws.rows.clear();
  for (size_t i = 0; i < ws.geoms.size(); ++i) {
    ContactGeom& g = ws.geoms[i];
    PairMemory& mem = candidateMemory(ws, i);
    if (!isActive(mem)) continue;
    ContactRow row;
    row.mu = g.params->friction;
    row.slip_sign = mem.slip_sign;
    if (g.params->law == ContactLaw::kCompliant) {
      row.normal_unknown = false;
      row.lambda_n_fixed =
          compliantNormalForce(g, mem.hertz_K, mem.v_in_mps, m.hc_min_impact_speed_mps);
    }
    ws.active.push_back(static_cast<int>(i));
    ws.rows.push_back(row);
  }
}

// Known contact forces, into the free acceleration ws.du and the multipliers ws.lambda.
void applyKnownForces(const Ctx& c, const std::vector<MatX>* minv) {
  const Model& m = c.m;
  Workspace& ws = c.ws;
  const int k = static_cast<int>(ws.active.size());
  for (int i = 0; i < k; ++i) {
    const ContactGeom& g = ws.geoms[ws.active[i]];
    const ContactRow& row = ws.rows[i];
    if (row.normal_unknown) continue;
    const double fn = row.lambda_n_fixed;
    const double ft = row.slip_sign != 0 ? -row.slip_sign * row.mu * fn : 0.0;
    ws.lambda[2 * i] = fn;
    ws.lambda[2 * i + 1] = ft;
    const double fr = residualForceFactor(g, fn);  // series spring (docs/model.md §9b) [N]
    for (const BodyJac& s : g.side) {
      applyInverseMass(m, minv, s.body, s.w_n, fn, &ws.du);
      applyInverseMass(m, minv, s.body, s.w_t, ft, &ws.du);
      if (fr != 0.0) applyInverseMass(m, minv, s.body, s.w_r, fr, &ws.du);
    }
  }
}

// Effect on a constraint row's acceleration (contact gr, its normal for r_dir 0 or tangent for
// 1) of a unit multiplier of a column's unknown (contact gc under row rowc, normal for c_dir 0
// with the slip coupling of a sliding tangent, tangent for 1).
double rowCoupling(const Model& m, const std::vector<MatX>* minv, const ContactGeom& gr, int r_dir,
                   const ContactGeom& gc, const ContactRow& rowc, int c_dir) {
  double ft_per = 0.0, fn_per = 0.0;
  if (c_dir == 0) {
    fn_per = 1.0;
    ft_per = rowc.slip_sign != 0 ? -rowc.slip_sign * rowc.mu : 0.0;
  } else {
    ft_per = 1.0;
  }
  double v = 0.0;
  for (const BodyJac& sr : gr.side) {
    for (const BodyJac& sc : gc.side) {
      if (sr.body < 0 || sr.body != sc.body) continue;
      const SmallVec& wr = r_dir == 0 ? sr.w_n : sr.w_t;
      const int T = static_cast<int>(m.teeth.size());
      if (sr.body < T && minv != nullptr) {
        v += fn_per * weightedDot(m, minv, sr.body, wr, sc.w_n) +
             ft_per * weightedDot(m, minv, sr.body, wr, sc.w_t);
      } else if (sr.body < T) {
        v += fn_per * wr.dot(sc.w_n) + ft_per * wr.dot(sc.w_t);
      } else {
        const KernelModel& km = m.kernels[sr.body - T];
        const Eigen::Vector3d inv(1 / km.mass_kg, 1 / km.mass_kg, 1 / km.inertia_kgm2);
        for (int q = 0; q < 3; ++q) v += wr[q] * inv[q] * (fn_per * sc.w_n[q] + ft_per * sc.w_t[q]);
      }
    }
  }
  return v;
}

// The nc constraint rows (closed rigid normals and sticking tangents, g'' = 0) as the system
// ws.ed.A lambda = ws.ed.rc, with their unknowns listed in ws.ed.idx.
void assembleConstraintRows(const Ctx& c, const VecX& z, const VecX& u, const Drive& dr,
                            const std::vector<MatX>* minv, int nc) {
  const Model& m = c.m;
  Workspace& ws = c.ws;
  const int k = static_cast<int>(ws.active.size());
  // Unknowns: per constraint row, lambda along a direction that may carry a slip coupling.
  growTo(&ws.ed.A, nc, nc);
  growTo(&ws.ed.rc, nc);
  auto A = ws.ed.A.topLeftCorner(nc, nc);
  auto rhs_c = ws.ed.rc.head(nc);
  std::vector<std::pair<int, int>>& idx = ws.ed.idx;  // (active contact, 0 = N / 1 = T)
  idx.clear();
  for (int i = 0; i < k; ++i) {
    if (ws.rows[i].normal_unknown) idx.push_back({i, 0});
    if (ws.rows[i].slip_sign == 0 && ws.rows[i].mu > 0) idx.push_back({i, 1});
  }
  int drift_of = -1;  // active contact whose drift is in `drift`
  Vec2 drift = Vec2::Zero();
  for (int r = 0; r < nc; ++r) {
    const ContactGeom& gr = ws.geoms[ws.active[idx[r].first]];
    // Row: current g'' from the free acceleration, plus the velocity drift term.
    if (drift_of != idx[r].first) {
      drift = contactVelocityDrift(m, z, u, dr, gr, &ws);
      drift_of = idx[r].first;
    }
    double acc = idx[r].second == 0 ? drift[0] : drift[1];
    for (const BodyJac& s : gr.side) {
      if (s.body < 0 || s.w_n.size() == 0) continue;
      const auto ab = ws.du.segment(bodyDofOffset(m, s.body), s.w_n.size());
      acc += (idx[r].second == 0 ? s.w_n : s.w_t).dot(ab);
    }
    rhs_c[r] = -acc;
    // Columns: effect of each unknown on this row's acceleration.
    for (int col = 0; col < nc; ++col) {
      const int ic = idx[col].first;
      A(r, col) = rowCoupling(m, minv, gr, idx[r].second, ws.geoms[ws.active[ic]], ws.rows[ic],
                              idx[col].second);
    }
  }
}

// The solved multipliers (ws.ed.lam) into ws.lambda, and their forces into ws.du.
void applyConstraintForces(const Ctx& c, const std::vector<MatX>* minv, int nc) {
  const Model& m = c.m;
  Workspace& ws = c.ws;
  const std::vector<std::pair<int, int>>& idx = ws.ed.idx;
  const auto lam = ws.ed.lam.head(nc);
  for (int r = 0; r < nc; ++r) {
    const int i = idx[r].first;
    const ContactGeom& g = ws.geoms[ws.active[i]];
    const ContactRow& row = ws.rows[i];
    double fn = 0, ft = 0;
    if (idx[r].second == 0) {
      fn = lam[r];
      ws.lambda[2 * i] = fn;
      if (row.slip_sign != 0) {
        ft = -row.slip_sign * row.mu * fn;
        ws.lambda[2 * i + 1] = ft;
      }
    } else {
      ft = lam[r];
      ws.lambda[2 * i + 1] = ft;
    }
    for (const BodyJac& s : g.side) {
      applyInverseMass(m, minv, s.body, s.w_n, fn, &ws.du);
      applyInverseMass(m, minv, s.body, s.w_t, ft, &ws.du);
    }
  }
}

}  // namespace

// Right-hand side under the current index sets: udot, the contact forces (stored in the pair
// memory's normal/tangential force) and the contact torque on the drum. Returns false if the
// constraint system is singular.
// `separated` and `horizon_s` are passed to evaluateAll (the Runge-Kutta stages need no
// separated pair).
bool rhs(const Ctx& c, double t, const VecX& z, const VecX& u, VecX* udot, double* drum_torque,
         bool store_forces, SeparatedPairs separated, double horizon_s) {
  const Model& m = c.m;
  Workspace& ws = c.ws;
  const Drive dr = driveAtTime(c, t);
  if (rhsMemoHit(c, dr, z, u, separated, horizon_s)) {
    *udot = ws.ed.memo.udot;
    *drum_torque = finishRhs(c, store_forces);
    return true;
  }
  smoothForces(m, c.d, z, u, dr, &ws.forces);
  evaluateAll(c, z, u, dr, separated, horizon_s);
  // Inverse masses: the identity of the modes (nullptr) unless a tooth is a large-deflection rod.
  const std::vector<MatX>* minv = toothInverseMass(m, z, &ws);

  // Known forces: compliant normals and every sliding friction with a known normal.
  collectActiveRows(c);

  // Constraint rows: closed rigid normals and sticking tangents, g'' = 0.
  const int k = static_cast<int>(ws.active.size());
  growTo(&ws.lambda, 2 * k);
  ws.lambda.head(2 * k).setZero();
  int nc = 0;
  for (int i = 0; i < k; ++i) {
    nc += ws.rows[i].normal_unknown ? 1 : 0;
    nc += (ws.rows[i].slip_sign == 0 && ws.rows[i].mu > 0) ? 1 : 0;
  }
  freeAcceleration(m, minv, ws.forces, &ws.du);
  // Known contact forces, into the free acceleration.
  applyKnownForces(c, minv);
  if (nc > 0) {
    assembleConstraintRows(c, z, u, dr, minv, nc);
    if (!solveSquare(&ws, nc)) return false;
    applyConstraintForces(c, minv, nc);
  }
  *udot = ws.du;

  // Contact torque on the drum (for the drive work) and, if asked, the forces for reporting.
  *drum_torque = finishRhs(c, store_forces);
  rhsMemoStore(c, dr, z, u, separated, horizon_s, ws.du, *drum_torque);
  return true;
}

}  // namespace event_driven
}  // namespace internal
}  // namespace threshing_sim
