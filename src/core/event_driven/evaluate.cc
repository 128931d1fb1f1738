// The event-driven integrator (docs/model.md §7-9): the geometry of every candidate pair at a
// state, as much of it as the caller needs.
#include <algorithm>
#include <cmath>

#include "context.h"

namespace threshing_sim {
namespace internal {
namespace event_driven {

namespace {

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

// A bound of the speed of any point of tooth k at the velocities u [m/s]: the drum's turn of its
// tip and its modes' rate (as motionBound reads them).
double toothSpeedBound(const Ctx& c, const VecX& u, int k) {
  const ToothModel& tm = c.m.teeth[k];
  const double modal = tm.n_modes == 0 ? 0.0
                       : tm.beam_model == ToothBeamModel::kLargeDeflection
                           ? tm.length_m * u.segment(tm.dof_offset, tm.n_modes).lpNorm<1>()
                           : 30.0 * u.segment(tm.dof_offset, tm.n_modes).norm();
  return std::abs(c.d.omega_radps) * (c.m.drum.radius_m + tm.length_m) + modal;
}

// kReach: the relative speed bound of a pair's bodies at the velocities u [m/s].
double pairSpeedBound(const Ctx& c, const VecX& u, const PairId& p) {
  switch (p.kind) {
    case PairKind::kToothKernel:
      return kernelSpeedBound(c.m, u, p.b) + toothSpeedBound(c, u, p.a);
    case PairKind::kKernelKernel:
      return kernelSpeedBound(c.m, u, p.a) + kernelSpeedBound(c.m, u, p.b);
    default:
      return kernelSpeedBound(c.m, u, p.a);
  }
}

// kReach: whether a separated pair is still surely apart at t_s + horizon_s without an
// evaluation (conservative advancement): its last evaluation at or before t_s found it apart by
// a gap it cannot cover before PairMemory::cp_safe_until_s at its bodies' speed bound then,
// which their bound now does not exceed.
bool safelyApart(const PairMemory& mem, double t_s, double horizon_s, double speed_mps) {
  return mem.state == ContactState::kSeparated && t_s >= mem.cp_safe_from_s &&
         t_s + horizon_s < mem.cp_safe_until_s && speed_mps <= mem.cp_safe_speed_mps;
}

// kReach: after a separated pair's evaluation at t_s, the time until which it stays apart: 0.8
// of its gap over its speed bound with kSpeedHeadroom on it (none when touching or without a
// bound), so that the bound, which grows a little from step to step as a pile is pushed or a
// mode swings, does not void the interval at the next step.
void recordSafeInterval(const ContactGeom& g, double t_s, double speed_mps, PairMemory* mem) {
  constexpr double kSpeedHeadroom = 1.1;  // [-]
  const double speed = kSpeedHeadroom * speed_mps;
  mem->cp_safe_from_s = t_s;
  mem->cp_safe_speed_mps = speed;
  mem->cp_safe_gap_m = g.gap_m;
  mem->cp_safe_until_s =
      g.gap_m > 0.0 && speed > 0.0 && std::isfinite(g.gap_m) ? t_s + 0.8 * g.gap_m / speed : -kInf;
}

// The warm narrow phase (evaluateWarmToothKernel) of a tooth pair in contact (state) with a warm
// start x_warm_m [m] (< 0: none): true if it answered, *warm then receiving the closest point as
// evaluateContact's would; false: its guard doubts the warm answer, nothing decided.
bool evaluateWarm(const Ctx& c, const VecX& z, const VecX& u, const Drive& dr, const PairId& p,
                  ContactState state, double x_warm_m, ToothFrame* frame, ContactGeom* g,
                  double* warm) {
  if (x_warm_m < 0.0) return false;
  frame->update(c.m, p.a, dr.theta_rad);
  const bool apart_ok = state == ContactState::kSeparated;
  if (!evaluateWarmToothKernel(c.m, z, u, dr, p, *frame, x_warm_m, g, apart_ok)) return false;
  *warm = g->tooth_x_m;
  return true;
}

}  // namespace

// Evaluates every candidate pair at (z, u, t) into ws.geoms; separated pairs as `separated`
// says (a far pair gets only a lower bound of its gap). Under kSign, a separated kernel pair
// (kernel-obstacle, kernel-kernel) is evaluated exactly when its gap bound is within 1 um or
// within twice what its bodies can cover in horizon_s [s] at their present speeds: a pair
// whose gap falls to zero and rises again inside a step of that length (a spinning kernel
// grazing a wall) is then exact, with its rate, at both ends of the step, as the graze check
// needs; a pair beyond that reach cannot close within the step. kStepEnd: exact within the
// larger of the kSign and the kNear reaches.
void evaluateAll(const Ctx& c, const VecX& z, const VecX& u, const Drive& dr,
                 SeparatedPairs separated, double horizon_s) {
  c.ws.ed.memo.valid = false;  // ws.geoms and the stations change
  // Stations only of the teeth that have a candidate pair that will be evaluated (candidates
  // are sorted by kind, tooth pairs first, by tooth).
  // A tooth whose evaluated pairs are all in contact with a warm start (evaluateContact) needs
  // none: the warm start computes the two stations around its points itself.
  layoutStations(c.m, &c.ws);
  int last_tooth = -1;
  for (size_t i = 0; i < c.ws.candidates.size(); ++i) {
    const PairId& p = c.ws.candidates[i];
    if (p.kind != PairKind::kToothKernel) break;
    if (p.a == last_tooth) continue;
    const PairMemory& mem = candidateMemory(c.ws, i);
    const bool separated_pair = mem.state == ContactState::kSeparated;
    if (separated == SeparatedPairs::kNone && separated_pair) continue;
    if (separated == SeparatedPairs::kReach &&
        safelyApart(mem, dr.t_s, horizon_s, pairSpeedBound(c, u, p)))
      continue;
    if (!separated_pair && mem.warm_x_m >= 0.0 && c.m.teeth[p.a].n_modes > 0 &&
        c.m.teeth[p.a].beam_model == ToothBeamModel::kModal)
      continue;
    updateToothStations(c.m, z, dr.theta_rad, p.a, &c.ws);
    last_tooth = p.a;
  }
  c.ws.geoms.resize(c.ws.candidates.size());
  const double near_m = 0.25 * c.m.broadphase_margin_m;
  // The contact phase's step ends (kReach): tooth pairs in contact take the warm narrow phase.
  const bool fast_warm = separated == SeparatedPairs::kReach;
  ToothFrame frame;  // the warm pairs' tooth frame, recomputed when the tooth changes
  for (size_t i = 0; i < c.ws.candidates.size(); ++i) {
    const PairId& p = c.ws.candidates[i];
    ContactGeom& g = c.ws.geoms[i];
    double far_m = kInf;
    bool tight = false;
    double reach_speed_mps = -1.0;  // kReach, a separated pair: its speed bound [m/s]
    PairMemory& mem = candidateMemory(c.ws, i);
    // Tooth pairs in contact start the narrow phase from their last closest point (moved on
    // in time by the rate between the last two); a separated one records its closest point for
    // when its contact begins.
    double x_warm = -1;
    double* warm = p.kind == PairKind::kToothKernel ? &x_warm : nullptr;
    if (warm && mem.state != ContactState::kSeparated) x_warm = warmStart(c.m, mem, p, dr.t_s);
    // A separated tooth pair within reach at the contact phase's step ends starts from its last
    // closest point too (evaluateWarm: where the distance has a single minimum).
    double x_apart = -1;
    if (warm && fast_warm && mem.state == ContactState::kSeparated)
      x_apart = warmStart(c.m, mem, p, dr.t_s);
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
      if (separated == SeparatedPairs::kReach) {
        reach_speed_mps = pairSpeedBound(c, u, p);
        if (safelyApart(mem, dr.t_s, horizon_s, reach_speed_mps)) {
          g.pair = p;  // not evaluated: marked far with its last bound
          g.params = &c.m.contact[static_cast<int>(p.kind)];
          g.far = true;
          g.gap_m = mem.cp_safe_gap_m;
          continue;
        }
        far_m = std::max(1e-6, 2.0 * horizon_s * reach_speed_mps);
      } else if ((separated == SeparatedPairs::kSign || separated == SeparatedPairs::kStepEnd) &&
                 !tooth) {
        double speed_mps = kernelSpeedBound(c.m, u, p.a);
        if (p.kind == PairKind::kKernelKernel) speed_mps += kernelSpeedBound(c.m, u, p.b);
        far_m = std::max(1e-6, 2.0 * horizon_s * speed_mps);
        if (separated == SeparatedPairs::kStepEnd) far_m = std::max(far_m, near_m);
      } else {
        far_m = near_m;
      }
      tight = !tooth;  // kernel and obstacle pairs: the supporting-line bound
    }
    double* warm_theta = p.kind == PairKind::kKernelKernel ? &mem.warm_theta_rad : nullptr;
    const double x_start = mem.state == ContactState::kSeparated ? x_apart : x_warm;
    if (!(fast_warm && warm && evaluateWarm(c, z, u, dr, p, mem.state, x_start, &frame, &g, warm)))
      evaluateContact(c.m, z, u, dr, p, &c.ws, &g, far_m, tight, warm, warm_theta);
    if (reach_speed_mps >= 0.0) recordSafeInterval(g, dr.t_s, reach_speed_mps, &mem);
    if (warm && !g.far) {
      mem.warm_x_prev_m = mem.warm_x_m;
      mem.warm_t_prev_s = mem.warm_t_s;
      mem.warm_x_m = g.tooth_x_m;
      mem.warm_t_s = dr.t_s;
    }
  }
}

}  // namespace event_driven
}  // namespace internal
}  // namespace threshing_sim
