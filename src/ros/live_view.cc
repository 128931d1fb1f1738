#include "threshing_sim/ros/live_view.h"

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>

namespace threshing_sim {

double StrikeRecord::peakNormalForce() const {
  const double sampled_N = normal_force_N.empty()
                               ? 0.0
                               : *std::max_element(normal_force_N.begin(), normal_force_N.end());
  return std::max(sampled_N, core_peak_normal_force_N);
}

double StrikeRecord::peakTime() const {
  if (normal_force_N.empty()) return -1;
  return t_s[std::max_element(normal_force_N.begin(), normal_force_N.end()) -
             normal_force_N.begin()];
}

bool StrikeRecorder::strikeNear(const Data& data, double horizon_s) {
  for (const ContactInfo& c : data.contacts) {
    if (c.pair.kind != PairKind::kToothKernel) continue;
    if (c.state != ContactState::kSeparated) return true;
    // Closing (normal velocity < 0) and reaching zero gap within the horizon.
    if (c.gap_m <= 0 || c.gap_m < -c.normal_velocity_mps * horizon_s) return true;
  }
  return false;
}

void StrikeRecorder::sample(const Data& data) {
  // Mark the open episodes that are still closed now.
  std::map<std::pair<int, int>, bool> closed_now;
  for (const ContactInfo& c : data.contacts) {
    if (c.pair.kind != PairKind::kToothKernel) continue;
    const std::pair<int, int> key(c.pair.a, c.pair.b);
    if (c.state == ContactState::kSeparated) {
      apart_sums_Ns_[key] = Vec2(c.impulse_normal_Ns, c.impulse_tangential_Ns);
      continue;
    }
    closed_now[key] = true;
    auto it = open_.find(key);
    if (it == open_.end()) {
      it = open_.emplace(key, Open()).first;
      it->second.record.tooth = c.pair.a;
      it->second.record.kernel = c.pair.b;
      it->second.record.sample_interval_s = sample_interval_s_;
      // The core's sums at the last sample the pair was apart (0: never seen apart).
      const auto apart = apart_sums_Ns_.find(key);
      if (apart != apart_sums_Ns_.end()) it->second.sums_at_start_Ns = apart->second;
    }
    StrikeRecord& r = it->second.record;
    r.normal_impulse_Ns = c.impulse_normal_Ns - it->second.sums_at_start_Ns.x();
    r.tangential_impulse_Ns = c.impulse_tangential_Ns - it->second.sums_at_start_Ns.y();
    if (!r.t_s.empty() && r.t_s.back() == data.t_s) continue;  // no new evaluation point
    if (r.t_s.size() >= kMaxSamples) {
      r.truncated = true;
      continue;
    }
    r.t_s.push_back(data.t_s);
    r.normal_force_N.push_back(c.normal_force_N);
    r.tangential_force_N.push_back(c.tangential_force_N);
    r.gap_m.push_back(c.gap_m);
  }
  for (auto it = open_.begin(); it != open_.end();) {
    if (closed_now.count(it->first)) {
      ++it;
      continue;
    }
    StrikeRecord& r = it->second.record;
    if (r.t_s.size() > 1) r.sample_interval_s = (r.t_s.back() - r.t_s.front()) / (r.t_s.size() - 1);
    // The core's peak of the episode, from its impact event (compliant: the whole episode).
    for (const ContactEvent& e : data.events)
      if (e.is_impact && e.pair.kind == PairKind::kToothKernel && e.pair.a == r.tooth &&
          e.pair.b == r.kernel && !r.t_s.empty() && e.t_s >= r.t_s.front())
        r.core_peak_normal_force_N = std::max(r.core_peak_normal_force_N, e.peak_normal_force_N);
    finished_.push_back(std::move(r));
    it = open_.erase(it);
  }
}

void KernelImpulses::clear() {
  last_sums_Ns_.clear();
  sums_.clear();
}

namespace {

// The kernel a contact acts on and the other body's kind; kernel-kernel pairs act on both.
void addToKernels(const ContactInfo& c, const std::function<void(int, int, double)>& add) {
  switch (c.pair.kind) {
    case PairKind::kToothKernel:
      add(c.pair.b, kByTooth, 1.0);
      break;
    case PairKind::kKernelObstacle:
      add(c.pair.a, kByObstacle, 1.0);
      break;
    default:  // the normal points from a to b: the force on a is the opposite
      add(c.pair.b, kByKernel, 1.0);
      add(c.pair.a, kByKernel, -1.0);
      break;
  }
}

}  // namespace

void KernelImpulses::update(const Model& model, const Data& data) {
  sums_.resize(model.kernels.size());
  for (const ContactInfo& c : data.contacts) {
    const Vec2 now_Ns(c.impulse_normal_Ns, c.impulse_tangential_Ns);
    Vec2& last_Ns = last_sums_Ns_.try_emplace(c.pair, Vec2::Zero()).first->second;
    Vec2 delta_Ns = now_Ns - last_Ns;
    // The core restarted its sums (a pair that left the broad phase and came back).
    if (std::abs(now_Ns.x()) < std::abs(last_Ns.x())) delta_Ns = now_Ns;
    last_Ns = now_Ns;
    if (delta_Ns.isZero()) continue;
    addToKernels(c, [&](int kernel, int kind, double sign) {
      if (kernel < 0 || kernel >= static_cast<int>(sums_.size())) return;
      sums_[kernel].normal_impulse_Ns[kind] += delta_Ns.x();
      sums_[kernel].tangential_impulse_Ns[kind] += sign * delta_Ns.y();
    });
  }
}

std::vector<KernelForces> KernelImpulses::forces(const Model& model, const Data& data) const {
  std::vector<KernelForces> out(model.kernels.size());
  for (size_t i = 0; i < out.size() && i < sums_.size(); ++i) {
    out[i].normal_impulse_Ns = sums_[i].normal_impulse_Ns;
    out[i].tangential_impulse_Ns = sums_[i].tangential_impulse_Ns;
  }
  for (const ContactInfo& c : data.contacts) {
    if (c.state == ContactState::kSeparated) continue;
    addToKernels(c, [&](int kernel, int kind, double sign) {
      if (kernel < 0 || kernel >= static_cast<int>(out.size())) return;
      out[kernel].normal_force_N[kind] += c.normal_force_N;
      out[kernel].tangential_force_N[kind] += sign * c.tangential_force_N;
    });
  }
  return out;
}

double contactLoadTorque(const std::vector<ContactInfo>& contacts) {
  double torque_Nm = 0;
  for (const ContactInfo& c : contacts) {
    if (c.pair.kind != PairKind::kToothKernel || c.state == ContactState::kSeparated) continue;
    const Vec2 t_W(-c.n_W.y(), c.n_W.x());
    const Vec2 f_W = c.normal_force_N * c.n_W + c.tangential_force_N * t_W;
    torque_Nm += c.p_W.x() * f_W.y() - c.p_W.y() * f_W.x();
  }
  return torque_Nm;
}

SceneExtent sceneExtent(const Model& model, const FeedSpec* feed) {
  double reach_m = model.drum.radius_m;
  for (const ToothModel& t : model.teeth)
    reach_m = std::max(reach_m, t.p_DR_D.norm() + t.length_m + 0.5 * t.diameter_m);
  SceneExtent e;
  e.min_m = Vec2(-reach_m, -reach_m);
  e.max_m = Vec2(reach_m, reach_m);
  auto include = [&](const Vec2& p, double r) {
    e.min_m = e.min_m.cwiseMin(p - Vec2(r, r));
    e.max_m = e.max_m.cwiseMax(p + Vec2(r, r));
  };
  // The concave (bars and segments near the drum); far obstacles and planes are left out.
  const double near_m = 2 * reach_m;
  for (const ObstacleModel& o : model.obstacles) {
    if (o.type == ObstacleType::kCircle && o.center_m.norm() < near_m)
      include(o.center_m, o.radius_m);
    if (o.type == ObstacleType::kSegment && o.point_m.norm() < near_m &&
        o.point_b_m.norm() < near_m) {
      include(o.point_m, o.radius_m);
      include(o.point_b_m, o.radius_m);
    }
  }
  for (const KernelModel& k : model.kernels)
    if (!k.pool_slot) include(k.initial_position_m, k.semi_axis_a_m);
  if (feed != nullptr) {
    include(Vec2(feed->inlet_x_m, feed->anchor_y_m), 0.0);
    include(Vec2(feed->exit_x_m, feed->grate_y_m), 0.0);
  }
  const double margin_m = 0.05 * std::max(e.size().x(), e.size().y());
  e.min_m -= Vec2(margin_m, margin_m);
  e.max_m += Vec2(margin_m, margin_m);
  return e;
}

namespace {

// timeToStrike for each kernel; *first receives the kernel with the least [s].
double timeToStrikeOf(const Model& model, const Data& data, int* first) {
  const double c_th = std::cos(data.theta_rad), s_th = std::sin(data.theta_rad);
  auto toWorld = [&](const Vec2& p_D) {
    return Vec2(c_th * p_D.x() - s_th * p_D.y(), s_th * p_D.x() + c_th * p_D.y());
  };
  double best_s = std::numeric_limits<double>::infinity();
  for (const ToothModel& tooth : model.teeth) {
    const Vec2 root_W = toWorld(tooth.p_DR_D);
    const Vec2 tip_W = toWorld(tooth.p_DR_D + tooth.length_m * tooth.e1_D);
    const double speed_mps =
        std::max(std::abs(data.omega_radps) * (tooth.p_DR_D.norm() + tooth.length_m), 1e-9);
    const Vec2 axis = tip_W - root_W;
    for (size_t i = 0; i < model.kernels.size(); ++i) {
      const Vec2 c = data.z.segment<2>(model.kernels[i].dof_offset);
      const double s = std::clamp((c - root_W).dot(axis) / axis.squaredNorm(), 0.0, 1.0);
      const double gap_m =
          (c - root_W - s * axis).norm() - model.kernels[i].semi_axis_a_m - 0.5 * tooth.diameter_m;
      const double t_s = std::max(gap_m, 0.0) / speed_mps;
      if (t_s < best_s) *first = static_cast<int>(i);
      best_s = std::min(best_s, t_s);
    }
  }
  return best_s;
}

}  // namespace

double timeToStrike(const Model& model, const Data& data) {
  for (const ContactInfo& c : data.contacts)
    if (c.pair.kind == PairKind::kToothKernel && c.state != ContactState::kSeparated) return 0;
  int first = -1;
  return timeToStrikeOf(model, data, &first);
}

Vec2 strikeFocus(const Model& model, const Data& data) {
  for (const ContactInfo& c : data.contacts)
    if (c.pair.kind == PairKind::kToothKernel && c.state != ContactState::kSeparated) return c.p_W;
  int first = -1;
  timeToStrikeOf(model, data, &first);
  return first >= 0 ? Vec2(data.z.segment<2>(model.kernels[first].dof_offset)) : Vec2::Zero();
}

SceneExtent chartBox(const SceneExtent& scene) {
  const double h_m = scene.size().y();
  SceneExtent c;
  c.min_m = Vec2(scene.max_m.x() + 0.08 * h_m, scene.center().y() - 0.2 * h_m);
  c.max_m = c.min_m + Vec2(0.6 * h_m, 0.4 * h_m);
  return c;
}

SceneExtent viewBox(const SceneExtent& scene) {
  const SceneExtent c = chartBox(scene);
  SceneExtent v;
  v.min_m = scene.min_m.cwiseMin(c.min_m);
  v.max_m = scene.max_m.cwiseMax(c.max_m + Vec2(0.03 * scene.size().y(), 0));
  return v;
}

}  // namespace threshing_sim
