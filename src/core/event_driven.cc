// Event-driven integration (docs/model.md §7-9, the paper's method).
//
// Between events the index sets are fixed: each pair is separated, in compliant contact, or
// closed under the rigid law, and each contact sticks or slips one way. The smooth phase is
// integrated by Dormand-Prince 5(4) to the tolerance; the multipliers of closed normals and
// sticking tangents come from g'' = 0 at every right-hand side. After each accepted step the
// event functions are checked (gap, normal force, friction limit, slip velocity, pedicel
// force); a gap that dips below zero and back inside the step is found from the cubic Hermite
// interpolant of its values and rates at the step ends (checked at the predicted minimum), and
// a just-bounced gap (at or below zero, opening) is armed to fire when it closes again. A
// sign change is located by re-stepping from the step start (bisection on the step length), the
// state is advanced to just past it, and the index sets are switched: impacts are solved as a
// velocity-level complementarity problem, stick/slip/separation as an acceleration-level one.
// Impacts slower than zeno_velocity are plastic (Zeno rule).
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>

#include "internal.h"
#include "threshing_sim/core/beam.h"
#include "threshing_sim/core/simulator.h"

namespace threshing_sim {
namespace internal {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

// Per-step context: the data at the step start (drum state) and the candidate pairs.
struct Ctx {
  const Model& m;
  Data& d;
  Workspace& ws;
};

bool isActive(const PairMemory& mem) { return mem.state != ContactState::kSeparated; }

// Drum state at absolute time t (the target is fixed within a step).
Drive driveAtTime(const Ctx& c, double t) { return driveAt(c.m, c.d, t - c.d.t_s); }

// How much of a separated pair evaluateAll computes.
enum class SeparatedPairs {
  kNear,  // exact unless surely beyond a quarter of the broad-phase margin (reported contacts;
          // kernel and obstacle pairs by the supporting-line bound)
  kSign,  // the sign of the gap: tooth pairs as kNear, other pairs exact only within reach
          // by the supporting-line bound (event functions; see evaluateAll)
  kNone,  // nothing (Runge-Kutta stages: separated pairs exert no force)
};

// Starting point of a tooth pair's closest point at time t_s [s] [m]: the last one (-1: none),
// moved on linearly by the rate between the last two where they are 1e-12 s or more apart and
// the move is within 1e-3 of the tooth's length.
double warmStart(const Model& m, const PairMemory& mem, const PairId& p, double t_s) {
  double x = mem.warm_x_m;
  if (x < 0.0 || mem.warm_x_prev_m < 0.0) return x;
  const double dt = mem.warm_t_s - mem.warm_t_prev_s;
  if (!(std::abs(dt) >= 1e-12)) return x;
  const double move = (mem.warm_x_m - mem.warm_x_prev_m) / dt * (t_s - mem.warm_t_s);
  const double L = m.teeth[p.a].length_m;
  if (std::abs(move) <= 1e-3 * L) x = std::clamp(x + move, 0.0, L);
  return x;
}

// Evaluates every candidate pair at (z, u, t) into ws.geoms; separated pairs as `separated`
// says (a far pair gets only a lower bound of its gap). Under kSign, a separated kernel pair
// (kernel-obstacle, kernel-kernel) is evaluated exactly when its gap bound is within 1 um or
// within twice what its bodies can cover in horizon_s [s] at their present speeds: a pair
// whose gap falls to zero and rises again inside a step of that length (a spinning kernel
// grazing a wall) is then exact, with its rate, at both ends of the step, as the graze check
// needs; a pair beyond that reach cannot close within the step.
void evaluateAll(const Ctx& c, const VecX& z, const VecX& u, const Drive& dr,
                 SeparatedPairs separated = SeparatedPairs::kNear, double horizon_s = 0.0) {
  c.ws.ed.memo.valid = false;  // ws.geoms and the stations change
  // Stations only of the teeth that have a candidate pair that will be evaluated (candidates
  // are sorted by kind, tooth pairs first, by tooth).
  // A tooth whose evaluated pairs are all in contact with a warm start (evaluateContact) needs
  // none: the warm start computes the two stations around its points itself.
  layoutStations(c.m, &c.ws);
  int last_tooth = -1;
  for (const PairId& p : c.ws.candidates) {
    if (p.kind != PairKind::kToothKernel) break;
    if (p.a == last_tooth) continue;
    const PairMemory& mem = c.ws.memory[pairKey(p)];
    const bool separated_pair = mem.state == ContactState::kSeparated;
    if (separated == SeparatedPairs::kNone && separated_pair) continue;
    if (!separated_pair && mem.warm_x_m >= 0.0 && c.m.teeth[p.a].n_modes > 0 &&
        c.m.teeth[p.a].beam_model == ToothBeamModel::kModal)
      continue;
    updateToothStations(c.m, z, dr.theta_rad, p.a, &c.ws);
    last_tooth = p.a;
  }
  c.ws.geoms.resize(c.ws.candidates.size());
  const double near_m = 0.25 * c.m.broadphase_margin_m;
  for (size_t i = 0; i < c.ws.candidates.size(); ++i) {
    const PairId& p = c.ws.candidates[i];
    ContactGeom& g = c.ws.geoms[i];
    double far_m = kInf;
    bool tight = false;
    PairMemory& mem = c.ws.memory[pairKey(p)];
    // Tooth pairs in contact start the narrow phase from their last closest point (moved on
    // in time by the rate between the last two); a separated one records its closest point for
    // when its contact begins.
    double x_warm = -1;
    double* warm = p.kind == PairKind::kToothKernel ? &x_warm : nullptr;
    if (warm && mem.state != ContactState::kSeparated) x_warm = warmStart(c.m, mem, p, dr.t_s);
    if (mem.state == ContactState::kSeparated) {
      mem.warm_x_m = -1;
      if (separated == SeparatedPairs::kNone) {
        // Not evaluated: marked far with no finite bound.
        g.pair = p;
        g.params = &c.m.contact[static_cast<int>(p.kind)];
        g.far = true;
        g.gap_m = kInf;
        continue;
      }
      const bool tooth = p.kind == PairKind::kToothKernel;
      if (separated == SeparatedPairs::kSign && !tooth) {
        double speed_mps = kernelSpeedBound(c.m, u, p.a);
        if (p.kind == PairKind::kKernelKernel) speed_mps += kernelSpeedBound(c.m, u, p.b);
        far_m = std::max(1e-6, 2.0 * horizon_s * speed_mps);
      } else {
        far_m = near_m;
      }
      tight = !tooth;  // kernel and obstacle pairs: the supporting-line bound
    }
    evaluateContact(c.m, z, u, dr, p, &c.ws, &g, far_m, tight, warm);
    if (warm && !g.far) {
      mem.warm_x_prev_m = mem.warm_x_m;
      mem.warm_t_prev_s = mem.warm_t_s;
      mem.warm_x_m = g.tooth_x_m;
      mem.warm_t_s = dr.t_s;
    }
  }
}

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

// What rhs() reads of a candidate's pair memory: its index sets and compliant constants.
RhsMemo::PairState pairStateOf(const PairMemory& mem) {
  RhsMemo::PairState p;
  p.state = static_cast<int>(mem.state);
  p.closed = mem.closed;
  p.slip_sign = mem.slip_sign;
  p.v_in_mps = mem.v_in_mps;
  p.hertz_K = mem.hertz_K;
  return p;
}

bool bitsEqual(const VecX& a, const VecX& b) {
  if (a.size() != b.size()) return false;
  // Empty vectors (a scene without dofs) have no storage: memcmp must not see a null pointer.
  return a.size() == 0 ||
         std::memcmp(a.data(), b.data(), sizeof(double) * static_cast<size_t>(a.size())) == 0;
}

// Whether the last rhs() call (whose geometry, forces and multipliers are still in the
// workspace: any other evaluation clears ws.ed.memo.valid) was made with the same inputs, so
// that its results hold for a call at (dr, z, u): the same drum state, state bits, pedicels,
// candidates and index sets, and separated pairs evaluated as `separated` asks (any mode
// serves kNone, whose callers read only pairs in contact; without separated candidates the
// modes agree).
bool rhsMemoHit(const Ctx& c, const Drive& dr, const VecX& z, const VecX& u,
                SeparatedPairs separated, double horizon_s) {
  const RhsMemo& mm = c.ws.ed.memo;
  if (!mm.valid || mm.model != &c.m || mm.t_s != dr.t_s || mm.theta_rad != dr.theta_rad ||
      mm.omega_radps != dr.omega_radps || mm.alpha_radps2 != dr.alpha_radps2)
    return false;
  // kNear and kSign differ only on separated kernel-kernel and kernel-obstacle pairs (tooth
  // pairs are evaluated alike, whatever the horizon).
  const bool memo_none = mm.separated == static_cast<int>(SeparatedPairs::kNone);
  const bool mode_ok =
      separated == SeparatedPairs::kNone || mm.n_separated == 0 ||
      (!memo_none && (mm.n_separated_other == 0 ||
                      (static_cast<int>(separated) == mm.separated &&
                       (separated != SeparatedPairs::kSign || horizon_s == mm.horizon_s))));
  if (!mode_ok || !bitsEqual(z, mm.z) || !bitsEqual(u, mm.u) ||
      c.d.kernel_attached != mm.attached || c.ws.candidates != mm.candidates ||
      c.ws.geoms.size() != c.ws.candidates.size())
    return false;
  for (size_t i = 0; i < mm.candidates.size(); ++i) {
    const RhsMemo::PairState p = pairStateOf(c.ws.memory[pairKey(mm.candidates[i])]);
    const RhsMemo::PairState& q = mm.pairs[i];
    if (p.state != q.state || p.closed != q.closed || p.slip_sign != q.slip_sign ||
        p.v_in_mps != q.v_in_mps || p.hertz_K != q.hertz_K)
      return false;
  }
  return true;
}

// Records the inputs and the accelerations of a completed rhs() call.
void rhsMemoStore(const Ctx& c, const Drive& dr, const VecX& z, const VecX& u,
                  SeparatedPairs separated, double horizon_s, const VecX& udot, double torque) {
  RhsMemo& mm = c.ws.ed.memo;
  mm.model = &c.m;
  mm.t_s = dr.t_s;
  mm.theta_rad = dr.theta_rad;
  mm.omega_radps = dr.omega_radps;
  mm.alpha_radps2 = dr.alpha_radps2;
  mm.z = z;
  mm.u = u;
  mm.attached = c.d.kernel_attached;
  mm.candidates = c.ws.candidates;
  mm.pairs.resize(mm.candidates.size());
  mm.n_separated = 0;
  mm.n_separated_other = 0;
  for (size_t i = 0; i < mm.candidates.size(); ++i) {
    mm.pairs[i] = pairStateOf(c.ws.memory[pairKey(mm.candidates[i])]);
    const bool apart = mm.pairs[i].state == static_cast<int>(ContactState::kSeparated);
    mm.n_separated += apart ? 1 : 0;
    mm.n_separated_other += apart && mm.candidates[i].kind != PairKind::kToothKernel ? 1 : 0;
  }
  mm.separated = static_cast<int>(separated);
  mm.horizon_s = horizon_s;
  mm.udot = udot;
  mm.torque = torque;
  mm.valid = true;
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
    }
    if (store_forces) {
      PairMemory& mem = ws.memory[pairKey(g.pair)];
      mem.normal_force_N = ws.lambda[2 * i];
      mem.tangential_force_N = ws.lambda[2 * i + 1];
    }
  }
  return torque;
}

// Right-hand side under the current index sets: udot, the contact forces (stored in the pair
// memory's normal/tangential force) and the contact torque on the drum. Returns false if the
// constraint system is singular.
// `separated` and `horizon_s` are passed to evaluateAll (the Runge-Kutta stages need no
// separated pair).
bool rhs(const Ctx& c, double t, const VecX& z, const VecX& u, VecX* udot, double* drum_torque,
         bool store_forces, SeparatedPairs separated = SeparatedPairs::kNear,
         double horizon_s = 0.0) {
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
  ws.active.clear();
  ws.rows.clear();
  for (size_t i = 0; i < ws.geoms.size(); ++i) {
    ContactGeom& g = ws.geoms[i];
    PairMemory& mem = ws.memory[pairKey(g.pair)];
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
  for (int i = 0; i < k; ++i) {
    const ContactGeom& g = ws.geoms[ws.active[i]];
    const ContactRow& row = ws.rows[i];
    if (row.normal_unknown) continue;
    const double fn = row.lambda_n_fixed;
    const double ft = row.slip_sign != 0 ? -row.slip_sign * row.mu * fn : 0.0;
    ws.lambda[2 * i] = fn;
    ws.lambda[2 * i + 1] = ft;
    for (const BodyJac& s : g.side) {
      applyInverseMass(m, minv, s.body, s.w_n, fn, &ws.du);
      applyInverseMass(m, minv, s.body, s.w_t, ft, &ws.du);
    }
  }
  if (nc > 0) {
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
        const ContactGeom& gc = ws.geoms[ws.active[ic]];
        const ContactRow& rowc = ws.rows[ic];
        double ft_per = 0.0, fn_per = 0.0;
        if (idx[col].second == 0) {
          fn_per = 1.0;
          ft_per = rowc.slip_sign != 0 ? -rowc.slip_sign * rowc.mu : 0.0;
        } else {
          ft_per = 1.0;
        }
        double v = 0.0;
        for (const BodyJac& sr : gr.side) {
          for (const BodyJac& sc : gc.side) {
            if (sr.body < 0 || sr.body != sc.body) continue;
            const SmallVec& wr = idx[r].second == 0 ? sr.w_n : sr.w_t;
            const int T = static_cast<int>(m.teeth.size());
            if (sr.body < T && minv != nullptr) {
              v += fn_per * weightedDot(m, minv, sr.body, wr, sc.w_n) +
                   ft_per * weightedDot(m, minv, sr.body, wr, sc.w_t);
            } else if (sr.body < T) {
              v += fn_per * wr.dot(sc.w_n) + ft_per * wr.dot(sc.w_t);
            } else {
              const KernelModel& km = m.kernels[sr.body - T];
              const Eigen::Vector3d inv(1 / km.mass_kg, 1 / km.mass_kg, 1 / km.inertia_kgm2);
              for (int q = 0; q < 3; ++q)
                v += wr[q] * inv[q] * (fn_per * sc.w_n[q] + ft_per * sc.w_t[q]);
            }
          }
        }
        A(r, col) = v;
      }
    }
    if (!solveSquare(&ws, nc)) return false;
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
  *udot = ws.du;

  // Contact torque on the drum (for the drive work) and, if asked, the forces for reporting.
  *drum_torque = finishRhs(c, store_forces);
  rhsMemoStore(c, dr, z, u, separated, horizon_s, ws.du, *drum_torque);
  return true;
}

// Event functions: positive while the current index sets stay valid. Fills vals in the
// order of ws.geoms (4 per pair) followed by one per kernel (pedicel). Uses the forces the
// last rhs() call stored for (z, u) at time t. If rates is given it receives the time
// derivative of each function where it is known cheaply (the gap functions: +-dg_N/dt of a
// pair whose geometry was evaluated in full) and NaN elsewhere [unit of the function / s].
// horizon_s is the length of the step these values bound [s]: every separated pair that could
// close within it gets its exact gap and rate (evaluateAll).
void eventValues(const Ctx& c, double t, const VecX& z, const VecX& u, std::vector<double>* vals,
                 std::vector<double>* rates = nullptr, double horizon_s = 0.0) {
  const Model& m = c.m;
  Workspace& ws = c.ws;
  double torque;
  rhs(c, t, z, u, &ws.ed.udot_ev, &torque, true, SeparatedPairs::kSign, horizon_s);
  vals->assign(4 * ws.geoms.size() + m.kernels.size(), 1.0);
  if (rates) rates->assign(vals->size(), std::numeric_limits<double>::quiet_NaN());
  for (size_t i = 0; i < ws.geoms.size(); ++i) {
    const ContactGeom& g = ws.geoms[i];
    const PairMemory& mem = ws.memory[pairKey(g.pair)];
    double* v = &(*vals)[4 * i];
    if (!isActive(mem)) {
      // Separated: the gap closes.
      v[0] = g.gap_m;
      if (rates && !g.far) (*rates)[4 * i] = g.vn;
      continue;
    }
    const double mu = g.params->friction;
    const double fn = mem.normal_force_N, ft = mem.tangential_force_N;
    if (g.params->law == ContactLaw::kCompliant) {
      // Compliant: the bodies part, or the damped force would pull.
      v[0] = -g.gap_m;
      if (rates) (*rates)[4 * i] = -g.vn;
      const double delta = std::max(-g.gap_m, 0.0);
      v[1] = g.residual_mpN > 0.0
                 ? compliantNormalForceSigned(g, mem.hertz_K, mem.v_in_mps,
                                              m.hc_min_impact_speed_mps) /
                       std::max(1.0, mem.hertz_K * 1e-9)
                 : mem.hertz_K * delta * std::sqrt(delta) *
                       (1.0 - g.params->hc_damping_factor /
                                  std::max(mem.v_in_mps, m.hc_min_impact_speed_mps) * g.vn) /
                       std::max(1.0, mem.hertz_K * 1e-9);
    } else {
      // Rigid: the normal multiplier falls to zero.
      v[0] = fn;
    }
    if (mu > 0) {
      // Stick: the friction limit is reached. Slip: the sliding velocity reverses.
      v[2] = mem.slip_sign == 0 ? mu * fn - std::abs(ft) : mem.slip_sign * g.vt;
    }
  }
  for (size_t i = 0; i < m.kernels.size(); ++i) {
    const KernelModel& k = m.kernels[i];
    if (!k.pedicel.present || !c.d.kernel_attached[i]) continue;
    Vec2 p;
    (*vals)[4 * ws.geoms.size() + i] =
        k.pedicel.detachment_force_N - pedicelForce(m, z, u, static_cast<int>(i), &p).norm();
  }
}

// Marks in ws.ed.tooth_exact the teeth that the step from the data's time may advance exactly:
// the option is on, the drum is at its target speed (no ramp, so dOmega/dt = 0 all through the
// step), the tooth has modes and a valid propagator, and none of its pairs is in contact (a
// separated pair exerts no force within a step). Returns the number of teeth marked.
int markExactTeeth(const Ctx& c) {
  const Model& m = c.m;
  Workspace& ws = c.ws;
  const int T = static_cast<int>(m.teeth.size());
  ws.ed.tooth_exact.assign(T, 0);
  if (!m.integrator.exact_free_teeth || c.d.omega_radps != c.d.omega_target_radps) return 0;
  if (ws.ed.prop.size() != static_cast<size_t>(T)) ws.ed.prop.resize(T);
  // Teeth with a mode and a usable propagator at this drum speed.
  int marked = 0;
  for (int k = 0; k < T; ++k) {
    if (m.teeth[k].n_modes == 0) continue;
    if (!buildToothPropagator(m, k, c.d.omega_radps, &ws.ed.prop[k])) continue;
    ws.ed.tooth_exact[k] = 1;
    ++marked;
  }
  // Minus the teeth in contact.
  for (const PairId& p : ws.candidates) {
    if (p.kind != PairKind::kToothKernel || !ws.ed.tooth_exact[p.a]) continue;
    if (isActive(ws.memory[pairKey(p)])) {
      ws.ed.tooth_exact[p.a] = 0;
      --marked;
    }
  }
  return marked;
}

// One Dormand-Prince step of length h from (t0, y0 = [z; u]); y1 and its error estimate.
// Teeth marked by markExactTeeth take the exact solution of their free modal equations at the
// step end instead, and stay out of the error estimate (their stages affect no other body).
bool dopriStep(const Ctx& c, double t0, double h, const VecX& z0, const VecX& u0, VecX* z1,
               VecX* u1, double* err, double* torque1) {
  const int n = c.m.n_dof;
  Workspace& ws = c.ws;
  ++ws.ed.trial_steps;
  for (auto& k : ws.ed.rk_k) k.resize(2 * n);
  ws.ed.rk_tmp.resize(2 * n);
  VecX& zz = ws.ed.zz;
  VecX& uu = ws.ed.uu;
  VecX& udot = ws.ed.udot;
  double torque = 0;
  const int n_pairs = static_cast<int>(ws.candidates.size());
  growTo(&ws.ed.imp_n, n_pairs);
  growTo(&ws.ed.imp_t, n_pairs);
  ws.ed.imp_n.head(n_pairs).setZero();
  ws.ed.imp_t.head(n_pairs).setZero();
  ws.ed.torque_impulse = 0;
  zz.resize(n);
  uu.resize(n);
  for (int s = 0; s < 7; ++s) {
    // Stage state y0 + h sum_j a_sj k_j, component by component (plain loops: the vectors are
    // short, where Eigen's dynamic-size expressions cost more than the arithmetic).
    const double* k_j[6];
    double a_j[6];
    int n_j = 0;
    for (int j = 0; j < s; ++j) {
      if (kA[s][j] == 0.0) continue;
      k_j[n_j] = ws.ed.rk_k[j].data();
      a_j[n_j++] = h * kA[s][j];
    }
    const double* z0p = z0.data();
    const double* u0p = u0.data();
    for (int i = 0; i < n; ++i) {
      double zi = z0p[i], ui = u0p[i];
      for (int j = 0; j < n_j; ++j) {
        zi += a_j[j] * k_j[j][i];
        ui += a_j[j] * k_j[j][n + i];
      }
      zz[i] = zi;
      uu[i] = ui;
    }
    if (!rhs(c, t0 + kC[s] * h, zz, uu, &udot, &torque, false, SeparatedPairs::kNone)) return false;
    double* k_s = ws.ed.rk_k[s].data();
    for (int i = 0; i < n; ++i) {
      k_s[i] = uu[i];
      k_s[n + i] = udot[i];
    }
    // Contact impulses and drum torque integrated with the 5th-order weights (b = row 7 of A).
    if (s < 6 && kA[6][s] != 0.0) {
      const double b = h * kA[6][s];
      for (int i = 0; i < n_pairs; ++i) {
        ws.ed.imp_n[i] += b * ws.ed.fn[i];
        ws.ed.imp_t[i] += b * ws.ed.ft[i];
      }
      ws.ed.torque_impulse += b * torque;
    }
  }
  // Stage 7 is the 5th-order solution (FSAL).
  *z1 = zz;
  *u1 = uu;
  *torque1 = torque;
  // Free teeth: the exact end state replaces the Runge-Kutta one; their dofs are left out of
  // the error estimate (own_error = 0).
  std::vector<std::uint8_t>& own_error = ws.ed.own_error;  // per dof: in the error estimate
  own_error.assign(n, 1);
  const int n_exact = markExactTeeth(c);
  if (n_exact > 0) {
    for (size_t k = 0; k < c.m.teeth.size(); ++k) {
      if (!ws.ed.tooth_exact[k]) continue;
      const ToothModel& tm = c.m.teeth[k];
      propagateTooth(&ws.ed.prop[k], h, z0.segment(tm.dof_offset, tm.n_modes),
                     u0.segment(tm.dof_offset, tm.n_modes), z1->segment(tm.dof_offset, tm.n_modes),
                     u1->segment(tm.dof_offset, tm.n_modes));
      std::fill_n(own_error.begin() + tm.dof_offset, tm.n_modes, 0);
    }
  }
  // Error estimate scaled per component: positions by 1e-2 m, velocities by 1 m/s; the RMS over
  // the components it covers.
  double e2 = 0.0;
  int n_err = 0;
  for (int i = 0; i < 2 * n; ++i) {
    if (!own_error[i < n ? i : i - n]) continue;
    ++n_err;
    double ei = 0.0;
    for (int s = 0; s < 7; ++s) ei += kE[s] * ws.ed.rk_k[s][i];
    ei *= h;
    const double y = i < n ? std::max(std::abs(z0[i]), std::abs(zz[i]))
                           : std::max(std::abs(u0[i - n]), std::abs(uu[i - n]));
    const double scale = c.m.integrator.tolerance * ((i < n ? 1e-2 : 1.0) + y);
    e2 += (ei / scale) * (ei / scale);
  }
  *err = std::sqrt(e2 / std::max(1, n_err));
  return z1->allFinite() && u1->allFinite();
}

// Velocity-level impact over the closed rigid contacts: Newton restitution, Coulomb friction on
// the impulses. Falls back to a plastic impact if the Newton law would raise the energy.
void solveImpact(const Ctx& c, double t, bool force_plastic) {
  const Model& m = c.m;
  Workspace& ws = c.ws;
  Data& d = c.d;
  const Drive dr = driveAtTime(c, t);
  evaluateAll(c, d.z, d.u, dr);
  for (int attempt = 0; attempt < 2; ++attempt) {
    const bool plastic = force_plastic || attempt == 1;
    ws.active.clear();
    ws.rows.clear();
    for (size_t i = 0; i < ws.geoms.size(); ++i) {
      const ContactGeom& g = ws.geoms[i];
      const PairMemory& mem = ws.memory[pairKey(g.pair)];
      if (g.params->law != ContactLaw::kRigid) continue;
      if (!(mem.closed || g.gap_m <= 10 * m.integrator.tolerance * 1e-3)) continue;
      ContactRow row;
      row.mu = g.params->friction;
      ws.active.push_back(static_cast<int>(i));
      ws.rows.push_back(row);
    }
    const int k = static_cast<int>(ws.active.size());
    growTo(&ws.b, 2 * k);
    growTo(&ws.b_offset, k);
    for (int i = 0; i < k; ++i) {
      const ContactGeom& g = ws.geoms[ws.active[i]];
      const bool slow = g.vn > -m.integrator.zeno_velocity_mps;
      ws.b_offset[i] = plastic || slow ? 0.0 : g.params->restitution * std::min(g.vn, 0.0);
      ws.b[2 * i] = g.vn + ws.b_offset[i];
      ws.b[2 * i + 1] = g.vt;
    }
    const double e_before = energyOf(m, d, d.z, d.u, dr.omega_radps);
    const double H_before = angularMomentumOf(m, d.z, d.u, dr.omega_radps);
    const std::vector<MatX>* minv = toothInverseMass(m, d.z, &ws);
    solveContactIslands(m, minv, &ws);
    ws.u_old = d.u;
    double ang = 0.0;
    for (int i = 0; i < k; ++i) {
      const ContactGeom& g = ws.geoms[ws.active[i]];
      for (const BodyJac& s : g.side) {
        applyInverseMass(m, minv, s.body, s.w_n, ws.lambda[2 * i], &d.u);
        applyInverseMass(m, minv, s.body, s.w_t, ws.lambda[2 * i + 1], &d.u);
      }
      if (g.pair.kind == PairKind::kToothKernel) {
        const Vec2& p = g.p0;
        ang += -ws.lambda[2 * i] * (p.x() * g.n.y() - p.y() * g.n.x()) -
               ws.lambda[2 * i + 1] * (p.x() * g.t.y() - p.y() * g.t.x());
      }
    }
    const double H_after = angularMomentumOf(m, d.z, d.u, dr.omega_radps);
    const double work = dr.omega_radps * (H_after - H_before - ang);
    const double gain = energyOf(m, d, d.z, d.u, dr.omega_radps) - e_before - work;
    // Newton's law with friction can create energy: redo the impact plastically.
    if (gain > 1e-12 * std::max(1.0, std::abs(e_before)) && !plastic) {
      d.u = ws.u_old;
      continue;
    }
    d.stats.drive_work_J += work;
    const double e_net_after = e_before + gain - (d.stats.drive_work_J);
    // Report each contact that took an impulse.
    for (int i = 0; i < k; ++i) {
      const ContactGeom& g = ws.geoms[ws.active[i]];
      PairMemory& mem = ws.memory[pairKey(g.pair)];
      const double pn = ws.lambda[2 * i], pt = ws.lambda[2 * i + 1];
      if (pn <= 0.0) continue;
      const bool was_open = !mem.closed;
      if (was_open) beginEpisode(m, &d, &mem, g, t, e_before - (d.stats.drive_work_J - work));
      ContactEvent ev;
      ev.t_s = t;
      ev.pair = g.pair;
      ev.from = was_open ? ContactState::kSeparated : mem.state;
      ev.to = ContactState::kImpact;
      ev.is_impact = true;
      ev.vn_before_mps = g.vn;
      ev.vt_before_mps = g.vt;
      // y_N is dg_N+ + e dg_N-: take the offset back out for the post-impact velocity.
      const double vn_after = ws.y[2 * i] - ws.b_offset[i];
      ev.vn_after_mps = vn_after;
      ev.vt_after_mps = ws.y[2 * i + 1];
      ev.impulse_normal_Ns = pn;
      ev.impulse_tangential_Ns = pt;
      ev.energy_lost_J = -gain;
      ev.macro_collision = mem.macro_index;
      ev.sub_collision = mem.sub_index;
      d.events.push_back(ev);
      ++d.stats.impacts;
      const int kb = g.pair.kind == PairKind::kKernelObstacle ? g.pair.a : g.pair.b;
      ++d.stats.kernel_impacts[kb];
      if (g.pair.kind == PairKind::kKernelKernel) ++d.stats.kernel_impacts[g.pair.a];
      d.stats.max_energy_gain_at_impact_J = std::max(d.stats.max_energy_gain_at_impact_J, gain);
      d.stats.total_normal_impulse_Ns += pn;
      mem.impulse_n_acc += pn;
      mem.impulse_t_acc += pt;
      mem.episode_impulse_n += pn;
      mem.episode_impulse_t += pt;
      // Closed if the contact does not leave after the impact; otherwise it bounced.
      const bool stays = vn_after <= m.integrator.zeno_velocity_mps;
      mem.closed = stays;
      mem.state = ContactState::kImpact;
      mem.slip_sign = 0;
      if (!stays) {
        // It bounced: the episode was the instant of the impact.
        mem.last_contact_end_s = t;
        mem.state = ContactState::kSeparated;
        mem.closed = false;
      }
    }
    (void)e_net_after;
    return;
  }
}

// Chooses stick / slip / separation for every active contact from an acceleration-level
// complementarity problem over the closed rigid normals and the stick-capable tangents.
// Returns false if that problem has no solution found (Painleve); the caller then applies a
// tangential impact.
bool updateModes(const Ctx& c, double t, const std::vector<int>& forced_slip) {
  const Model& m = c.m;
  Workspace& ws = c.ws;
  Data& d = c.d;
  const Drive dr = driveAtTime(c, t);
  smoothForces(m, d, d.z, d.u, dr, &ws.forces);
  evaluateAll(c, d.z, d.u, dr);
  const std::vector<MatX>* minv = toothInverseMass(m, d.z, &ws);
  ws.du.setZero(m.n_dof);
  for (size_t b = 0; b < m.teeth.size() + m.kernels.size(); ++b) {
    const int off = bodyDofOffset(m, static_cast<int>(b));
    const int n = bodyDofCount(m, static_cast<int>(b));
    if (n == 0) continue;
    SmallVec fb = ws.forces.segment(off, n);
    applyInverseMass(m, minv, static_cast<int>(b), fb, 1.0, &ws.du);
  }
  const double v_eps = m.integrator.zeno_velocity_mps;
  ws.active.clear();
  ws.rows.clear();
  for (size_t i = 0; i < ws.geoms.size(); ++i) {
    const ContactGeom& g = ws.geoms[i];
    PairMemory& mem = ws.memory[pairKey(g.pair)];
    if (!isActive(mem)) continue;
    ContactRow row;
    row.mu = g.params->friction;
    if (g.params->law == ContactLaw::kCompliant) {
      row.normal_unknown = false;
      row.lambda_n_fixed =
          compliantNormalForce(g, mem.hertz_K, mem.v_in_mps, m.hc_min_impact_speed_mps);
    } else if (!mem.closed) {
      continue;
    }
    // Sliding contacts keep their direction; slow ones may stick.
    const bool forced =
        std::find(forced_slip.begin(), forced_slip.end(), static_cast<int>(i)) != forced_slip.end();
    if (forced) {
      row.slip_sign = mem.slip_sign;
    } else {
      row.slip_sign = std::abs(g.vt) > v_eps ? (g.vt > 0 ? 1 : -1) : 0;
    }
    if (row.mu == 0) row.slip_sign = 0;
    ws.active.push_back(static_cast<int>(i));
    ws.rows.push_back(row);
  }
  const int k = static_cast<int>(ws.active.size());
  growTo(&ws.b, 2 * k);
  for (int i = 0; i < k; ++i) {
    const ContactGeom& g = ws.geoms[ws.active[i]];
    const Vec2 drift = contactVelocityDrift(m, d.z, d.u, dr, g, &ws);
    double an = drift[0], at = drift[1];
    for (const BodyJac& s : g.side) {
      if (s.body < 0 || s.w_n.size() == 0) continue;
      const auto ab = ws.du.segment(bodyDofOffset(m, s.body), s.w_n.size());
      an += s.w_n.dot(ab);
      at += s.w_t.dot(ab);
    }
    ws.b[2 * i] = an;
    ws.b[2 * i + 1] = at;
  }
  if (!solveContactIslands(m, minv, &ws)) return false;
  for (int i = 0; i < k; ++i) {
    const ContactGeom& g = ws.geoms[ws.active[i]];
    const ContactRow& row = ws.rows[i];
    PairMemory& mem = ws.memory[pairKey(g.pair)];
    const double fn = ws.lambda[2 * i], ft = ws.lambda[2 * i + 1];
    const ContactState before = mem.state;
    if (row.normal_unknown && fn <= 0.0 && ws.y[2 * i] > 0.0) {
      // The normal multiplier vanished with a separating acceleration: the contact opens.
      endEpisode(m, &d, &mem, g, t,
                 energyOf(m, d, d.z, d.u, dr.omega_radps) - d.stats.drive_work_J);
      continue;
    }
    if (row.mu == 0.0) {
      mem.slip_sign = 0;
      mem.state = std::abs(g.vt) > v_eps ? ContactState::kSlip : ContactState::kStick;
    } else if (row.slip_sign != 0) {
      mem.slip_sign = row.slip_sign;
      mem.state = ContactState::kSlip;
    } else if (std::abs(ft) < row.mu * fn * (1.0 - 1e-9)) {
      mem.slip_sign = 0;
      mem.state = ContactState::kStick;
    } else {
      // At the friction limit the contact slides the way the tangential acceleration points.
      mem.slip_sign = ft > 0 ? -1 : 1;
      mem.state = ContactState::kSlip;
    }
    if (before != mem.state && before != ContactState::kImpact)
      emitTransition(&d, g.pair, before, mem.state, t, g);
  }
  return true;
}

// Projects the state back onto closed rigid contacts (g = 0, dg/dt = 0) and sticking tangents
// (dg_T/dt = 0) after a step, so that constraint drift never accumulates. Gauss-Seidel: each
// contact is re-evaluated after the previous one's correction. Returns whether any correction
// was applied (the state is otherwise untouched).
bool projectConstraints(const Ctx& c, double t) {
  bool corrected = false;
  const Model& m = c.m;
  Workspace& ws = c.ws;
  Data& d = c.d;
  const Drive dr = driveAtTime(c, t);
  for (int pass = 0; pass < 3; ++pass) {
    for (size_t i = 0; i < ws.candidates.size(); ++i) {
      const PairMemory& mem = ws.memory[pairKey(ws.candidates[i])];
      if (!isActive(mem)) continue;
      const ContactParams& cp = m.contact[static_cast<int>(ws.candidates[i].kind)];
      const bool normal = cp.law == ContactLaw::kRigid && mem.closed;
      const bool tangent =
          mem.slip_sign == 0 && cp.friction > 0 && mem.state == ContactState::kStick;
      if (!normal && !tangent) continue;
      // This contact at the current (already corrected) state.
      ws.ed.memo.valid = false;  // the stations move
      ContactGeom g;
      const PairId& pair = ws.candidates[i];
      if (pair.kind == PairKind::kToothKernel)
        updateToothStations(m, d.z, dr.theta_rad, pair.a, &ws);
      evaluateContact(m, d.z, d.u, dr, pair, &ws, &g);
      // Minimal mass-weighted correction of this contact alone.
      const std::vector<MatX>* minv = toothInverseMass(m, d.z, &ws);
      double gnn = 0, gtt = 0;
      for (const BodyJac& s : g.side) {
        if (s.body < 0 || s.w_n.size() == 0) continue;
        gnn += weightedDot(m, minv, s.body, s.w_n, s.w_n);
        gtt += weightedDot(m, minv, s.body, s.w_t, s.w_t);
      }
      if (normal && gnn > 0) {
        corrected = true;
        for (const BodyJac& s : g.side) {
          applyInverseMass(m, minv, s.body, s.w_n, -g.gap_m / gnn, &d.z);
          applyInverseMass(m, minv, s.body, s.w_n, -g.vn / gnn, &d.u);
        }
      }
      if (tangent && gtt > 0) {
        corrected = true;
        for (const BodyJac& s : g.side) applyInverseMass(m, minv, s.body, s.w_t, -g.vt / gtt, &d.u);
      }
    }
  }
  return corrected;
}

// Number of kernels still on their pedicels.
long attachedCount(const Data& d) {
  return std::count(d.kernel_attached.begin(), d.kernel_attached.end(), 1);
}

// Size of the next trial step: bounded by the broad-phase margin over the fastest motion.
double motionBound(const Ctx& c) {
  double v = 1e-6;
  for (const ToothModel& tm : c.m.teeth)
    v = std::max(
        v, std::abs(c.d.omega_radps) * (c.m.drum.radius_m + tm.length_m) +
               (tm.n_modes == 0 ? 0.0
                : tm.beam_model == ToothBeamModel::kLargeDeflection
                    // |theta_dot| <= sum |q_dot_i| (|phi_i| <= 1), points within L of the root.
                    ? tm.length_m * c.d.u.segment(tm.dof_offset, tm.n_modes).lpNorm<1>()
                    : 30.0 * c.d.u.segment(tm.dof_offset, tm.n_modes).norm()));
  for (int i = 0; i < static_cast<int>(c.m.kernels.size()); ++i)
    v = std::max(v, kernelSpeedBound(c.m, c.d.u, i));
  return v;
}

// Arming of one event function over a step: off, fires on reaching zero, or fires on falling
// below its value at the step start.
enum class Arm : std::uint8_t { kOff, kAtZero, kBelowStart };

// Interior minimum of the cubic Hermite interpolant of a function over a step of length h [s],
// from its values g0, g1 and rates r0 < 0 < r1 at the ends: returns the value and sets s_min,
// the position in (0, 1) as a fraction of h.
double hermiteMinimum(double g0, double r0, double g1, double r1, double h, double* s_min) {
  // p(s) = c0 + c1 s + c2 s^2 + c3 s^3 on s in [0, 1].
  const double c1 = h * r0;
  const double c2 = 3.0 * (g1 - g0) - 2.0 * h * r0 - h * r1;
  const double c3 = 2.0 * (g0 - g1) + h * r0 + h * r1;
  // p'(0) < 0 < p'(1): bisection on p' (60 halvings, exact to round-off, deterministic).
  double lo = 0.0, hi = 1.0;
  for (int it = 0; it < 60; ++it) {
    const double s = 0.5 * (lo + hi);
    (c1 + s * (2.0 * c2 + 3.0 * c3 * s) < 0 ? lo : hi) = s;
  }
  *s_min = 0.5 * (lo + hi);
  return g0 + *s_min * (c1 + *s_min * (c2 + *s_min * c3));
}

// Rate of a compliant contact's normal force F = K delta^{3/2} (1 + chi d(delta)/dt) [N/s] at
// the state (z, u) at time t [s], for the geometry g and accelerations udot of a rhs() call at
// that state: dF/dt = K [3/2 delta^{1/2} delta' (1 + chi delta') + delta^{3/2} chi delta''],
// delta'' = -(w_N . udot + velocity drift). Zero where the force is zero (apart, or clamped:
// no adhesion).
double compliantForceRate(const Ctx& c, const ContactGeom& g, const PairMemory& mem, const VecX& z,
                          const VecX& u, const VecX& udot, double t) {
  const double delta_m = -g.gap_m;
  const double rate_mps = -g.vn;
  const double chi_spm =
      g.params->hc_damping_factor / std::max(mem.v_in_mps, c.m.hc_min_impact_speed_mps);
  if (delta_m <= 0.0 || (g.residual_mpN <= 0.0 && 1.0 + chi_spm * rate_mps <= 0.0)) return 0.0;
  // Normal relative acceleration: the Jacobians times the accelerations, plus the drift.
  double acc_mps2 = contactVelocityDrift(c.m, z, u, driveAtTime(c, t), g, &c.ws)[0];
  for (const BodyJac& s : g.side) {
    if (s.body < 0 || s.w_n.size() == 0) continue;
    acc_mps2 += s.w_n.dot(udot.segment(bodyDofOffset(c.m, s.body), s.w_n.size()));
  }
  if (g.residual_mpN > 0.0)  // the residual spring in series (static correction)
    return compliantNormalForceRate(g, mem.hertz_K, mem.v_in_mps, c.m.hc_min_impact_speed_mps,
                                    acc_mps2);
  const double sq = std::sqrt(delta_m);
  return mem.hertz_K *
         (1.5 * sq * rate_mps * (1.0 + chi_spm * rate_mps) - delta_m * sq * chi_spm * acc_mps2);
}

// Whether a pair is in compliant contact.
bool inCompliantContact(const ContactGeom& g, const PairMemory& mem) {
  return isActive(mem) && g.params->law == ContactLaw::kCompliant;
}

// Normal force [N] and its rate [N/s] of every pair in compliant contact, from the last rhs()
// call, made at the state (z, u) at time t [s] with accelerations udot (ws.geoms, ws.ed.fn), into
// f and r (per geom, zero for other pairs); `on` flags those pairs. Returns whether there is any.
bool compliantForceSnapshot(const Ctx& c, double t, const VecX& z, const VecX& u, const VecX& udot,
                            std::vector<double>* f, std::vector<double>* r,
                            std::vector<std::uint8_t>* on) {
  Workspace& ws = c.ws;
  const size_t n_geoms = ws.geoms.size();
  f->assign(n_geoms, 0.0);
  r->assign(n_geoms, 0.0);
  on->assign(n_geoms, 0);
  bool any = false;
  for (size_t i = 0; i < n_geoms; ++i) {
    const ContactGeom& g = ws.geoms[i];
    const PairMemory& mem = ws.memory[pairKey(g.pair)];
    if (!inCompliantContact(g, mem)) continue;
    any = true;
    (*on)[i] = 1;
    (*f)[i] = ws.ed.fn[i];
    (*r)[i] = compliantForceRate(c, g, mem, z, u, udot, t);
  }
  return any;
}

// Located maxima of the compliant normal forces over an accepted step of length h [s] from
// (t0, z0, u0) to (z1, u1), before the index sets are switched. A force that rises at the start
// and falls at the end of the step (values and rates from ws.ed.pk_* at both ends) has an
// interior maximum: the cubic Hermite interpolant predicts its time, one Dormand-Prince step from
// the start gives the state there, and the force and its rate at that state narrow the bracket,
// until the prediction matches the probed force to 1e-2 x tolerance (at most 4 probes). Every
// probed state's forces count for the peak statistics: in slip |F_T| = mu F_N peaks with F_N.
// (A sticking |F_T| is a multiplier without a closed-form rate: its peak stays sampled at step
// ends and at located events.) A maximum at a step boundary (a kink from an impact elsewhere)
// is an end value, recorded with the step.
// end_evaluated: the last rhs() call was at (z1, u1), so ws.geoms and ws.ed.udot_ev hold the end.
void locateForcePeaks(const Ctx& c, double t0, double h, const VecX& z0, const VecX& u0,
                      const VecX& z1, const VecX& u1, bool end_evaluated) {
  Workspace& ws = c.ws;
  double torque_unused = 0, err_unused = 0;
  // Values and rates at the step end.
  if (!end_evaluated &&
      !rhs(c, t0 + h, z1, u1, &ws.ed.udot_ev, &torque_unused, false, SeparatedPairs::kNone))
    return;
  std::vector<std::uint8_t>& on_end = ws.ed.pk_on_end;
  compliantForceSnapshot(c, t0 + h, z1, u1, ws.ed.udot_ev, &ws.ed.pk_f1, &ws.ed.pk_r1, &on_end);
  const size_t n_geoms = std::min(ws.ed.pk_on.size(), on_end.size());
  // The probe steps overwrite the step's contact impulses and drum torque impulse: kept here.
  bool saved = false;
  double torque_impulse_saved = 0;
  const double rel_tol = 1e-2 * c.m.integrator.tolerance;
  for (size_t i = 0; i < n_geoms; ++i) {
    if (!ws.ed.pk_on[i] || !on_end[i]) continue;
    // Bracket [a, b] of the step (from its start) with a rising and a falling end. A force at
    // zero at an end (the episode opens or closes there, where F ~ delta^{3/2} has a zero rate)
    // counts as rising from the start or falling to the end.
    double a = 0, b = h;
    double fa = ws.ed.pk_f0[i], ra = ws.ed.pk_r0[i], fb = ws.ed.pk_f1[i], rb = ws.ed.pk_r1[i];
    const bool rising = ra > 0 || (fa <= 0 && fb > 0);
    const bool falling = rb < 0 || (fb <= 0 && fa > 0);
    if (!(rising && falling)) continue;
    if (!saved) {
      ws.ed.imp_n_saved = ws.ed.imp_n;
      ws.ed.imp_t_saved = ws.ed.imp_t;
      torque_impulse_saved = ws.ed.torque_impulse;
      saved = true;
    }
    for (int probe = 0; probe < 4; ++probe) {
      // Predicted maximum of the Hermite cubic (the minimum of its negative).
      double s_max = 0;
      const double f_pred = -hermiteMinimum(-fa, -ra, -fb, -rb, b - a, &s_max);
      const double tp = a + s_max * (b - a);
      // The state there, one step from the start, and its forces.
      if (!dopriStep(c, t0, tp, z0, u0, &ws.ed.zt, &ws.ed.ut, &err_unused, &torque_unused) ||
          !rhs(c, t0 + tp, ws.ed.zt, ws.ed.ut, &ws.ed.pk_udot, &torque_unused, false,
               SeparatedPairs::kNone))
        break;
      const ContactGeom& g = ws.geoms[i];
      PairMemory& mem = ws.memory[pairKey(g.pair)];
      const double fp = ws.ed.fn[i];
      recordForce(c.m, &c.d, g, fp, ws.ed.ft[i], t0 + tp);
      mem.episode_peak_N = std::max(mem.episode_peak_N, fp);
      if (std::abs(f_pred - fp) <= rel_tol * fp) break;
      // Its rate; the bracket shrinks to the side where the force still rises.
      const double rp = compliantForceRate(c, g, mem, ws.ed.zt, ws.ed.ut, ws.ed.pk_udot, t0 + tp);
      if (rp > 0) {
        a = tp;
        fa = fp;
        ra = rp;
      } else if (rp < 0) {
        b = tp;
        fb = fp;
        rb = rp;
      } else {
        break;
      }
    }
  }
  if (saved) {
    ws.ed.imp_n = ws.ed.imp_n_saved;
    ws.ed.imp_t = ws.ed.imp_t_saved;
    ws.ed.torque_impulse = torque_impulse_saved;
  }
}

// Whether an event function armed as `arm` has fired at value v (v0: its value at the step
// start), and its signed distance from firing (> 0 before, <= 0 once fired; kBelowStart:
// v - v0, which is 0 at the start itself).
bool armFires(Arm arm, double v, double v0) {
  return arm == Arm::kAtZero ? v <= 0 : arm == Arm::kBelowStart && v < v0;
}
double armValue(Arm arm, double v, double v0) { return arm == Arm::kAtZero ? v : v - v0; }

// Earliest crossing in (lo, hi) of the armed functions that fired at hi, by linear
// interpolation of their values (v_lo, v_hi) weighted by (w_lo, w_hi); *sel receives the
// function. The midpoint (and *sel = -1) where a fired function has no positive value at lo
// (armed below its start, at the start itself) or no crossing inside.
double earliestCrossing(const Workspace& ws, double lo, double hi, const std::vector<double>& v_lo,
                        const std::vector<double>& v_hi, double w_lo, double w_hi, int* sel) {
  const std::vector<double>& ev0 = ws.ed.ev0;
  double x = hi;
  *sel = -1;
  for (size_t i = 0; i < v_hi.size(); ++i) {
    const Arm a = static_cast<Arm>(ws.ed.arm[i]);
    if (a == Arm::kOff || !armFires(a, v_hi[i], ev0[i])) continue;
    const double f_lo = w_lo * armValue(a, v_lo[i], ev0[i]);
    const double f_hi = w_hi * armValue(a, v_hi[i], ev0[i]);
    if (!(f_lo > 0) || !(f_lo - f_hi > 0)) {
      *sel = -1;
      return 0.5 * (lo + hi);
    }
    const double xi = lo + (hi - lo) * (f_lo / (f_lo - f_hi));
    if (xi < x) {
      x = xi;
      *sel = static_cast<int>(i);
    }
  }
  if (!(x > lo)) {
    *sel = -1;
    return 0.5 * (lo + hi);
  }
  return x;
}

// Locates the first event of a step from the data's time: some armed function (ws.ed.arm,
// values ws.ed.ev0 at the start) has fired at step length hi_s (values ev_hi; its state, impulses
// and torque impulse in ws.ed.z_hi, ...) and none at 0. Narrows the bracket [lo, hi] until
// hi - lo <= t_tol by re-stepping from the start: Illinois regula falsi on the function
// that fired earliest by linear interpolation, bisection when a fired function has no positive
// value at lo (an armed-below-start function at the start) or the bracket stopped halving;
// trial points keep t_tol / 2 from the ends so that the bracket closes from both sides. Sets
// *h_take to hi, with its state in ws.ed.z_hi, ws.ed.u_hi, ws.ed.imp_n_hi, ws.ed.imp_t_hi,
// ws.ed.torque_impulse_hi and its values in ws.ed.ev_hi; returns whether the last evaluation
// (ws.geoms, forces) was at hi.
bool locateEvent(const Ctx& c, double hi_s, const std::vector<double>& ev_hi, double t_tol,
                 double* h_take) {
  Workspace& ws = c.ws;
  const std::vector<double>& ev0 = ws.ed.ev0;
  const std::vector<std::uint8_t>& arm = ws.ed.arm;
  std::vector<double>& v_lo = ws.ed.ev_lo;
  std::vector<double>& v_hi = ws.ed.ev_hi;
  std::vector<double>& v_mid = ws.ed.evm;
  v_lo = ev0;
  v_hi = ev_hi;
  double lo = 0, hi = hi_s;
  double w_lo = 1, w_hi = 1;  // Anderson-Bjorck weights of the end values
  int kept = 0;               // +1: lo kept by the last step, -1: hi kept, 0: neither yet
  double width_before[3] = {kInf, kInf, kInf};  // bracket widths one to three steps back
  bool at_hi = true;
  double err, tq;
  for (int it = 0; it < 80 && hi - lo > t_tol; ++it) {
    // Trial point: the earliest linear-interpolated crossing of the fired functions.
    int sel = -1;  // the function that gave it
    double x = hi - lo > 0.5 * width_before[2]
                   ? 0.5 * (lo + hi)
                   : earliestCrossing(ws, lo, hi, v_lo, v_hi, w_lo, w_hi, &sel);
    x = std::clamp(x, lo + 0.5 * t_tol, hi - 0.5 * t_tol);
    width_before[2] = width_before[1];
    width_before[1] = width_before[0];
    width_before[0] = hi - lo;
    dopriStep(c, c.d.t_s, x, c.d.z, c.d.u, &ws.ed.zt, &ws.ed.ut, &err, &tq);
    eventValues(c, c.d.t_s + x, ws.ed.zt, ws.ed.ut, &v_mid);
    bool fired = false;
    for (size_t i = 0; i < v_mid.size() && v_mid.size() == ev0.size() && !fired; ++i)
      fired = armFires(static_cast<Arm>(arm[i]), v_mid[i], ev0[i]);
    // Anderson-Bjorck: an end kept twice in a row has its value scaled by 1 - f_new / f_old
    // (of the replaced end; 1/2 where that is not positive or no function was selected).
    auto scale = [&](const std::vector<double>& v_old) {
      if (sel < 0 || v_mid.size() != ev0.size()) return 0.5;
      const Arm a = static_cast<Arm>(arm[sel]);
      const double ratio = armValue(a, v_mid[sel], ev0[sel]) / armValue(a, v_old[sel], ev0[sel]);
      const double m = 1.0 - ratio;
      return m > 0 && m < 1 ? m : 0.5;
    };
    if (fired) {
      if (kept == 1) w_lo *= scale(v_hi);
      hi = x;
      v_hi = v_mid;
      ws.ed.z_hi = ws.ed.zt;
      ws.ed.u_hi = ws.ed.ut;
      ws.ed.imp_n_hi = ws.ed.imp_n;
      ws.ed.imp_t_hi = ws.ed.imp_t;
      ws.ed.torque_impulse_hi = ws.ed.torque_impulse;
      w_hi = 1;
      kept = 1;
    } else {
      if (kept == -1) w_hi *= scale(v_lo);
      lo = x;
      v_lo = v_mid;
      w_lo = 1;
      kept = -1;
    }
    at_hi = fired;
  }
  *h_take = hi;
  return at_hi;
}
// ---------------------------------------------------------------------------------------------
// The step's stages (eventDrivenStep below calls them in order).

// What one event-driven step carries from stage to stage.
struct StepPlan {
  double t_end_s = 0;         // the advanceTo call's target time [s]
  double margin_m = 0;        // broad-phase margin: the step cannot outrun it [m]
  double h_s = 0;             // trial step length, then the accepted one [s]
  double h_wanted_s = 0;      // the step-size proposal before truncation at t_end [s]
  bool truncated = false;     // h_s was cut short to land on t_end_s
  bool rejected = false;      // some trial step was rejected
  double h_next_s = 0;        // the step-size law's proposal for the next step [s]
  bool peaks_on = false;      // compliant force peaks are located over this step
  bool event = false;         // an event function fired over the step
  double h_take_s = 0;        // the step taken: h_s, or the located event [s]
  double h_fired_s = 0;       // a step length at whose end an event is known to have fired [s]
  bool end_evaluated = true;  // the last rhs() call was at the step's end state
};

// Whether any armed function fired at values b (ws.ed.arm, start values ws.ed.ev0); function
// `deep` (if given) only counts when it went below -depth.
bool anyFired(const Workspace& ws, const std::vector<double>& b, size_t deep = SIZE_MAX,
              double depth = 0) {
  if (b.size() != ws.ed.ev0.size()) return false;
  for (size_t i = 0; i < b.size(); ++i)
    if (armFires(static_cast<Arm>(ws.ed.arm[i]), i == deep ? b[i] + depth : b[i], ws.ed.ev0[i]))
      return true;
  return false;
}

// Stage 1: the candidate pairs for this step, by the broad phase with a margin the step cannot
// outrun; contacts that left the candidate set are separated (their episodes end).
void prepareCandidates(const Ctx& c, StepPlan* plan) {
  const Model& m = c.m;
  Data* d = &c.d;
  Workspace& ws = c.ws;
  // A time step since the last event-driven one rewrote the geometry and forces.
  if (ws.ts.in_contact_step != -2) ws.ed.memo.valid = false;
  ws.ts.in_contact_step = -2;  // time stepping's list of pairs in contact is stale from here
  plan->margin_m = std::max(m.broadphase_margin_m, 1e-6);
  // (Stations only of the teeth that a kernel can reach: evaluateAll computes what it needs.)
  layoutStations(m, &ws);
  broadPhase(m, d->z, 2.0 * plan->margin_m, &ws, &d->theta_rad);
  for (const PairId& p : ws.candidates) ws.memory[pairKey(p)];
  for (auto& kv : ws.memory) kv.second.seen = false;
  for (const PairId& p : ws.candidates) ws.memory[pairKey(p)].seen = true;
  for (auto& kv : ws.memory) {
    PairMemory& mem = kv.second;
    if (mem.seen || !isActive(mem)) continue;
    ContactGeom g;
    g.pair = PairId{static_cast<PairKind>(kv.first >> 60),
                    static_cast<int>((kv.first >> 30) & 0x3fffffff),
                    static_cast<int>(kv.first & 0x3fffffff)};
    g.params = &m.contact[static_cast<int>(g.pair.kind)];
    endEpisode(m, d, &mem, g, d->t_s, mechanicalEnergy(m, *d) - d->stats.drive_work_J);
  }
}

// Stage 2: pairs touching at the start of the step without being in contact (a scene that
// starts at rest on a plate, a reset, a contact closed by the previous event) begin a contact
// now, unless they are separating.
void openTouchingContacts(const Ctx& c) {
  const Model& m = c.m;
  Data* d = &c.d;
  Workspace& ws = c.ws;
  const Drive dr0 = driveAtTime(c, d->t_s);
  // (The last step's end, evaluated by its statistics, is this state.)
  if (!rhsMemoHit(c, dr0, d->z, d->u, SeparatedPairs::kNear, 0.0)) evaluateAll(c, d->z, d->u, dr0);
  bool rigid_touch = false, any_touch = false;
  double e_net = kInf;  // energy minus drive work, computed when a contact begins
  for (size_t i = 0; i < ws.geoms.size(); ++i) {
    const ContactGeom& g = ws.geoms[i];
    PairMemory& mem = ws.memory[pairKey(g.pair)];
    if (isActive(mem) || g.far || g.gap_m > 0.0 || g.vn > 0.0) continue;
    any_touch = true;
    if (g.params->law == ContactLaw::kRigid) {
      rigid_touch = true;
    } else {
      if (e_net == kInf) e_net = mechanicalEnergy(m, *d) - d->stats.drive_work_J;
      mem.v_in_mps = -g.vn;
      mem.hertz_K = g.hertz_K;
      beginEpisode(m, d, &mem, g, d->t_s, e_net);
      mem.state = ContactState::kImpact;
      mem.slip_sign = 0;
      emitTransition(d, g.pair, ContactState::kSeparated, ContactState::kImpact, d->t_s, g);
    }
  }
  if (rigid_touch) solveImpact(c, d->t_s, false);
  if (any_touch && !updateModes(c, d->t_s, {})) {
    solveImpact(c, d->t_s, true);
    if (!updateModes(c, d->t_s, {})) ++d->stats.numerical_recoveries;
  }
}

// Stage 3: the trial step length: the last proposal, within max_step and the broad-phase
// margin over the motion bound, cut short to land on t_end or on the end of a drum ramp.
void planStep(const Ctx& c, double v_bound_mps, StepPlan* plan) {
  const Model& m = c.m;
  const Data& d = c.d;
  double h = c.ws.ed.h > 0 ? c.ws.ed.h : std::min(m.integrator.max_step_s, 1e-6);
  h = std::min({h, m.integrator.max_step_s, plan->margin_m / v_bound_mps});
  // A step cut short to land on t_end (or on the end of a drum ramp) must not shrink the
  // step-size proposal for the steps after it.
  plan->h_wanted_s = h;
  h = std::min(h, plan->t_end_s - d.t_s);
  plan->truncated = h < plan->h_wanted_s;
  const double ramp = timeToTarget(m, d);
  if (ramp > 1e-15 && ramp < h) h = ramp;
  if (!(h > 0)) h = plan->t_end_s - d.t_s;
  plan->h_s = h;
}

// Stage 4: event values at the start of the step, and which of them are armed over it. A
// function positive at the start fires when it reaches zero. A gap function at or below zero
// whose rate points to positive (a pair that just bounced apart, a compliant contact that just
// closed) is armed as well: it fires when it falls below its start value again, so that a
// flight shorter than the step is not seen one step late, inside the plate.
void armEvents(const Ctx& c, StepPlan* plan) {
  Workspace& ws = c.ws;
  const Data& d = c.d;
  eventValues(c, d.t_s, d.z, d.u, &ws.ed.ev0, &ws.ed.rate0, plan->h_s);
  // Compliant normal forces and their rates at the start, for the located peaks.
  plan->peaks_on = compliantForceSnapshot(c, d.t_s, d.z, d.u, ws.ed.udot_ev, &ws.ed.pk_f0,
                                          &ws.ed.pk_r0, &ws.ed.pk_on);
  const std::vector<double>& ev0 = ws.ed.ev0;
  ws.ed.arm.assign(ev0.size(), static_cast<std::uint8_t>(Arm::kOff));
  for (size_t i = 0; i < ev0.size(); ++i) {
    if (ev0[i] > 0) {
      ws.ed.arm[i] = static_cast<std::uint8_t>(Arm::kAtZero);
    } else if (ws.ed.rate0[i] > 0) {  // NaN (rate unknown) stays off
      ws.ed.arm[i] = static_cast<std::uint8_t>(Arm::kBelowStart);
    }
  }
}

// The step-size law: the factor by which a step with error norm err (1 = the tolerance) is
// scaled, for a retry (err > 1) or for the next step (err <= 1).
double retryFactor(double err) {
  return std::max(0.1, 0.9 * std::pow(std::isfinite(err) ? err : 1e10, -0.2));
}
double growthFactor(double err) {
  return std::min(5.0, 0.9 * std::pow(std::max(err, 1e-10), -0.2));
}

// Stage 5: adaptive Dormand-Prince steps from the step start until the error is within the
// tolerance; the end state in ws.ed.z1, ws.ed.u1. False after too many rejections.
bool integrateAdaptive(const Ctx& c, StepPlan* plan) {
  Workspace& ws = c.ws;
  Data* d = &c.d;
  const int n = c.m.n_dof;
  ws.ed.udot_end.resize(n);
  ws.ed.z1.resize(n);
  ws.ed.u1.resize(n);
  double err = 0, torque1 = 0;
  double& h = plan->h_s;
  for (int attempt = 0;; ++attempt) {
    if (!dopriStep(c, d->t_s, h, d->z, d->u, &ws.ed.z1, &ws.ed.u1, &err, &torque1)) err = kInf;
    if (err <= 1.0) break;
    plan->rejected = true;
    ++d->stats.rejected_steps;
    h *= retryFactor(err);
    if (h < 1e-15 || attempt > 200) return false;
  }
  plan->h_next_s = h * growthFactor(err);
  return true;
}

// Stage 6a: grazes. A separated pair whose gap falls and rises again within the step shows no
// sign change at the ends. The cubic Hermite interpolant of the gap (values and rates at both
// ends) predicts the interior minimum; where it comes near zero the state there is computed (a
// step from the start) and the gap checked. A dip counts once it is deeper than the position
// error scale of the integrator (tolerance x 1e-2 m): shallower ones are below what the step
// resolves, and a path that exactly touches gives no contact.
void detectGrazes(const Ctx& c, StepPlan* plan) {
  Workspace& ws = c.ws;
  const Data& d = c.d;
  const std::vector<double>& ev0 = ws.ed.ev0;
  const std::vector<double>& ev1 = ws.ed.ev1;
  const double h = plan->h_s;
  const double depth_m = c.m.integrator.tolerance * 1e-2;
  double et, tq;
  for (size_t i = 0; i < ws.geoms.size() && !plan->event; ++i) {
    const size_t j = 4 * i;
    if (static_cast<Arm>(ws.ed.arm[j]) != Arm::kAtZero ||
        isActive(ws.memory[pairKey(ws.geoms[i].pair)]))
      continue;
    if (!(ws.ed.rate0[j] < 0 && ws.ed.rate1[j] > 0)) continue;  // no interior minimum
    double s_min = 0;
    const double g_min = hermiteMinimum(ev0[j], ws.ed.rate0[j], ev1[j], ws.ed.rate1[j], h, &s_min);
    if (!(g_min < std::max(depth_m, 1e-3 * (ev0[j] + ev1[j])))) continue;
    // The probe step overwrites the step's contact impulses and drum torque impulse; they are
    // restored unless the event is confirmed (then the located step recomputes them).
    ws.ed.imp_n_saved = ws.ed.imp_n;
    ws.ed.imp_t_saved = ws.ed.imp_t;
    const double torque_impulse_saved = ws.ed.torque_impulse;
    plan->end_evaluated = false;
    dopriStep(c, d.t_s, s_min * h, d.z, d.u, &ws.ed.zt, &ws.ed.ut, &et, &tq);
    eventValues(c, d.t_s + s_min * h, ws.ed.zt, ws.ed.ut, &ws.ed.evm);
    if (anyFired(ws, ws.ed.evm, j, depth_m)) {
      plan->event = true;
      plan->h_fired_s = s_min * h;
    } else {
      ws.ed.imp_n = ws.ed.imp_n_saved;
      ws.ed.imp_t = ws.ed.imp_t_saved;
      ws.ed.torque_impulse = torque_impulse_saved;
    }
  }
}

// Stage 6: did any event function fire over the step (a sign change at the end, or a graze
// inside)?
void detectEvents(const Ctx& c, StepPlan* plan) {
  Workspace& ws = c.ws;
  const int n = c.m.n_dof;
  eventValues(c, c.d.t_s + plan->h_s, ws.ed.z1, ws.ed.u1, &ws.ed.ev1, &ws.ed.rate1, plan->h_s);
  plan->h_take_s = plan->h_s;
  plan->h_fired_s = plan->h_s;
  plan->event = anyFired(ws, ws.ed.ev1);
  ws.ed.zt.resize(n);
  ws.ed.ut.resize(n);
  plan->end_evaluated = true;
  if (!plan->event && ws.ed.ev1.size() == ws.ed.ev0.size()) detectGrazes(c, plan);
}

// Stage 7: the first crossing (re-stepping from the start each time) to the tolerance, from
// the values at the fired end (ws.ed.ev1, or the graze probe's); the step's end state, impulses
// and end values become the located ones.
void locateFirstEvent(const Ctx& c, StepPlan* plan) {
  Workspace& ws = c.ws;
  const double t_tol = std::max(1e-15, 1e-3 * c.m.integrator.tolerance * 1e-3);
  const bool at_end = plan->h_fired_s == plan->h_s;
  ws.ed.z_hi = at_end ? ws.ed.z1 : ws.ed.zt;
  ws.ed.u_hi = at_end ? ws.ed.u1 : ws.ed.ut;
  ws.ed.imp_n_hi = ws.ed.imp_n;  // the step's, or the confirmed graze probe's
  ws.ed.imp_t_hi = ws.ed.imp_t;
  ws.ed.torque_impulse_hi = ws.ed.torque_impulse;
  const bool at_hi =
      locateEvent(c, plan->h_fired_s, at_end ? ws.ed.ev1 : ws.ed.evm, t_tol, &plan->h_take_s);
  // The state at the located end, and its values (geometry and forces) unless the last
  // evaluation was there.
  ws.ed.z1 = ws.ed.z_hi;
  ws.ed.u1 = ws.ed.u_hi;
  ws.ed.imp_n = ws.ed.imp_n_hi;
  ws.ed.imp_t = ws.ed.imp_t_hi;
  ws.ed.torque_impulse = ws.ed.torque_impulse_hi;
  if (at_hi) {
    ws.ed.ev1 = ws.ed.ev_hi;
  } else {
    eventValues(c, c.d.t_s + plan->h_take_s, ws.ed.z1, ws.ed.u1, &ws.ed.ev1);
  }
  plan->end_evaluated = true;
}

// Stage 8: accept the step: the drive's work, then the state and the drum move to its end.
void acceptStep(const Ctx& c, const StepPlan& plan) {
  const Model& m = c.m;
  Data* d = &c.d;
  Workspace& ws = c.ws;
  const Drive mid = driveAt(m, *d, 0.5 * plan.h_take_s);
  const Drive end = driveAt(m, *d, plan.h_take_s);
  // (The start's momentum is the last step's end value unless something moved the state.)
  double H0 = 0, unused_energy = 0;
  if (!ws.ed.end_values.lookup(*d, &unused_energy, &H0))
    H0 = angularMomentumOf(m, d->z, d->u, d->omega_radps);
  const double H1 = angularMomentumOf(m, ws.ed.z1, ws.ed.u1, end.omega_radps);
  d->stats.drive_work_J += mid.omega_radps * (H1 - H0 - ws.ed.torque_impulse);
  const int n_geoms = static_cast<int>(ws.candidates.size());
  growTo(&ws.ed.imp_n_step, n_geoms);
  growTo(&ws.ed.imp_t_step, n_geoms);
  ws.ed.imp_n_step.head(n_geoms) = ws.ed.imp_n.head(n_geoms);
  ws.ed.imp_t_step.head(n_geoms) = ws.ed.imp_t.head(n_geoms);
  d->z = ws.ed.z1;
  d->u = ws.ed.u1;
  d->t_s = end.t_s;
  d->theta_rad = end.theta_rad;
  d->omega_radps = end.omega_radps;
  d->alpha_radps2 = end.alpha_radps2;
  ++d->steps;
  ws.ed.end_values.store(*d, 0.0, H1);
  if (!plan.event)
    ws.ed.h = plan.truncated && !plan.rejected && plan.h_next_s < plan.h_wanted_s ? plan.h_wanted_s
                                                                                  : plan.h_next_s;
}

// Stage 9: statistics of the forces over the accepted step (its end point), and the step's
// impulses added to the episodes; an impact under the compliant law becomes stick or slip.
void recordStepForces(const Ctx& c) {
  const Model& m = c.m;
  Data* d = &c.d;
  Workspace& ws = c.ws;
  const double t = d->t_s;
  double torque1 = 0;
  rhs(c, t, d->z, d->u, &ws.ed.udot_end, &torque1, true);
  const VecX& imp_n = ws.ed.imp_n_step;
  const VecX& imp_t = ws.ed.imp_t_step;
  for (size_t i = 0; i < ws.geoms.size(); ++i) {
    const ContactGeom& g = ws.geoms[i];
    PairMemory& mem = ws.memory[pairKey(g.pair)];
    if (!isActive(mem)) continue;
    recordForce(m, d, g, mem.normal_force_N, mem.tangential_force_N, t);
    mem.episode_peak_N = std::max(mem.episode_peak_N, mem.normal_force_N);
    mem.episode_impulse_n += imp_n[i];
    mem.episode_impulse_t += imp_t[i];
    mem.impulse_n_acc += imp_n[i];
    mem.impulse_t_acc += imp_t[i];
    d->stats.total_normal_impulse_Ns += imp_n[i];
    if (mem.state == ContactState::kImpact && g.params->law == ContactLaw::kCompliant)
      mem.state = mem.slip_sign == 0 ? ContactState::kStick : ContactState::kSlip;
  }
}

// Stage 10 for one pair: the transition of its index sets for the event functions that fired
// (gap j, normal force j + 1, friction limit or slip velocity j + 2). Sets *rigid_impact for a
// rigid pair that closed; adds a pair that starts to slip to forced_slip.
void switchPair(const Ctx& c, size_t i, double e_net, bool* rigid_impact,
                std::vector<int>* forced_slip) {
  const Model& m = c.m;
  Data* d = &c.d;
  Workspace& ws = c.ws;
  const double t = d->t_s;
  const size_t j = 4 * i;
  auto fired = [&](size_t k) {
    return armFires(static_cast<Arm>(ws.ed.arm[k]), ws.ed.ev1[k], ws.ed.ev0[k]);
  };
  const ContactGeom& g = ws.geoms[i];
  PairMemory& mem = ws.memory[pairKey(g.pair)];
  const bool fired0 = fired(j), fired1 = fired(j + 1), fired2 = fired(j + 2);
  if (!isActive(mem)) {
    if (!fired0 || g.vn >= 0) return;
    if (g.params->law == ContactLaw::kRigid) {
      *rigid_impact = true;
    } else {
      // Compliant: the contact opens with its approach speed fixing the damping.
      mem.v_in_mps = -g.vn;
      mem.hertz_K = g.hertz_K;
      beginEpisode(m, d, &mem, g, t, e_net);
      mem.state = ContactState::kImpact;
      mem.slip_sign = 0;
      emitTransition(d, g.pair, ContactState::kSeparated, ContactState::kImpact, t, g);
    }
  } else if (g.params->law == ContactLaw::kCompliant && (fired0 || fired1)) {
    endEpisode(m, d, &mem, g, t, e_net);
  } else if (g.params->law == ContactLaw::kRigid && fired0) {
    endEpisode(m, d, &mem, g, t, e_net);
  } else if (fired2) {
    if (mem.slip_sign == 0) {
      // Stick -> slip against the friction force.
      mem.slip_sign = mem.tangential_force_N > 0 ? -1 : 1;
      forced_slip->push_back(static_cast<int>(i));
      emitTransition(d, g.pair, mem.state, ContactState::kSlip, t, g);
      mem.state = ContactState::kSlip;
    } else {
      // Slip velocity reached zero: stick or reverse, decided below.
      mem.slip_sign = 0;
    }
  }
}

// Stage 10: switch the index sets for every event function at or past zero; solve the rigid
// impacts; break the pedicels that reached their detachment force; new consistent modes.
void switchModes(const Ctx& c, const StepPlan& plan) {
  Data* d = &c.d;
  Workspace& ws = c.ws;
  if (!plan.event) {
    updatePedicels(c.m, d);
    return;
  }
  const double t = d->t_s;
  const double e_net = mechanicalEnergy(c.m, *d) - d->stats.drive_work_J;
  bool rigid_impact = false;
  std::vector<int>& forced_slip = ws.ed.forced_slip;
  forced_slip.clear();
  for (size_t i = 0; i < ws.geoms.size(); ++i) {
    const size_t j = 4 * i;
    if (static_cast<Arm>(ws.ed.arm[j]) == Arm::kOff &&
        static_cast<Arm>(ws.ed.arm[j + 1]) == Arm::kOff &&
        static_cast<Arm>(ws.ed.arm[j + 2]) == Arm::kOff)
      continue;
    switchPair(c, i, e_net, &rigid_impact, &forced_slip);
  }
  if (rigid_impact) solveImpact(c, t, false);
  updatePedicels(c.m, d);
  if (!updateModes(c, t, forced_slip)) {
    // Painleve: no consistent accelerations; a tangential (plastic) impact resolves it.
    solveImpact(c, t, true);
    if (!updateModes(c, t, forced_slip)) ++d->stats.numerical_recoveries;
  }
}

// Stage 11: the forces and geometry of the end state (the statistics' evaluation holds them
// unless an event, a broken pedicel or a projection changed the state or the index sets), and
// the contacts published to the data.
void finishStep(const Ctx& c, const StepPlan& plan, long attached_before) {
  Data* d = &c.d;
  Workspace& ws = c.ws;
  const bool projected = projectConstraints(c, d->t_s);
  double torque1 = 0;
  if (plan.event || projected || attached_before != attachedCount(*d))
    rhs(c, d->t_s, d->z, d->u, &ws.ed.udot_end, &torque1, true);
  publishContacts(d, &ws);
}

}  // namespace

// One event-driven step: from the data's time to the next event, the step-size law's step, or
// t_end_s, whichever comes first.
StepStatus eventDrivenStep(const Model& m, Data* d, double t_end_s) {
  Ctx c{m, *d, *d->ws};
  StepPlan plan;
  plan.t_end_s = t_end_s;
  const double v_bound_mps = motionBound(c);
  prepareCandidates(c, &plan);
  openTouchingContacts(c);
  planStep(c, v_bound_mps, &plan);
  armEvents(c, &plan);
  if (!integrateAdaptive(c, &plan)) return StepStatus::kFailed;
  detectEvents(c, &plan);
  if (plan.event) locateFirstEvent(c, &plan);
  // Located maxima of the compliant forces over the step, under the step's index sets.
  if (plan.peaks_on)
    locateForcePeaks(c, d->t_s, plan.h_take_s, d->z, d->u, c.ws.ed.z1, c.ws.ed.u1,
                     plan.end_evaluated);
  acceptStep(c, plan);
  recordStepForces(c);
  const long attached_before = attachedCount(*d);
  switchModes(c, plan);
  finishStep(c, plan, attached_before);
  return StepStatus::kOk;
}

}  // namespace internal
}  // namespace threshing_sim
