// The event-driven integrator: the memo of the last right-hand side (RhsMemo), so that a call
// with the same inputs reuses its results.
#include <cstring>

#include "context.h"

namespace threshing_sim {
namespace internal {
namespace event_driven {

namespace {

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

}  // namespace

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
  // kNear, kSign and kStepEnd differ only on separated kernel-kernel and kernel-obstacle pairs
  // (tooth pairs are evaluated alike, whatever the horizon). A step end over a horizon serves
  // kNear and kSign or kStepEnd over a horizon up to it: it evaluates exactly every pair those
  // do (and perhaps more: their exact gaps are positive beyond either reach).
  const bool memo_none = mm.separated == static_cast<int>(SeparatedPairs::kNone);
  const bool memo_end = mm.separated == static_cast<int>(SeparatedPairs::kStepEnd);
  const bool served_by_end =
      memo_end && (separated == SeparatedPairs::kNear || horizon_s <= mm.horizon_s);
  const bool mode_ok =
      separated == SeparatedPairs::kNone || mm.n_separated == 0 ||
      (!memo_none && (mm.n_separated_other == 0 || served_by_end ||
                      (static_cast<int>(separated) == mm.separated &&
                       (separated != SeparatedPairs::kSign || horizon_s == mm.horizon_s))));
  if (!mode_ok || !bitsEqual(z, mm.z) || !bitsEqual(u, mm.u) ||
      c.d.kernel_attached != mm.attached || c.ws.candidates != mm.candidates ||
      c.ws.geoms.size() != c.ws.candidates.size())
    return false;
  for (size_t i = 0; i < mm.candidates.size(); ++i) {
    const RhsMemo::PairState p = pairStateOf(candidateMemory(c.ws, i));  // (the same list)
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
    mm.pairs[i] = pairStateOf(candidateMemory(c.ws, i));
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

}  // namespace event_driven
}  // namespace internal
}  // namespace threshing_sim
