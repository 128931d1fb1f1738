#include "threshing_sim/ros/messages.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>

#include "threshing_sim/core/constants.h"
#include "threshing_sim/core/simulator.h"

namespace threshing_sim {

const char* const kWorldFrame = "world";
const char* const kDrumFrame = "drum";

std::string toothRootFrame(int tooth) { return "tooth_" + std::to_string(tooth) + "_root"; }
std::string toothTipFrame(int tooth) { return "tooth_" + std::to_string(tooth) + "_tip"; }

int pairMarkerId(const PairId& pair) {
  return static_cast<int>(pair.kind) * 1000000 + pair.a * 1000 + pair.b;
}

void loadPose(const Snapshot& s, Data* scratch) {
  scratch->theta_rad = s.theta_rad;
  scratch->z = s.z;
}

namespace {

// Contact forces of an arrow shorter than this are drawn at this length [m].
constexpr double kMinArrowLength_m = 3e-3;
// Tangent step of the backward difference that gives the tip frame's orientation [-, of L].
constexpr double kTipSlopeStep = 1e-4;

geometry_msgs::Point point(const Vec2& p_m, double z_m = 0) {
  geometry_msgs::Point out;
  out.x = p_m.x();
  out.y = p_m.y();
  out.z = z_m;
  return out;
}

// Rotation by angle about z.
geometry_msgs::Quaternion yaw(double angle_rad) {
  geometry_msgs::Quaternion q;
  q.z = std::sin(0.5 * angle_rad);
  q.w = std::cos(0.5 * angle_rad);
  return q;
}

// The tangent t = J n of docs/model.md §5.
Vec2 tangent(const Vec2& n) { return Vec2(-n.y(), n.x()); }

std_msgs::ColorRGBA rgba(float r, float g, float b, float a = 1.f) {
  std_msgs::ColorRGBA c;
  c.r = r;
  c.g = g;
  c.b = b;
  c.a = a;
  return c;
}

// Contact arrows by state: impact orange, stick cyan, slip lime (apart from tf's red, green
// and blue axes).
std_msgs::ColorRGBA stateColor(ContactState state) {
  switch (state) {
    case ContactState::kImpact:
      return rgba(1.f, 0.45f, 0.f);
    case ContactState::kStick:
      return rgba(0.f, 0.85f, 0.85f);
    case ContactState::kSlip:
      return rgba(0.7f, 1.f, 0.f);
    default:
      return rgba(0.6f, 0.6f, 0.6f);
  }
}

geometry_msgs::TransformStamped transform(const ros::Time& stamp, const std::string& parent,
                                          const std::string& child, const Vec2& p_m,
                                          double angle_rad) {
  geometry_msgs::TransformStamped t;
  t.header.stamp = stamp;
  t.header.frame_id = parent;
  t.child_frame_id = child;
  t.transform.translation.x = p_m.x();
  t.transform.translation.y = p_m.y();
  t.transform.rotation = yaw(angle_rad);
  return t;
}

// Point of tooth k's deformed centreline at x, in its root frame [m].
Vec2 toothPointRoot(const Model& model, const Data& scratch, int k, double x_m) {
  return Vec2(x_m + toothForeshortening(model, scratch, k, x_m),
              toothDeflection(model, scratch, k, x_m));
}

visualization_msgs::Marker marker(const Snapshot& s, const std::string& ns, int id, int type) {
  visualization_msgs::Marker m;
  m.header.stamp = s.stamp;
  m.header.frame_id = kWorldFrame;
  m.ns = ns;
  m.id = id;
  m.type = type;
  m.action = visualization_msgs::Marker::ADD;
  m.pose.orientation.w = 1;
  return m;
}

// An arrow whose head touches p_W, along the force f_W on body b, above the bodies.
visualization_msgs::Marker forceArrow(const Snapshot& s, const std::string& ns, int id,
                                      const Vec2& p_W, const Vec2& f_W, double scale_mpN,
                                      const std_msgs::ColorRGBA& color) {
  visualization_msgs::Marker m = marker(s, ns, id, visualization_msgs::Marker::ARROW);
  const double f_N = f_W.norm();
  const Vec2 dir = f_N > 0 ? Vec2(f_W / f_N) : Vec2::UnitY();
  const double length_m = std::max(kMinArrowLength_m, scale_mpN * f_N);
  // 20 mm up: rviz's top-down orthographic view cannot resolve depth differences of a few mm.
  constexpr double kHeight_m = 2e-2;
  m.points = {point(p_W - length_m * dir, kHeight_m), point(p_W, kHeight_m)};
  m.scale.x = 1e-3;    // shaft diameter [m]
  m.scale.y = 2.5e-3;  // head diameter [m]
  m.scale.z = 3e-3;    // head length [m]
  m.color = color;
  return m;
}

// Kernels by state: on an intact pedicel green, free (no pedicel, or it broke) gold, damaged
// (peak normal force at or above the plastic threshold) pink.
std_msgs::ColorRGBA kernelColor(const KernelModel& kernel, bool attached, double peak_force_N,
                                const DamageThresholds& damage) {
  if (peak_force_N >= damage.plastic_force_N) return rgba(1.f, 0.35f, 0.6f);
  if (kernel.pedicel.present && attached) return rgba(0.35f, 0.85f, 0.35f);
  return rgba(1.f, 0.78f, 0.1f);
}

visualization_msgs::Marker text(const Snapshot& s, const std::string& ns, int id, const Vec2& p_m,
                                double height_m, const std::string& content) {
  visualization_msgs::Marker m = marker(s, ns, id, visualization_msgs::Marker::TEXT_VIEW_FACING);
  m.pose.position = point(p_m, 0.03);
  m.scale.z = height_m;
  m.color = rgba(0.95f, 0.95f, 0.95f);
  m.text = content;
  return m;
}

void addStaticGeometry(const Snapshot& s, visualization_msgs::MarkerArray* out) {
  const Model& model = *s.model;
  // Drum: its rim, a fine polygon (rviz's cylinder mesh is too coarse at tooth scale).
  constexpr int kRimPoints = 721;
  visualization_msgs::Marker drum = marker(s, "drum", 0, visualization_msgs::Marker::LINE_STRIP);
  for (int j = 0; j < kRimPoints; ++j) {
    const double angle_rad = 2 * kPi * j / (kRimPoints - 1);
    drum.points.push_back(
        point(model.drum.radius_m * Vec2(std::cos(angle_rad), std::sin(angle_rad))));
  }
  drum.scale.x = 1e-3;
  drum.color = rgba(0.7f, 0.7f, 0.7f);
  out->markers.push_back(drum);

  // Obstacles: planes and segments as thin boxes, concave bars as discs.
  for (size_t i = 0; i < model.obstacles.size(); ++i) {
    const ObstacleModel& o = model.obstacles[i];
    const int id = static_cast<int>(i);
    visualization_msgs::Marker m;
    if (o.type == ObstacleType::kCircle) {
      m = marker(s, "obstacles", id, visualization_msgs::Marker::CYLINDER);
      m.pose.position = point(o.center_m);
      m.scale.x = m.scale.y = 2 * o.radius_m;
      m.scale.z = 2e-3;
    } else if (o.type == ObstacleType::kSegment) {
      const Vec2 ab = o.point_b_m - o.point_m;
      m = marker(s, "obstacles", id, visualization_msgs::Marker::CUBE);
      m.pose.position = point(0.5 * (o.point_m + o.point_b_m));
      m.pose.orientation = yaw(std::atan2(ab.y(), ab.x()));
      m.scale.x = ab.norm();
      m.scale.y = 2 * o.radius_m;
      m.scale.z = 2e-3;
    } else {
      // A 1 m stretch of the plane, 10 mm thick on its solid side.
      constexpr double kThickness_m = 1e-2;
      const Vec2 t = tangent(o.normal);
      m = marker(s, "obstacles", id, visualization_msgs::Marker::CUBE);
      m.pose.position = point(o.point_m - 0.5 * kThickness_m * o.normal);
      m.pose.orientation = yaw(std::atan2(t.y(), t.x()));
      m.scale.x = 1.0;
      m.scale.y = kThickness_m;
      m.scale.z = 2e-3;
    }
    m.color = rgba(0.45f, 0.5f, 0.55f);
    out->markers.push_back(m);
  }
}

}  // namespace

ContactStateArray ContactStateBuilder::build(const Snapshot& s) {
  // The core's sums restart at a reset.
  if (s.reset) last_sums_Ns_.clear();
  ContactStateArray msg;
  msg.header.stamp = s.stamp;
  msg.header.frame_id = kWorldFrame;
  msg.contacts.reserve(s.contacts.size());
  for (const ContactInfo& c : s.contacts) {
    const Vec2 sums_Ns(c.impulse_normal_Ns, c.impulse_tangential_Ns);
    Vec2& last_Ns = last_sums_Ns_.try_emplace(c.pair, Vec2::Zero()).first->second;
    PairContact p;
    p.pair_kind = static_cast<std::uint8_t>(c.pair.kind);
    p.a = c.pair.a;
    p.b = c.pair.b;
    p.state = static_cast<std::uint8_t>(c.state);
    p.gap = c.gap_m;
    p.point = point(c.p_W);
    p.normal.x = c.n_W.x();
    p.normal.y = c.n_W.y();
    p.tooth_x = c.tooth_x_m;
    p.normal_velocity = c.normal_velocity_mps;
    p.slip_velocity = c.slip_velocity_mps;
    p.normal_force = c.normal_force_N;
    p.tangential_force = c.tangential_force_N;
    p.normal_impulse = sums_Ns.x() - last_Ns.x();
    p.tangential_impulse = sums_Ns.y() - last_Ns.y();
    last_Ns = sums_Ns;
    msg.contacts.push_back(p);
  }
  return msg;
}

ImpactEvent impactEventMsg(const ContactEvent& e, const ros::Time& stamp) {
  ImpactEvent msg;
  msg.header.stamp = stamp;
  msg.header.frame_id = kWorldFrame;
  msg.time = e.t_s;
  msg.pair_kind = static_cast<std::uint8_t>(e.pair.kind);
  msg.a = e.pair.a;
  msg.b = e.pair.b;
  msg.state_before = static_cast<std::uint8_t>(e.from);
  msg.state_after = static_cast<std::uint8_t>(e.to);
  msg.normal_velocity_before = e.vn_before_mps;
  msg.normal_velocity_after = e.vn_after_mps;
  msg.tangential_velocity_before = e.vt_before_mps;
  msg.tangential_velocity_after = e.vt_after_mps;
  msg.normal_impulse = e.impulse_normal_Ns;
  msg.tangential_impulse = e.impulse_tangential_Ns;
  msg.energy_lost = e.energy_lost_J;
  msg.peak_normal_force = e.peak_normal_force_N;
  msg.macro_collision = e.macro_collision;
  msg.sub_collision = e.sub_collision;
  return msg;
}

DrumSpeedCommand drumSpeedCommandMsg(const AppliedCommand& c) {
  DrumSpeedCommand msg;
  msg.header.stamp = c.stamp;
  msg.header.frame_id = kDrumFrame;
  msg.speed = c.speed_radps;
  return msg;
}

KernelStateArray kernelStatesMsg(const Snapshot& s) {
  const Model& model = *s.model;
  KernelStateArray msg;
  msg.header.stamp = s.stamp;
  msg.header.frame_id = kWorldFrame;
  for (size_t i = 0; i < model.kernels.size(); ++i) {
    if (i < s.kernel_active.size() && s.kernel_active[i] == 0) continue;  // a parked pool slot
    const int o = model.kernels[i].dof_offset;                            // c_x, c_y, psi
    KernelState k;
    k.index = static_cast<int>(i);
    k.pose.x = s.z[o];
    k.pose.y = s.z[o + 1];
    k.pose.theta = s.z[o + 2];
    k.velocity.x = s.u[o];
    k.velocity.y = s.u[o + 1];
    k.velocity.theta = s.u[o + 2];
    k.attached = model.kernels[i].pedicel.present && s.kernel_attached[i] != 0;
    k.peak_normal_force = s.kernel_peak_force_N[i];
    k.impacts = s.kernel_impacts[i];
    msg.kernels.push_back(k);
  }
  return msg;
}

BeamShapeArray beamShapeMsg(const Snapshot& s, const Data& scratch, int points) {
  const Model& model = *s.model;
  BeamShapeArray msg;
  msg.header.stamp = s.stamp;
  msg.header.frame_id = kWorldFrame;
  for (size_t k = 0; k < model.teeth.size(); ++k) {
    const ToothModel& tooth = model.teeth[k];
    const int ik = static_cast<int>(k);
    BeamShape b;
    b.tooth = ik;
    // Evenly spaced stations from the root to the tip.
    for (int j = 0; j < points; ++j) {
      const double x_m = tooth.length_m * j / (points - 1);
      b.station_x.push_back(x_m);
      b.points_root.push_back(point(toothPointRoot(model, scratch, ik, x_m)));
      b.points_world.push_back(point(toothPointWorld(model, scratch, ik, x_m)));
    }
    const auto q = s.z.segment(tooth.dof_offset, tooth.n_modes);
    b.modal_coordinates.assign(q.data(), q.data() + q.size());
    b.tip_deflection = toothDeflection(model, scratch, ik, tooth.length_m);
    msg.teeth.push_back(b);
  }
  return msg;
}

std::vector<geometry_msgs::TransformStamped> movingTransforms(const Snapshot& s,
                                                              const Data& scratch) {
  const Model& model = *s.model;
  std::vector<geometry_msgs::TransformStamped> out;
  out.push_back(transform(s.stamp, kWorldFrame, kDrumFrame, Vec2::Zero(), s.theta_rad));
  out.push_back(transform(s.stamp, kWorldFrame, "strike", s.strike_focus_W, 0.0));
  // Tip frames: at the deflected tip, x along the deformed centreline's tangent.
  for (size_t k = 0; k < model.teeth.size(); ++k) {
    const int ik = static_cast<int>(k);
    const double L = model.teeth[k].length_m;
    const Vec2 p_tip = toothPointRoot(model, scratch, ik, L);
    const Vec2 dp = p_tip - toothPointRoot(model, scratch, ik, (1 - kTipSlopeStep) * L);
    out.push_back(transform(s.stamp, toothRootFrame(ik), toothTipFrame(ik), p_tip,
                            std::atan2(dp.y(), dp.x())));
  }
  return out;
}

std::vector<geometry_msgs::TransformStamped> staticTransforms(const Model& model,
                                                              const ros::Time& stamp) {
  std::vector<geometry_msgs::TransformStamped> out;
  for (size_t k = 0; k < model.teeth.size(); ++k) {
    const ToothModel& tooth = model.teeth[k];
    out.push_back(transform(stamp, kDrumFrame, toothRootFrame(static_cast<int>(k)), tooth.p_DR_D,
                            std::atan2(tooth.e1_D.y(), tooth.e1_D.x())));
  }
  return out;
}

std_msgs::ColorRGBA statusColor(const RunStatus& status) {
  if (status.level == RunStatus::kError) return rgba(1.f, 0.15f, 0.15f);
  if (status.level == RunStatus::kWarn) return rgba(1.f, 0.6f, 0.f);
  if (status.state != "RUNNING") return rgba(0.6f, 0.8f, 1.f);
  return rgba(0.95f, 0.95f, 0.95f);
}

visualization_msgs::MarkerArray MarkerBuilder::build(const Snapshot& s, const Data& scratch,
                                                     bool with_static) {
  const Model& model = *s.model;
  visualization_msgs::MarkerArray out;
  if (s.reset) {
    visualization_msgs::Marker clear = marker(s, "", 0, visualization_msgs::Marker::ARROW);
    clear.action = visualization_msgs::Marker::DELETEALL;
    out.markers.push_back(clear);
    live_force_arrows_.clear();
    kernel_drawn_.assign(kernel_drawn_.size(), 0);
  }
  if (with_static || s.reset) {
    const visualization_msgs::MarkerArray geometry = staticGeometry(s);
    out.markers.insert(out.markers.end(), geometry.markers.begin(), geometry.markers.end());
  }
  addOverlay(s, &out);
  // A strike's frame leaves out what does not change within a strike (the chart's curves are
  // most of a message: 23 to 49 KB of 30 to 60 KB in the stream scene).
  if (!s.frame) {
    addStatus(s, &out);
    addStrikeChart(s, &out);
  }

  // Teeth: line strips along the deformed centreline, as thick as the tooth.
  for (size_t k = 0; k < model.teeth.size(); ++k) {
    const int ik = static_cast<int>(k);
    const ToothModel& tooth = model.teeth[k];
    visualization_msgs::Marker m = marker(s, "teeth", ik, visualization_msgs::Marker::LINE_STRIP);
    for (int j = 0; j < beam_points_; ++j)
      m.points.push_back(
          point(toothPointWorld(model, scratch, ik, tooth.length_m * j / (beam_points_ - 1))));
    m.scale.x = tooth.diameter_m;
    m.color = rgba(0.3f, 0.6f, 1.f);
    out.markers.push_back(m);
  }

  // Kernels: flat elliptic cylinders, semi-axes a along the kernel's x axis.
  kernel_drawn_.resize(model.kernels.size(), 0);
  for (size_t i = 0; i < model.kernels.size(); ++i) {
    const KernelModel& kernel = model.kernels[i];
    const int o = kernel.dof_offset;
    visualization_msgs::Marker m =
        marker(s, "kernels", static_cast<int>(i), visualization_msgs::Marker::CYLINDER);
    // A feed's parked pool slot is not drawn (deleted once: its last kernel left).
    if (i < s.kernel_active.size() && s.kernel_active[i] == 0) {
      if (!kernel_drawn_[i]) continue;
      kernel_drawn_[i] = 0;
      m.action = visualization_msgs::Marker::DELETE;
      out.markers.push_back(m);
      continue;
    }
    kernel_drawn_[i] = 1;
    m.pose.position = point(s.z.segment<2>(o));
    m.pose.orientation = yaw(s.z[o + 2]);
    m.scale.x = 2 * kernel.semi_axis_a_m;
    m.scale.y = 2 * kernel.semi_axis_b_m;
    m.scale.z = 2 * kernel.semi_axis_b_m;
    m.color = kernelColor(kernel, s.kernel_attached[i] != 0, s.kernel_peak_force_N[i], damage_);
    out.markers.push_back(m);
  }

  // Force arrows at the contacts now closed, coloured by state; stale ones deleted.
  std::set<int> live;
  for (const ContactInfo& c : s.contacts) {
    if (c.state == ContactState::kSeparated) continue;
    const int id = pairMarkerId(c.pair);
    const Vec2 f_W = c.normal_force_N * c.n_W + c.tangential_force_N * tangent(c.n_W);
    out.markers.push_back(
        forceArrow(s, "contact_forces", id, c.p_W, f_W, scale_mpN_, stateColor(c.state)));
    live.insert(id);
  }
  for (int id : live_force_arrows_) {
    if (live.count(id)) continue;
    visualization_msgs::Marker m =
        marker(s, "contact_forces", id, visualization_msgs::Marker::ARROW);
    m.action = visualization_msgs::Marker::DELETE;
    out.markers.push_back(m);
  }
  live_force_arrows_ = std::move(live);

  // The peak of each pair's latest finished episode, magenta; hidden while the pair touches
  // (its live arrow shows then).
  for (const PeakContact& p : s.peaks) {
    visualization_msgs::Marker m = forceArrow(s, "last_contact", pairMarkerId(p.pair), p.p_W, p.f_W,
                                              scale_mpN_, rgba(0.9f, 0.2f, 0.9f));
    if (p.last_closed_step == s.step) m.action = visualization_msgs::Marker::DELETE;
    out.markers.push_back(m);
  }
  return out;
}

DrumState drumStateMsg(const Snapshot& s) {
  DrumState msg;
  msg.header.stamp = s.stamp;
  msg.header.frame_id = kWorldFrame;
  msg.angle = s.theta_rad;
  msg.speed = s.omega_radps;
  msg.target_speed = s.omega_target_radps;
  msg.acceleration = s.alpha_radps2;
  msg.loops = s.loops;
  msg.load_torque = contactLoadTorque(s.contacts);
  msg.load_power = msg.load_torque * s.omega_radps;
  return msg;
}

FeedRateCommand feedRateCommandMsg(const AppliedFeedCommand& c) {
  FeedRateCommand msg;
  msg.header.stamp = c.stamp;
  msg.header.frame_id = kWorldFrame;
  msg.rate_per_s = c.rate_per_s;
  return msg;
}

FeedThroughput feedThroughputMsg(const FeedIntervalRecord& r) {
  FeedThroughput msg;
  msg.header.stamp = r.stamp;
  msg.header.frame_id = kWorldFrame;
  msg.start_time = r.row.t_start_s;
  msg.end_time = r.row.t_end_s;
  msg.feed_rate_per_s = r.rate_per_s;
  msg.feed_rate_kgps = r.rate_kgps;
  msg.fed = r.row.fed;
  msg.threshed = r.row.threshed;
  msg.damaged = r.row.damaged;
  msg.separated = r.row.separated;
  msg.carried_over_detached = r.row.carried_detached;
  msg.carried_over_unthreshed = r.row.carried_unthreshed;
  msg.out_of_bounds = r.row.out_of_bounds;
  msg.total_fed = r.counts.fed;
  msg.in_drum = r.counts.in_drum;
  msg.total_threshed = r.totals.threshed;
  msg.total_damaged = r.totals.damaged;
  msg.total_separated = r.counts.separated;
  msg.total_carried_over_detached = r.counts.carried_detached;
  msg.total_carried_over_unthreshed = r.counts.carried_unthreshed;
  msg.total_out_of_bounds = r.counts.out_of_bounds;
  msg.peak_force_mean = r.row.peak_force_mean_N;
  msg.peak_force_p50 = r.row.peak_force_p50_N;
  msg.peak_force_p90 = r.row.peak_force_p90_N;
  msg.peak_force_max = r.row.peak_force_max_N;
  msg.drive_work = r.row.drive_work_J;
  msg.power = r.row.power_W;
  msg.torque = r.row.torque_Nm;
  return msg;
}

std::string feedOverlayLine(const SnapshotFeed& feed) {
  const FeedCounts& c = feed.counts;
  const long retired = c.fed - c.in_drum;
  // Percent of the kernels retired so far.
  auto pct = [retired](long n) { return retired > 0 ? 100.0 * n / retired : 0.0; };
  char line[320];
  std::snprintf(line, sizeof(line),
                "feed %.4g kernels/s (%.3g g/s): fed %ld, in drum %ld, retired %ld\n"
                "threshed %.0f%%  damaged %.0f%%  separated %.0f%%  carried over %.0f%% "
                "(unthreshed %.0f%%)  out %.0f%%",
                feed.rate_per_s, feed.rate_kgps * 1e3, c.fed, c.in_drum, retired,
                pct(feed.totals.threshed), pct(feed.totals.damaged), pct(c.separated),
                pct(c.carried_detached + c.carried_unthreshed), pct(c.carried_unthreshed),
                pct(c.out_of_bounds));
  return line;
}

KernelContactForces kernelContactForcesMsg(const Snapshot& s) {
  KernelContactForces msg;
  msg.header.stamp = s.stamp;
  msg.header.frame_id = kWorldFrame;
  for (size_t i = 0; i < s.kernel_forces.size(); ++i) {
    const KernelForces& f = s.kernel_forces[i];
    KernelForce k;
    k.index = static_cast<int>(i);
    k.tooth_normal_force = f.normal_force_N[kByTooth];
    k.tooth_tangential_force = f.tangential_force_N[kByTooth];
    k.tooth_normal_impulse = f.normal_impulse_Ns[kByTooth];
    k.tooth_tangential_impulse = f.tangential_impulse_Ns[kByTooth];
    k.obstacle_normal_force = f.normal_force_N[kByObstacle];
    k.obstacle_tangential_force = f.tangential_force_N[kByObstacle];
    k.obstacle_normal_impulse = f.normal_impulse_Ns[kByObstacle];
    k.obstacle_tangential_impulse = f.tangential_impulse_Ns[kByObstacle];
    k.kernel_normal_force = f.normal_force_N[kByKernel];
    k.kernel_tangential_force = f.tangential_force_N[kByKernel];
    k.kernel_normal_impulse = f.normal_impulse_Ns[kByKernel];
    k.kernel_tangential_impulse = f.tangential_impulse_Ns[kByKernel];
    msg.kernels.push_back(k);
  }
  return msg;
}

StrikeHistory strikeHistoryMsg(const StrikeRecord& r, const ros::Time& stamp) {
  StrikeHistory msg;
  msg.header.stamp = stamp;
  msg.header.frame_id = kWorldFrame;
  msg.tooth = r.tooth;
  msg.kernel = r.kernel;
  msg.start_time = r.t_s.empty() ? 0.0 : r.t_s.front();
  msg.end_time = r.t_s.empty() ? 0.0 : r.t_s.back();
  msg.sample_interval = r.sample_interval_s;
  msg.peak_normal_force = r.peakNormalForce();
  msg.peak_time = r.peakTime();
  msg.normal_impulse = r.normal_impulse_Ns;
  msg.tangential_impulse = r.tangential_impulse_Ns;
  msg.truncated = r.truncated;
  msg.time = r.t_s;
  msg.normal_force = r.normal_force_N;
  msg.tangential_force = r.tangential_force_N;
  msg.gap = r.gap_m;
  return msg;
}

visualization_msgs::MarkerArray MarkerBuilder::staticGeometry(const Snapshot& s) const {
  visualization_msgs::MarkerArray out;
  addStaticGeometry(s, &out);
  addFeedGeometry(s, &out);
  // The chart's frame: a box with a zero line.
  const SceneExtent c = chartBox(extent_);
  visualization_msgs::Marker frame =
      marker(s, "strike_chart_frame", 0, visualization_msgs::Marker::LINE_STRIP);
  for (const Vec2& p :
       {c.min_m, Vec2(c.max_m.x(), c.min_m.y()), c.max_m, Vec2(c.min_m.x(), c.max_m.y()), c.min_m})
    frame.points.push_back(point(p));
  frame.scale.x = 0.004 * extent_.size().y();
  frame.color = rgba(0.55f, 0.55f, 0.55f);  // darker than the drum rim
  out.markers.push_back(frame);
  return out;
}

// A fed scene: the grate (a dashed line from the inlet to the exit, its gaps where kernels
// fall through) and the mat's band at the inlet and the exit (two short vertical bars).
void MarkerBuilder::addFeedGeometry(const Snapshot& s, visualization_msgs::MarkerArray* out) const {
  if (!has_feed_) return;
  const FeedSpec& f = feed_;
  visualization_msgs::Marker grate = marker(s, "feed", 0, visualization_msgs::Marker::LINE_LIST);
  constexpr int kBars = 40;
  const double span_m = f.exit_x_m - f.inlet_x_m;
  for (int j = 0; j < kBars; ++j) {
    const double x0 = f.inlet_x_m + span_m * j / kBars;
    grate.points.push_back(point(Vec2(x0, f.grate_y_m)));
    grate.points.push_back(point(Vec2(x0 + 0.6 * span_m / kBars, f.grate_y_m)));
  }
  grate.scale.x = 2e-3;
  grate.color = rgba(0.45f, 0.5f, 0.55f);
  out->markers.push_back(grate);
  visualization_msgs::Marker mat = marker(s, "feed", 1, visualization_msgs::Marker::LINE_LIST);
  for (double x : {f.inlet_x_m, f.exit_x_m}) {
    mat.points.push_back(point(Vec2(x, f.anchor_y_m - 0.5 * f.mat_thickness_m)));
    mat.points.push_back(point(Vec2(x, f.anchor_y_m + 0.5 * f.mat_thickness_m)));
  }
  mat.scale.x = 2e-3;
  mat.color = rgba(0.8f, 0.7f, 0.3f);
  out->markers.push_back(mat);
}

namespace {

// Whether the run is simply running (no status line, word, cause or frame).
bool plainRunning(const RunStatus& status) {
  return status.level == RunStatus::kOk && status.state == "RUNNING";
}

// The overlay's status line: the state, and the summary's head (up to its first ':' or '(')
// unless that only repeats the state ("PAUSED", "FAILED: integrator failed", "SLOW: slower
// than the target real time"); the whole summary is the status cause marker.
std::string statusLine(const RunStatus& status) {
  std::string head = status.message.substr(0, status.message.find_first_of(":("));
  while (!head.empty() && head.back() == ' ') head.pop_back();
  std::string lower = status.state;
  for (char& c : lower) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return head.empty() || head == lower ? status.state : status.state + ": " + head;
}

// text broken into lines of at most `width` characters at spaces (a longer word stays whole):
// joining the lines with spaces gives text back.
std::string wrap(const std::string& text, size_t width) {
  std::string out;
  size_t line_start = 0;
  for (size_t i = 0; i < text.size();) {
    size_t end = text.find(' ', i);
    if (end == std::string::npos) end = text.size();
    if (i > line_start && end - line_start > width) {
      out.back() = '\n';
      line_start = i;
    }
    out.append(text, i, end - i);
    if (end < text.size()) out += ' ';
    i = end + 1;
  }
  return out;
}

}  // namespace

void MarkerBuilder::addOverlay(const Snapshot& s, visualization_msgs::MarkerArray* out) const {
  char peak[64] = "(none yet)";
  if (have_strike_) std::snprintf(peak, sizeof(peak), "%.1f N", last_strike_.peakNormalForce());
  char line[400];
  std::snprintf(line, sizeof(line),
                "t = %.6f s   drum %.2f rad/s = %.0f rpm (target %.2f)\n"
                "real-time factor %.3g (requested %.3g, pace now %.3g)\n"
                "last strike peak %s",
                s.t_s, s.omega_radps, s.omega_radps * 30 / kPi, s.omega_target_radps,
                s.measured_rtf, s.requested_rtf, s.target_rtf, peak);
  // Unless simply running, the status line comes first, in letters small enough for four
  // lines to take the room of three.
  const bool plain = plainRunning(status_);
  const double h_m = extent_.size().y();
  visualization_msgs::Marker m =
      text(s, "overlay", 0, Vec2(extent_.center().x(), extent_.max_m.y() + 0.02 * h_m),
           (plain ? 0.03 : 0.0225) * h_m, plain ? line : statusLine(status_) + "\n" + line);
  m.color = statusColor(status_);
  out->markers.push_back(m);
  // A fed drum: the feed and its running fractions at the scene's foot, below the grate (id 1).
  if (s.feed.present) {
    visualization_msgs::Marker f =
        text(s, "overlay", 1, Vec2(extent_.center().x(), extent_.min_m.y()), 0.0225 * h_m,
             feedOverlayLine(s.feed));
    f.color = statusColor(status_);
    out->markers.push_back(f);
  }
}

// Unless the run is simply running: its state in large letters at the scene's top left corner
// (the drum's circle leaves the corners of its box empty) and the whole /diagnostics summary
// below the strike chart; on a warning or an error also a frame around the scene; all in the
// status colour, deleted again once it runs (the frame once the alarm is over).
void MarkerBuilder::addStatus(const Snapshot& s, visualization_msgs::MarkerArray* out) const {
  const bool show = !plainRunning(status_);
  const double h_m = extent_.size().y(), w_m = extent_.size().x();
  const SceneExtent c = chartBox(extent_);
  visualization_msgs::Marker word =
      text(s, "status", 0, Vec2(extent_.min_m.x() + 0.16 * w_m, extent_.max_m.y() - 0.09 * h_m),
           0.07 * h_m, status_.state);
  visualization_msgs::Marker cause =
      text(s, "status", 1, Vec2(c.center().x(), 0.5 * (c.min_m.y() + extent_.min_m.y())),
           0.025 * h_m, wrap(status_.message, 48));
  visualization_msgs::Marker frame =
      marker(s, "status_frame", 0, visualization_msgs::Marker::LINE_STRIP);
  const double pad = 0.01 * h_m;
  const Vec2 lo = extent_.min_m - Vec2(pad, pad), hi = extent_.max_m + Vec2(pad, pad);
  for (const Vec2& p : {lo, Vec2(hi.x(), lo.y()), hi, Vec2(lo.x(), hi.y()), lo})
    frame.points.push_back(point(p, 0.02));
  frame.scale.x = 0.008 * h_m;
  word.color = cause.color = frame.color = statusColor(status_);
  // The frame is an alarm: for warnings and errors only (a paused or finished run is fine).
  const bool alarm = status_.level != RunStatus::kOk;
  for (visualization_msgs::Marker* m : {&word, &cause, &frame}) {
    if (m == &frame ? alarm : show) continue;
    m->action = visualization_msgs::Marker::DELETE;
    m->text.clear();
    m->points.clear();
  }
  out->markers.push_back(word);
  out->markers.push_back(cause);
  out->markers.push_back(frame);
}

void MarkerBuilder::addStrikeChart(const Snapshot& s, visualization_msgs::MarkerArray* out) const {
  if (!have_strike_ || last_strike_.t_s.size() < 2) return;
  const StrikeRecord& r = last_strike_;
  const SceneExtent c = chartBox(extent_);
  const double t0 = r.t_s.front(), span_s = std::max(r.t_s.back() - t0, 1e-12);
  double f_max = 1e-9;
  for (size_t j = 0; j < r.t_s.size(); ++j)
    f_max = std::max({f_max, r.normal_force_N[j], std::abs(r.tangential_force_N[j])});
  // y = 0 at the box's lower quarter, so that a negative tangential force shows.
  const double y0 = c.min_m.y() + 0.25 * c.size().y(), y_span = 0.7 * c.size().y();
  auto curve = [&](int id, const std::vector<double>& f, const std_msgs::ColorRGBA& color) {
    visualization_msgs::Marker m =
        marker(s, "strike_chart", id, visualization_msgs::Marker::LINE_STRIP);
    const size_t stride = std::max<size_t>(1, r.t_s.size() / 1000);
    for (size_t j = 0; j < r.t_s.size(); j += stride)
      m.points.push_back(point(
          Vec2(c.min_m.x() + c.size().x() * (r.t_s[j] - t0) / span_s, y0 + y_span * f[j] / f_max),
          0.01));
    m.scale.x = 0.004 * extent_.size().y();
    m.color = color;
    return m;
  };
  out->markers.push_back(curve(0, r.normal_force_N, rgba(1.f, 0.45f, 0.f)));
  out->markers.push_back(curve(1, r.tangential_force_N, rgba(0.f, 0.85f, 0.85f)));
  char label[300];
  std::snprintf(label, sizeof(label),
                "last strike: tooth %d, kernel %d, t = %.6f s\n"
                "normal (orange) peak %.1f N, tangential (cyan)\n"
                "%.1f us, %zu samples %.2g us apart on average",
                r.tooth, r.kernel, t0, r.peakNormalForce(), span_s * 1e6, r.t_s.size(),
                r.sample_interval_s * 1e6);
  const double h_m = extent_.size().y();
  out->markers.push_back(text(s, "strike_chart", 2, Vec2(c.center().x(), c.max_m.y() + 0.06 * h_m),
                              0.025 * h_m, label));
}

}  // namespace threshing_sim
