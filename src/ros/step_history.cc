// Accepted steps' states and their interpolant (step_history.h).
#include "threshing_sim/ros/step_history.h"

#include <algorithm>
#include <utility>

namespace threshing_sim {

void copyStepState(const Data& data, StepState* s) {
  s->t_s = data.t_s;
  s->theta_rad = data.theta_rad;
  s->omega_radps = data.omega_radps;
  s->z = data.z;
  s->u = data.u;
  s->contacts = data.contacts;
  s->closed = std::any_of(data.contacts.begin(), data.contacts.end(), [](const ContactInfo& c) {
    return c.pair.kind == PairKind::kToothKernel && c.state != ContactState::kSeparated;
  });
}

void interpolateStep(const StepState& a, const StepState& b, double t_s, FrameState* out) {
  const double h_s = b.t_s - a.t_s;
  // Cubic Hermite on positions with their derivatives u = dz/dt (drum: theta, omega).
  const double x = (t_s - a.t_s) / h_s, x2 = x * x, x3 = x2 * x;
  const double h00 = 2 * x3 - 3 * x2 + 1, h10 = x3 - 2 * x2 + x, h01 = 3 * x2 - 2 * x3,
               h11 = x3 - x2;
  out->t_s = t_s;
  out->z = h00 * a.z + (h10 * h_s) * a.u + h01 * b.z + (h11 * h_s) * b.u;
  out->u = (1 - x) * a.u + x * b.u;
  out->theta_rad =
      h00 * a.theta_rad + h10 * h_s * a.omega_radps + h01 * b.theta_rad + h11 * h_s * b.omega_radps;
  out->omega_radps = (1 - x) * a.omega_radps + x * b.omega_radps;
  // The contacts of the nearer step; a pair closed at both ends has its point and forces
  // interpolated.
  const StepState& near = x < 0.5 ? a : b;
  const StepState& far = x < 0.5 ? b : a;
  const double w = x < 0.5 ? x : 1 - x;  // weight of the far step
  out->contacts = near.contacts;
  for (ContactInfo& c : out->contacts) {
    const auto o = std::find_if(far.contacts.begin(), far.contacts.end(),
                                [&](const ContactInfo& f) { return f.pair == c.pair; });
    if (o == far.contacts.end() || c.state == ContactState::kSeparated ||
        o->state == ContactState::kSeparated)
      continue;
    c.p_W = (1 - w) * c.p_W + w * o->p_W;
    c.normal_force_N = (1 - w) * c.normal_force_N + w * o->normal_force_N;
    c.tangential_force_N = (1 - w) * c.tangential_force_N + w * o->tangential_force_N;
  }
}

void StepHistory::begin(const Data& data) {
  n_ = 0;
  add(data);
}

void StepHistory::add(const Data& data) {
  if (n_ > 0 && data.t_s < states_[n_ - 1].t_s) return;
  if (n_ > 0 && data.t_s == states_[n_ - 1].t_s) {
    copyStepState(data, &states_[n_ - 1]);
    return;
  }
  if (n_ == kCapacity) {
    // Full: keep states 0, 2, 4, ... (swaps: no allocation).
    std::size_t kept = 1;
    for (std::size_t i = 2; i < n_; i += 2) std::swap(states_[kept++], states_[i]);
    n_ = kept;
  }
  copyStepState(data, &states_[n_++]);
}

bool StepHistory::stateAt(double t_s, FrameState* out) const {
  if (n_ == 0 || t_s < states_[0].t_s || t_s > states_[n_ - 1].t_s) return false;
  // The first kept state at or after t_s.
  const auto it = std::lower_bound(states_.begin(), states_.begin() + n_, t_s,
                                   [](const StepState& s, double t) { return s.t_s < t; });
  const StepState& b = *it;
  if (b.t_s == t_s) {
    out->t_s = b.t_s;
    out->theta_rad = b.theta_rad;
    out->omega_radps = b.omega_radps;
    out->z = b.z;
    out->u = b.u;
    out->contacts = b.contacts;
    return true;
  }
  const StepState& a = *(it - 1);
  if (a.z.size() != b.z.size()) return false;
  interpolateStep(a, b, t_s, out);
  return true;
}

}  // namespace threshing_sim
