// Contact kinematics: broad phase, narrow phase (gap, normal, Jacobians, rheonomic terms),
// the compliant normal law, and the smooth generalised forces.
#include <algorithm>
#include <cmath>
#include <limits>

#include "internal.h"
#include "threshing_sim/core/beam.h"
#include "threshing_sim/core/constants.h"

namespace threshing_sim {
namespace internal {
namespace {

inline Vec2 rotate(double angle_rad, const Vec2& v) {
  const double c = std::cos(angle_rad), s = std::sin(angle_rad);
  return Vec2(c * v.x() - s * v.y(), s * v.x() + c * v.y());
}
// The same rotation with its cosine and sine computed once.
struct Rotation2 {
  explicit Rotation2(double angle_rad) : c(std::cos(angle_rad)), s(std::sin(angle_rad)) {}
  Vec2 operator*(const Vec2& v) const { return Vec2(c * v.x() - s * v.y(), s * v.x() + c * v.y()); }
  double c, s;  // cos and sin of the angle [-]
};

// Station interval [x_s, x_{s+1}] holding x and the blend weight t of x_{s+1}, as in
// interpolateH (beam.cc): a guess from the equal spacing, corrected against the stored
// station positions so that x == x_s gives weight exactly 0 on the next station.
void stationInterval(const ToothModel& tm, double x_m, int* s_out, double* t_out) {
  const VecX& xs = tm.station_x_m;
  const int last = static_cast<int>(xs.size()) - 1;
  const double x = std::clamp(x_m, 0.0, tm.length_m);
  int s = std::clamp(static_cast<int>(x / tm.length_m * last), 0, last - 1);
  while (s > 0 && x < xs[s]) --s;
  while (s < last - 1 && x >= xs[s + 1]) ++s;
  *s_out = s;
  *t_out = (x - xs[s]) / (xs[s + 1] - xs[s]);
}
inline Vec2 perp(const Vec2& v) { return Vec2(-v.y(), v.x()); }  // J v
inline double cross(const Vec2& a, const Vec2& b) { return a.x() * b.y() - a.y() * b.x(); }

// Effective modulus E* of two bodies in contact [Pa].
double effectiveModulus(double E1, double nu1, double E2, double nu2) {
  return 1.0 / ((1.0 - nu1 * nu1) / E1 + (1.0 - nu2 * nu2) / E2);
}
// Series combination of two radii of curvature (inf = flat) [m].
double seriesRadius(double r1, double r2) {
  const double k = (std::isfinite(r1) ? 1.0 / r1 : 0.0) + (std::isfinite(r2) ? 1.0 / r2 : 0.0);
  return k > 0.0 ? 1.0 / k : std::numeric_limits<double>::infinity();
}
// Hertz point-contact constant K = 4/3 E* sqrt(R*), with R* = sqrt(R' R'') from the in-plane
// and out-of-plane relative radii (Johnson, Contact Mechanics, eq. 4.24 equivalent sphere).
double hertzConstant(double E_star, double r_in, double r_out) {
  const double r_star = std::sqrt(r_in * r_out);
  return 4.0 / 3.0 * E_star * std::sqrt(r_star);
}

// Half-width of an ellipse along the unit direction n (its support value h(n)) [m].
struct EllipseWidth {
  explicit EllipseWidth(const Ellipse& e)
      : axis(std::cos(e.angle_rad), std::sin(e.angle_rad)), a_m(e.a_m), b_m(e.b_m) {}
  double operator()(const Vec2& n) const {
    const double na = a_m * n.dot(axis), nb = b_m * cross(axis, n);
    return std::sqrt(na * na + nb * nb);
  }
  Vec2 axis;        // unit a-axis in world [-]
  double a_m, b_m;  // semi-axes [m]
};

// Lower bound of the signed distance between the ellipse and a convex body whose nearest point
// to the ellipse's centre is p: with n from p to the centre, the body lies behind the line
// through p normal to n, and the ellipse reaches at most h(n) towards it. (Any direction gives
// a lower bound, the supporting-line gap; this one is cheap and tight for nearby bodies.)
double gapLowerBound(const Ellipse& e, const EllipseWidth& width, const Vec2& p) {
  const Vec2 d = e.center - p;
  const double dist = d.norm();
  if (!(dist > 0.0)) return -e.a_m;
  return dist - width(d / dist);
}

// Kernel contact point Jacobian rows: d(v_point . dir)/d(vx, vy, omega).
void kernelRow(const Vec2& p_W, const Vec2& c_W, const Vec2& dir, double sign, SmallVec* w) {
  w->resize(3);
  (*w)[0] = sign * dir.x();
  (*w)[1] = sign * dir.y();
  (*w)[2] = sign * cross(p_W - c_W, dir);
}

// Deformed centreline point at material coordinate x in world, A(theta) [b + (x + w_c) e1 + w e2],
// and its tangent dr/dx = A(theta) [(1 + w_c') e1 + w' e2] with w_c' = -(w')^2 / 2.
// The foreshortening w_c(x) = -q^T H(x) q / 2 blends the stations' values linearly, as H(x)
// blends the station matrices; updateStations stored them for this q (or, with `direct`,
// they are computed here for the interval holding x).
// H(x_s) q [1/sqrt(kg)] and w_c(x_s) = -q^T H(x_s) q / 2 [m] of station s for modal
// coordinates q, with the operations of updateToothStations (so the same bits).
void stationHq(const ToothModel& tm, int s, const double* q, double* hq, double* wc) {
  const int n = tm.n_modes;
  const double* H = tm.H_s[s].data();
  for (int i = 0; i < n; ++i) hq[i] = 0.0;
  for (int j = 0; j < n; ++j) {
    const double qj = q[j];
    for (int i = 0; i < n; ++i) hq[i] += H[j * n + i] * qj;
  }
  double qHq = 0.0;
  for (int i = 0; i < n; ++i) qHq += q[i] * hq[i];
  *wc = -0.5 * qHq;
}

// The stations bracketing one interval, computed directly (without the workspace's stations).
struct StationPair {
  int s = -1;                             // interval [x_s, x_{s+1}] held (-1: none) [-]
  double hq0[kMaxModes], hq1[kMaxModes];  // H q at its two stations [1/sqrt(kg)]
  double wc0 = 0, wc1 = 0;                // w_c there [m]
  void update(const ToothModel& tm, int s_new, const double* q) {
    if (s == s_new) return;
    s = s_new;
    stationHq(tm, s, q, hq0, &wc0);
    stationHq(tm, s + 1, q, hq1, &wc1);
  }
};

Vec2 centrelinePoint(const ToothModel& tm, int tooth, const Eigen::Ref<const VecX>& q,
                     const Rotation2& rot, double x_m, Workspace* ws, Vec2* dr_dx,
                     StationPair* direct = nullptr) {
  if (tm.beam_model == ToothBeamModel::kLargeDeflection) {
    // Exact centreline of the rod; the configuration is cached per q in the workspace.
    if (ws->ld_cfg_q.size() <= static_cast<size_t>(tooth) ||
        ws->ld_cfg_q[tooth].size() != q.size() || ws->ld_cfg_q[tooth] != q) {
      ws->ld_cfg.resize(std::max(ws->ld_cfg.size(), static_cast<size_t>(tooth) + 1));
      ws->ld_cfg_q.resize(ws->ld_cfg.size());
      ws->ld_cfg_q[tooth] = q;
      ldConfigure(tm, q.data(), &ws->ld_cfg[tooth]);
    }
    Vec2 r_s;
    const Vec2 r_T = ldPoint(tm, ws->ld_cfg[tooth], x_m, &r_s, nullptr, nullptr);
    *dr_dx = rot * (r_s.x() * tm.e1_D + r_s.y() * tm.e2_D);
    return rot * (r_T.x() * tm.e1_D + r_T.y() * tm.e2_D);
  }
  evaluateModes(tm, x_m, &ws->scratch_phi, &ws->scratch_dphi);
  int s = 0;
  double t = 0;
  stationInterval(tm, x_m, &s, &t);
  double wc = 0.0;
  if (direct != nullptr) {
    direct->update(tm, s, q.data());
    wc = (1.0 - t) * direct->wc0 + t * direct->wc1;
  } else {
    const int s0 = ws->station_offset[tooth];
    wc = (1.0 - t) * ws->station_wc_m[s0 + s] + t * ws->station_wc_m[s0 + s + 1];
  }
  const double w = ws->scratch_phi.dot(q);
  const double slope = ws->scratch_dphi.dot(q);
  *dr_dx = rot * ((1.0 - 0.5 * slope * slope) * tm.e1_D + slope * tm.e2_D);
  return rot * (tm.p_DR_D + (x_m + wc) * tm.e1_D + w * tm.e2_D);
}

// Residual flexibility of tooth k at material point x_m for drum speed omega_radps, as the
// 2 x 2 block (ww, wt, tt) of w and w' under a force and a couple: the compiled table where
// Omega^2 is within its window, else one built once per speed into ws->tooth_residual.
void residualAtSpeed(const Model& m, int k, double omega_radps, double x_m, Workspace* ws,
                     double* ww, double* wt, double* tt) {
  const ToothModel& tm = m.teeth[k];
  const double w2 = omega_radps * omega_radps;
  const double window = tm.residual_speed_window_radps2;
  const VecX *t_ww = &tm.residual_ww, *t_wt = &tm.residual_wt, *t_tt = &tm.residual_tt;
  if (tm.static_correction &&
      std::abs(w2 - tm.residual_omega_radps * tm.residual_omega_radps) > window) {
    if (ws->tooth_residual.size() < m.teeth.size()) ws->tooth_residual.resize(m.teeth.size());
    ResidualCache& cache = ws->tooth_residual[k];
    if (!(std::abs(w2 - cache.omega_radps * cache.omega_radps) <= window)) {
      cache.table = residualFlexibility(tm, m.drum.radius_m, omega_radps);
      cache.omega_radps = omega_radps;
    }
    t_ww = &cache.table.ww, t_wt = &cache.table.wt, t_tt = &cache.table.tt;
  }
  *ww = residualAt(*t_ww, tm.length_m, x_m);
  *wt = residualAt(*t_wt, tm.length_m, x_m);
  *tt = residualAt(*t_tt, tm.length_m, x_m);
}

}  // namespace

int bodyDofOffset(const Model& m, int body) {
  const int T = static_cast<int>(m.teeth.size());
  return body < T ? m.teeth[body].dof_offset : m.kernels[body - T].dof_offset;
}
int bodyDofCount(const Model& m, int body) {
  const int T = static_cast<int>(m.teeth.size());
  return body < T ? m.teeth[body].n_modes : 3;
}

std::uint64_t pairKey(const PairId& p) {
  return (static_cast<std::uint64_t>(p.kind) << 60) |
         (static_cast<std::uint64_t>(static_cast<std::uint32_t>(p.a)) << 30) |
         static_cast<std::uint64_t>(static_cast<std::uint32_t>(p.b));
}

namespace {
// Slot of a key in a table of n_slots = 2^k slots: a 64-bit multiplicative hash (the key's
// fields sit in the high and low bits, the product mixes them into the top bits).
size_t slotOf(std::uint64_t key, size_t n_slots) {
  const std::uint64_t mixed = (key ^ (key >> 31)) * 0x9E3779B97F4A7C15ull;
  return static_cast<size_t>(mixed >> 32) & (n_slots - 1);
}
}  // namespace

void PairTable::reserve(size_t n) {
  entries_.reserve(n);
  // Load factor at most 1/2.
  size_t n_slots = 16;
  while (n_slots < 2 * n) n_slots *= 2;
  if (n_slots > slots_.size()) rehash(n_slots);
}

void PairTable::rehash(size_t n_slots) {
  slots_.assign(n_slots, -1);
  for (size_t i = 0; i < entries_.size(); ++i) {
    size_t s = slotOf(entries_[i].first, n_slots);
    while (slots_[s] >= 0) s = (s + 1) & (n_slots - 1);
    slots_[s] = static_cast<int>(i);
  }
}

int PairTable::indexOf(std::uint64_t key) {
  if (slots_.empty()) rehash(16);
  // Linear probing to the key or an empty slot.
  size_t s = slotOf(key, slots_.size());
  while (slots_[s] >= 0) {
    if (entries_[slots_[s]].first == key) return slots_[s];
    s = (s + 1) & (slots_.size() - 1);
  }
  // New entry; grow the slots past half full (allocates only beyond the reserve).
  const int index = static_cast<int>(entries_.size());
  entries_.emplace_back(key, PairMemory());
  slots_[s] = index;
  if (2 * entries_.size() > slots_.size()) rehash(2 * slots_.size());
  return index;
}

PairMemory& PairTable::operator[](std::uint64_t key) { return entries_[indexOf(key)].second; }

const PairMemory* PairTable::find(std::uint64_t key) const {
  if (slots_.empty()) return nullptr;
  for (size_t s = slotOf(key, slots_.size());; s = (s + 1) & (slots_.size() - 1)) {
    if (slots_[s] < 0) return nullptr;
    if (entries_[slots_[s]].first == key) return &entries_[slots_[s]].second;
  }
}

void PairTable::clear() {
  entries_.clear();
  std::fill(slots_.begin(), slots_.end(), -1);
}

Ellipse kernelEllipse(const Model& m, const VecX& z, int i) {
  const KernelModel& k = m.kernels[i];
  Ellipse e;
  e.center = z.segment<2>(k.dof_offset);
  e.angle_rad = z[k.dof_offset + 2];
  e.a_m = k.semi_axis_a_m;
  e.b_m = k.semi_axis_b_m;
  return e;
}

void layoutStations(const Model& m, Workspace* ws) {
  // All teeth's stations in one array; H(x_s) q per station in rows of the largest mode count.
  ws->station_offset.resize(m.teeth.size() + 1);
  int total = 0, max_modes = 0;
  for (size_t k = 0; k < m.teeth.size(); ++k) {
    ws->station_offset[k] = total;
    total += m.teeth[k].n_stations;
    max_modes = std::max(max_modes, m.teeth[k].n_modes);
  }
  ws->station_offset[m.teeth.size()] = total;
  ws->stations_W.resize(total);
  ws->station_wc_m.resize(total);
  ws->station_Hq.resize(max_modes, total);
}

void updateToothStations(const Model& m, const VecX& z, double theta_rad, int tooth,
                         Workspace* ws) {
  // r(x) = A(theta) [ b + (x + w_c(x)) e1 + w(x) e2 ] at every station, with
  // w = phi(x_s) . q and w_c = -q^T H(x_s) q / 2 (H symmetric; H q is kept for the Jacobians).
  const ToothModel& tm = m.teeth[tooth];
  const int n = tm.n_modes;
  const int s0 = ws->station_offset[tooth];
  const Rotation2 rot(theta_rad);
  if (tm.beam_model == ToothBeamModel::kLargeDeflection) {
    // The rod's exact centreline at the stations (tooth frame T, then drum, then world).
    const LdConfig& cfg = ldConfigOf(m, tooth, z, ws);
    for (int s = 0; s < tm.n_stations; ++s) {
      const Vec2 r_T = ldPoint(tm, cfg, tm.station_x_m[s], nullptr, nullptr, nullptr);
      ws->stations_W[s0 + s] = rot * (r_T.x() * tm.e1_D + r_T.y() * tm.e2_D);
      ws->station_wc_m[s0 + s] = 0.0;
    }
    return;
  }
  const auto q = z.segment(tm.dof_offset, n);
  double hq[kMaxModes];  // H(x_s) q
  for (int s = 0; s < tm.n_stations; ++s) {
    double w = 0.0, qHq = 0.0;
    // H q column by column (contiguous in memory), each entry summed over j in order.
    const double* H = tm.H_s[s].data();
    for (int i = 0; i < n; ++i) hq[i] = 0.0;
    for (int j = 0; j < n; ++j) {
      const double qj = q[j];
      for (int i = 0; i < n; ++i) hq[i] += H[j * n + i] * qj;
    }
    for (int i = 0; i < n; ++i) {
      w += tm.phi_s(s, i) * q[i];
      ws->station_Hq(i, s0 + s) = hq[i];
      qHq += q[i] * hq[i];
    }
    const double wc = -0.5 * qHq;
    ws->station_wc_m[s0 + s] = wc;
    const Vec2 p_D = tm.p_DR_D + (tm.station_x_m[s] + wc) * tm.e1_D + w * tm.e2_D;
    ws->stations_W[s0 + s] = rot * p_D;
  }
}

void updateStations(const Model& m, const VecX& z, double theta_rad, Workspace* ws) {
  layoutStations(m, ws);
  for (size_t k = 0; k < m.teeth.size(); ++k)
    updateToothStations(m, z, theta_rad, static_cast<int>(k), ws);
}

void prepareBroadPhase(const Model& m, Workspace* ws) {
  // Obstacles by the lower end of their extent along x; planes have no extent and are always
  // tested.
  const size_t n_obs = m.obstacles.size();
  ws->obstacle_order.clear();
  ws->obstacle_planes.clear();
  ws->obstacle_order.reserve(n_obs);
  ws->obstacle_xmin_m.assign(n_obs, 0.0);
  ws->obstacle_xmax_m.assign(n_obs, 0.0);
  ws->obstacle_max_width_m = 0.0;
  for (size_t j = 0; j < n_obs; ++j) {
    const ObstacleModel& o = m.obstacles[j];
    if (o.type == ObstacleType::kPlane) {
      ws->obstacle_planes.push_back(static_cast<int>(j));
      continue;
    }
    const double lo =
        o.type == ObstacleType::kCircle ? o.center_m.x() : std::min(o.point_m.x(), o.point_b_m.x());
    const double hi =
        o.type == ObstacleType::kCircle ? o.center_m.x() : std::max(o.point_m.x(), o.point_b_m.x());
    ws->obstacle_xmin_m[j] = lo - o.radius_m;
    ws->obstacle_xmax_m[j] = hi + o.radius_m;
    ws->obstacle_max_width_m =
        std::max(ws->obstacle_max_width_m, ws->obstacle_xmax_m[j] - ws->obstacle_xmin_m[j]);
    ws->obstacle_order.push_back(static_cast<int>(j));
  }
  std::sort(ws->obstacle_order.begin(), ws->obstacle_order.end(), [&](int a, int b) {
    return ws->obstacle_xmin_m[a] < ws->obstacle_xmin_m[b] ||
           (ws->obstacle_xmin_m[a] == ws->obstacle_xmin_m[b] && a < b);
  });
  ws->obstacle_sorted_xmin_m.resize(ws->obstacle_order.size());
  for (size_t i = 0; i < ws->obstacle_order.size(); ++i)
    ws->obstacle_sorted_xmin_m[i] = ws->obstacle_xmin_m[ws->obstacle_order[i]];
  // Per tooth, bounds of the stations' displacement from the rigid centreline: the largest
  // |phi_i(x_s)| per mode and the largest Frobenius norm of H(x_s) (>= its largest eigenvalue).
  ws->tooth_phi_max.assign(m.teeth.size(), SmallVec());
  ws->tooth_H_max.assign(m.teeth.size(), 0.0);
  for (size_t k = 0; k < m.teeth.size(); ++k) {
    const ToothModel& tm = m.teeth[k];
    SmallVec& phi_max = ws->tooth_phi_max[k];
    phi_max.setZero(tm.n_modes);
    for (int st = 0; st < tm.n_stations && tm.n_modes > 0; ++st) {
      phi_max = phi_max.cwiseMax(tm.phi_s.row(st).transpose().cwiseAbs());
      ws->tooth_H_max[k] = std::max(ws->tooth_H_max[k], tm.H_s[st].norm());
    }
  }
  // The kernel order of the sweep starts afresh.
  ws->sort_index.clear();
  ws->sort_xmin_m.clear();
  ws->grid_order.clear();
  ws->candidates.reserve(4 * m.kernels.size() * (m.teeth.size() + 4) + 64);
}

namespace {
// Whether kernel i (centre c, bounding radius r = a + margin) is within reach of obstacle o:
// the exact test of the broad phase.
bool obstacleInReach(const ObstacleModel& o, const Vec2& c, double r) {
  double dist = 0.0;
  if (o.type == ObstacleType::kPlane) {
    dist = o.normal.dot(c - o.point_m);
  } else if (o.type == ObstacleType::kCircle) {
    // A bar clearly out of reach along either axis is rejected without a square root (the
    // slack keeps the decision that of the exact test below).
    const double reach_m = (r + o.radius_m) * (1.0 + 1e-9) + 1e-12;
    if (std::abs(c.x() - o.center_m.x()) > reach_m || std::abs(c.y() - o.center_m.y()) > reach_m)
      return false;
    dist = (c - o.center_m).norm() - o.radius_m;
  } else {
    const Vec2 ab = o.point_b_m - o.point_m;
    const double s = std::clamp((c - o.point_m).dot(ab) / ab.squaredNorm(), 0.0, 1.0);
    dist = (c - (o.point_m + s * ab)).norm() - o.radius_m;
  }
  return dist <= r;
}
// Round-off slack of the interval searches below: they only pre-select, the exact tests decide,
// so a pre-selection a little too wide changes nothing [m].
double slackOf(double x_m) { return 1e-9 * (std::abs(x_m) + 1.0); }

// Orders the K bodies by (keyOf(i), i) into order, with keys[j] the key of order[j]. The
// order of the previous call is the starting point (the identity if its size is not K) and is
// repaired by insertion sort: about K comparisons while keys change little between calls. The
// order is total, so the result is the unique sorted order whatever the start.
template <class Key, class KeyOf>
void repairOrder(int K, KeyOf keyOf, std::vector<int>* order, std::vector<Key>* keys) {
  std::vector<int>& o = *order;
  std::vector<Key>& k = *keys;
  if (static_cast<int>(o.size()) != K) {
    o.resize(K);
    for (int i = 0; i < K; ++i) o[i] = i;
  }
  k.resize(K);
  for (int ia = 0; ia < K; ++ia) {
    const int a = o[ia];
    const Key ka = keyOf(a);
    int ib = ia;
    while (ib > 0 && (k[ib - 1] > ka || (k[ib - 1] == ka && o[ib - 1] > a))) {
      o[ib] = o[ib - 1];
      k[ib] = k[ib - 1];
      --ib;
    }
    o[ib] = a;
    k[ib] = ka;
  }
}
}  // namespace

void broadPhase(const Model& m, const VecX& z, double margin_m, Workspace* ws,
                const double* stations_theta_rad) {
  ws->candidates.clear();
  const int K = static_cast<int>(m.kernels.size());
  if (ws->obstacle_xmin_m.size() != m.obstacles.size() || ws->tooth_H_max.size() != m.teeth.size())
    prepareBroadPhase(m, ws);
  // Kernels by the lower end of their bounding circle along x (kernels move little between
  // steps: the previous order is repaired).
  std::vector<int>& order = ws->sort_index;
  std::vector<double>& xmin = ws->sort_xmin_m;
  repairOrder<double>(
      K, [&](int i) { return z[m.kernels[i].dof_offset] - m.kernels[i].semi_axis_a_m; }, &order,
      &xmin);
  double a_max = 0.0;
  for (int i = 0; i < K; ++i) a_max = std::max(a_max, m.kernels[i].semi_axis_a_m);

  // Teeth against kernels: the deformed centreline's bounding box against the kernel's bounding
  // circle; only the kernels whose xmin lies in the box's x range (widened by the largest
  // kernel) are tested.
  auto kernelsInBox = [&](const Vec2& lo, const Vec2& hi, double pad, int* first) {
    const double from = lo.x() - pad - 2.0 * a_max, to = hi.x() + pad;
    *first = static_cast<int>(std::lower_bound(xmin.begin(), xmin.end(), from - slackOf(from)) -
                              xmin.begin());
    return to + slackOf(to);  // last xmin to test
  };
  for (size_t k = 0; k < m.teeth.size(); ++k) {
    const ToothModel& tm = m.teeth[k];
    const double pad = 0.5 * tm.diameter_m + margin_m;
    if (stations_theta_rad != nullptr) {
      // Stations on demand: the rigid centreline's box widened by a bound of the deflection,
      // |w(x_s)| <= sum_i max_s |phi_i(x_s)| |q_i| and |w_c(x_s)| <= max_s |H(x_s)|_F |q|^2 / 2,
      // holds every station. Only a tooth with some kernel in reach of that box has its
      // stations computed; without one the exact box below would find none either.
      const Rotation2 rot(*stations_theta_rad);
      const auto q = z.segment(tm.dof_offset, tm.n_modes);
      // A large-deflection rod stays within its length of the root.
      const double deflection_m =
          tm.beam_model == ToothBeamModel::kLargeDeflection
              ? tm.length_m
              : (tm.n_modes > 0 ? ws->tooth_phi_max[k].dot(q.cwiseAbs()) +
                                      0.5 * ws->tooth_H_max[k] * q.squaredNorm()
                                : 0.0);
      const Vec2 root = rot * (tm.p_DR_D + tm.station_x_m[0] * tm.e1_D);
      const Vec2 tip = rot * (tm.p_DR_D + tm.station_x_m[tm.n_stations - 1] * tm.e1_D);
      const double grow_m = deflection_m * (1.0 + 1e-9) + 1e-9 * (root.norm() + tip.norm() + 1e-3);
      const Vec2 lo_b = root.cwiseMin(tip).array() - grow_m;
      const Vec2 hi_b = root.cwiseMax(tip).array() + grow_m;
      int first = 0;
      const double last = kernelsInBox(lo_b, hi_b, pad, &first);
      bool any = false;
      for (int ia = first; ia < K && xmin[ia] <= last && !any; ++ia) {
        const int i = order[ia];
        const Vec2 c = z.segment<2>(m.kernels[i].dof_offset);
        const double r = m.kernels[i].semi_axis_a_m + pad;
        any = !(c.x() + r < lo_b.x() || c.x() - r > hi_b.x() || c.y() + r < lo_b.y() ||
                c.y() - r > hi_b.y());
      }
      if (!any) continue;
      updateToothStations(m, z, *stations_theta_rad, static_cast<int>(k), ws);
    }
    const int s0 = ws->station_offset[k], s1 = ws->station_offset[k + 1];
    Vec2 lo = ws->stations_W[s0], hi = lo;
    for (int s = s0 + 1; s < s1; ++s) {
      lo = lo.cwiseMin(ws->stations_W[s]);
      hi = hi.cwiseMax(ws->stations_W[s]);
    }
    int first = 0;
    const double last = kernelsInBox(lo, hi, pad, &first);
    for (int ia = first; ia < K && xmin[ia] <= last; ++ia) {
      const int i = order[ia];
      const Vec2 c = z.segment<2>(m.kernels[i].dof_offset);
      const double r = m.kernels[i].semi_axis_a_m + pad;
      if (c.x() + r < lo.x() || c.x() - r > hi.x() || c.y() + r < lo.y() || c.y() - r > hi.y())
        continue;
      ws->candidates.push_back({PairKind::kToothKernel, static_cast<int>(k), i});
    }
  }
  // Kernels against kernels: a uniform grid of cells as wide as the longest reach
  // (2 a_max + margin, widened against round-off), so that two kernels in reach lie in the same
  // or adjacent cells. Kernels are kept ordered by (cell row, cell column, index), repaired by
  // insertion sort from the previous order (cells change rarely). Each kernel looks at the
  // rest of its own cell, the next cell of its row and the three cells of the next row: a
  // half stencil, so that each pair is met once.
  const double cell_m = (2.0 * a_max + margin_m) * (1.0 + 1e-9) + 1e-12;
  std::vector<int>& g_order = ws->grid_order;
  std::vector<std::int64_t>& g_key = ws->grid_key;
  ws->grid_cell.resize(K);
  // Cell coordinates, clamped (a kernel far away or not finite goes to the last cell).
  auto cellOf = [&](double x_m) {
    const double f = std::floor(x_m / cell_m);
    return static_cast<std::int64_t>(f >= -1e9 && f <= 1e9 ? f : 1e9);
  };
  const std::int64_t kRow = std::int64_t(1) << 32;  // key = row * 2^32 + column
  for (int i = 0; i < K; ++i) {
    const Vec2 c = z.segment<2>(m.kernels[i].dof_offset);
    ws->grid_cell[i] = cellOf(c.y()) * kRow + cellOf(c.x());
  }
  repairOrder<std::int64_t>(
      K, [&](int i) { return ws->grid_cell[i]; }, &g_order, &g_key);
  auto testPair = [&](int a, const Vec2& ca, double ra, int b) {
    const Vec2 cb = z.segment<2>(m.kernels[b].dof_offset);
    const double rr = ra + m.kernels[b].semi_axis_a_m + margin_m;
    if ((cb - ca).squaredNorm() > rr * rr) return;
    ws->candidates.push_back({PairKind::kKernelKernel, std::min(a, b), std::max(a, b)});
  };
  for (int ia = 0; ia < K; ++ia) {
    const int a = g_order[ia];
    const Vec2 ca = z.segment<2>(m.kernels[a].dof_offset);
    const double ra = m.kernels[a].semi_axis_a_m;
    const std::int64_t key = g_key[ia];
    // The rest of this cell and the next cell of the row.
    for (int ib = ia + 1; ib < K && g_key[ib] <= key + 1; ++ib) testPair(a, ca, ra, g_order[ib]);
    // The three cells of the next row.
    const std::int64_t lo = key + kRow - 1, hi = key + kRow + 1;
    for (int ib = static_cast<int>(std::lower_bound(g_key.begin() + ia + 1, g_key.end(), lo) -
                                   g_key.begin());
         ib < K && g_key[ib] <= hi; ++ib)
      testPair(a, ca, ra, g_order[ib]);
  }
  // Kernels against obstacles: planes always; bars and plates only those whose x extent can
  // meet the kernel's reach (found by bisection in the obstacles' xmin order).
  const std::vector<double>& obs_xmin = ws->obstacle_sorted_xmin_m;
  for (int i = 0; i < K; ++i) {
    const Vec2 c = z.segment<2>(m.kernels[i].dof_offset);
    const double r = m.kernels[i].semi_axis_a_m + margin_m;
    for (int j : ws->obstacle_planes)
      if (obstacleInReach(m.obstacles[j], c, r))
        ws->candidates.push_back({PairKind::kKernelObstacle, i, j});
    const double reach_lo = c.x() - r, to = c.x() + r;
    const double from = reach_lo - ws->obstacle_max_width_m;
    const size_t first = static_cast<size_t>(
        std::lower_bound(obs_xmin.begin(), obs_xmin.end(), from - slackOf(from)) -
        obs_xmin.begin());
    for (size_t jo = first; jo < obs_xmin.size() && obs_xmin[jo] <= to + slackOf(to); ++jo) {
      const int j = ws->obstacle_order[jo];
      if (ws->obstacle_xmax_m[j] < reach_lo - slackOf(reach_lo)) continue;
      if (obstacleInReach(m.obstacles[j], c, r))
        ws->candidates.push_back({PairKind::kKernelObstacle, i, j});
    }
  }
  std::sort(ws->candidates.begin(), ws->candidates.end());
}

void broadPhaseBruteForce(const Model& m, const VecX& z, double margin_m, Workspace* ws) {
  ws->candidates.clear();
  const int K = static_cast<int>(m.kernels.size());
  // Every tooth against every kernel, bounding box against bounding circle.
  for (size_t k = 0; k < m.teeth.size(); ++k) {
    const int s0 = ws->station_offset[k], s1 = ws->station_offset[k + 1];
    Vec2 lo = ws->stations_W[s0], hi = lo;
    for (int s = s0 + 1; s < s1; ++s) {
      lo = lo.cwiseMin(ws->stations_W[s]);
      hi = hi.cwiseMax(ws->stations_W[s]);
    }
    const double pad = 0.5 * m.teeth[k].diameter_m + margin_m;
    for (int i = 0; i < K; ++i) {
      const Vec2 c = z.segment<2>(m.kernels[i].dof_offset);
      const double r = m.kernels[i].semi_axis_a_m + pad;
      if (c.x() + r < lo.x() || c.x() - r > hi.x() || c.y() + r < lo.y() || c.y() - r > hi.y())
        continue;
      ws->candidates.push_back({PairKind::kToothKernel, static_cast<int>(k), i});
    }
  }
  // Every kernel pair, bounding circles.
  for (int a = 0; a < K; ++a) {
    for (int b = a + 1; b < K; ++b) {
      const Vec2 d = z.segment<2>(m.kernels[b].dof_offset) - z.segment<2>(m.kernels[a].dof_offset);
      const double rr = m.kernels[a].semi_axis_a_m + m.kernels[b].semi_axis_a_m + margin_m;
      if (d.squaredNorm() <= rr * rr) ws->candidates.push_back({PairKind::kKernelKernel, a, b});
    }
  }
  // Every kernel against every obstacle.
  for (int i = 0; i < K; ++i) {
    const Vec2 c = z.segment<2>(m.kernels[i].dof_offset);
    const double r = m.kernels[i].semi_axis_a_m + margin_m;
    for (size_t j = 0; j < m.obstacles.size(); ++j)
      if (obstacleInReach(m.obstacles[j], c, r))
        ws->candidates.push_back({PairKind::kKernelObstacle, i, static_cast<int>(j)});
  }
  std::sort(ws->candidates.begin(), ws->candidates.end());
}

void evaluateContact(const Model& m, const VecX& z, const VecX& u, const Drive& drive,
                     const PairId& pair, Workspace* ws, ContactGeom* g, double far_m,
                     bool tight_bound, double* warm_x_m) {
  g->pair = pair;
  g->far = false;
  g->params = &m.contact[static_cast<int>(pair.kind)];
  g->wtilde_n = g->wtilde_t = 0.0;
  g->rho0_m = g->rho1_m = std::numeric_limits<double>::infinity();
  g->residual_mpN = 0.0;
  g->side[0].body = -1;
  g->side[0].w_n.resize(0);
  g->side[0].w_t.resize(0);
  const int kb = pair.kind == PairKind::kKernelObstacle ? pair.a : pair.b;
  const KernelModel& kern = m.kernels[kb];
  const Ellipse e = kernelEllipse(m, z, kb);
  const EllipseWidth width(e);
  double r_in = 0, r_out = 0, E_star = 0;

  if (pair.kind == PairKind::kToothKernel) {
    // Closest approach of the deformed centreline polyline to the ellipse.
    const ToothModel& tm = m.teeth[pair.a];
    const int s0 = ws->station_offset[pair.a];
    Proximity best;
    best.distance_m = std::numeric_limits<double>::infinity();
    const double r_t = 0.5 * tm.diameter_m;
    // A pair in contact starts from its last closest point (warm_x_m) on the exact centreline;
    // should that refinement not converge, the polyline search below is the fallback.
    // (Not for a large-deflection rod: a strongly bent rod alongside an elongated kernel can
    // have two local minima of the distance, and the warm start and the search must not pick
    // different ones, or the pair would close and open at once.)
    const bool warm = warm_x_m != nullptr && *warm_x_m >= 0.0 && tm.n_modes > 0 &&
                      tm.beam_model == ToothBeamModel::kModal &&
                      far_m == std::numeric_limits<double>::infinity();
    StationPair direct;      // the warm start's stations (the workspace's may be stale then)
    bool from_warm = false;  // the closest point came from the warm start
    for (int attempt = warm ? 0 : 1; attempt < 2; ++attempt) {
      if (attempt == 1) {
        if (warm) updateToothStations(m, z, drive.theta_rad, pair.a, ws);
        best.distance_m = std::numeric_limits<double>::infinity();
        int best_seg = 0;
        // Segments are visited nearest first by a cheap lower bound (distance to the ellipse's
        // centre minus a); once the bound passes the best distance the rest cannot win.
        // Segments are ordered by the supporting-line gap (gapLowerBound); "far" is decided by the
        // coarser bounding-circle bound (centre distance minus a) as it always was: the polyline
        // only approximates the deformed centreline between stations, which the margin covers.
        const int n_seg = tm.n_stations - 1;
        double lower[64];
        int order[64];
        double circle_bound = std::numeric_limits<double>::infinity();
        for (int s = 0; s < n_seg; ++s) {
          const Vec2& a = ws->stations_W[s0 + s];
          const Vec2 ab = ws->stations_W[s0 + s + 1] - a;
          const double f = std::clamp((e.center - a).dot(ab) / ab.squaredNorm(), 0.0, 1.0);
          const Vec2 p = a + f * ab;
          lower[s] = gapLowerBound(e, width, p);
          circle_bound = std::min(circle_bound, (e.center - p).norm() - e.a_m);
          order[s] = s;
        }
        std::sort(order, order + n_seg, [&](int i, int j) { return lower[i] < lower[j]; });
        if (circle_bound - 0.5 * tm.diameter_m > far_m) {
          g->gap_m = circle_bound - 0.5 * tm.diameter_m;
          g->far = true;
          return;
        }
        for (int o = 0; o < n_seg; ++o) {
          const int s = order[o];
          if (lower[s] > best.distance_m) break;
          const Proximity p = segmentEllipse(ws->stations_W[s0 + s], ws->stations_W[s0 + s + 1], e);
          if (p.distance_m < best.distance_m) {
            best = p;
            best_seg = s;
          }
        }
        const double x0 = tm.station_x_m[best_seg], x1 = tm.station_x_m[best_seg + 1];
        g->tooth_x_m = x0 + best.param * (x1 - x0);
      } else {
        g->tooth_x_m = *warm_x_m;
      }
      if (tm.n_modes > 0) {
        // Refine on the exact deformed centreline (the polyline only brackets it), so that the
        // gap and the modal Jacobian below describe the same curve: secant iterations on the
        // closest-point condition h(x) = n(x) . r'(x) = 0, started from the polyline's answer.
        const auto q = z.segment(tm.dof_offset, tm.n_modes);
        Vec2 r_x;
        const Rotation2 rot(drive.theta_rad);
        auto slopeAt = [&](double x, Proximity* p) {
          Vec2 dr_dx;
          r_x =
              centrelinePoint(tm, pair.a, q, rot, x, ws, &dr_dx, attempt == 0 ? &direct : nullptr);
          *p = pointEllipse(r_x, e, width.axis.x(), width.axis.y());
          return p->normal.dot(dr_dx);
        };
        if (attempt == 0) {
          // Warm start: the last closest point is within the motion since it was found, so the
          // secant starts with a short probe (1e-9 L) and stops once its next correction is
          // below the tolerance (1e-15 L) without evaluating it; not converged in 20 iterations
          // (or equal slopes apart), the polyline search decides.
          double xa = g->tooth_x_m;
          double xb = std::min(tm.length_m, xa + 1e-9 * tm.length_m);
          if (xb == xa) xb = xa - 1e-9 * tm.length_m;
          Proximity pa, pb;
          double ha = slopeAt(xa, &pa), hb = slopeAt(xb, &pb);
          bool converged = false;
          for (int it = 0; it < 20 && hb != ha; ++it) {
            const double xn = std::clamp(xb - hb * (xb - xa) / (hb - ha), 0.0, tm.length_m);
            converged = std::abs(xn - xb) <= 1e-15 * tm.length_m;
            if (converged) break;
            xa = xb, ha = hb;
            xb = xn;
            hb = slopeAt(xb, &pb);
          }
          // A warm point that says the bodies are apart is checked by the polyline search,
          // which decides for separated pairs: the secant can settle on another stationary
          // point of the distance than the closest one (a kernel near the round tip), and a
          // pair that separates there would touch again at once (an endless impact chatter).
          if (!converged || pb.distance_m > r_t) continue;
          from_warm = true;
          g->tooth_x_m = xb;
          best = pb;
          best.point1 = r_x;
          break;
        }
        double xa = g->tooth_x_m;
        double xb = std::min(tm.length_m, xa + 1e-6 * tm.length_m);
        if (xb == xa) xb = xa - 1e-6 * tm.length_m;
        Proximity pa, pb;
        double ha = slopeAt(xa, &pa), hb = slopeAt(xb, &pb);
        int iterations = 0;
        for (; iterations < 20 && hb != ha && std::abs(xb - xa) > 1e-15 * tm.length_m;
             ++iterations) {
          const double xn = std::clamp(xb - hb * (xb - xa) / (hb - ha), 0.0, tm.length_m);
          xa = xb, ha = hb;
          xb = xn;
          hb = slopeAt(xb, &pb);
        }
        // No secant step (equal slopes at both points, e.g. a flank square to the axis at the
        // tip): xb is only the probe; keep the polyline's point if it is the closer one, and
        // evaluate there again so that r_x and the mode values in scratch_phi/dphi describe it.
        if (iterations == 0 && pa.distance_m < pb.distance_m) {
          xb = xa;
          slopeAt(xb, &pb);
        }
        // The last evaluation was at xb (r_x, pb, and the mode values in scratch_phi/dphi).
        g->tooth_x_m = xb;
        best = pb;
        best.point1 = r_x;
      }
      break;
    }
    if (warm_x_m != nullptr) *warm_x_m = g->tooth_x_m;
    g->gap_m = best.distance_m - r_t;
    g->rho1_m = best.radius2_m;
    g->n = best.normal;
    g->t = perp(g->n);
    g->p0 = best.point1 + r_t * g->n;
    g->p1 = best.point2;

    // Tooth side: velocity of the surface point = Omega J p0 + Jq qdot, with
    // Jq = A(theta) (e2 phi^T - e1 (H q)^T) + (J r_t n) phi'^T.
    BodyJac& s = g->side[0];
    s.body = toothBody(pair.a);
    const int n = tm.n_modes;
    s.w_n.resize(n);
    s.w_t.resize(n);
    if (n > 0 && tm.beam_model == ToothBeamModel::kLargeDeflection) {
      // Rod: the centreline point moves at A E (dr/dq) qdot, the surface offset r_t n turns
      // with the section angle theta(x) = phi(x) . q.
      LdJac jac;
      ldPoint(tm, ldConfigOf(m, pair.a, z, ws), g->tooth_x_m, nullptr, nullptr, &jac);
      double phi[kLdMaxShapes];
      ldShapes(tm, g->tooth_x_m, phi, nullptr);
      const Rotation2 rot(drive.theta_rad);
      const Vec2 e1 = rot * tm.e1_D, e2 = rot * tm.e2_D;
      const Vec2 jr = perp(r_t * g->n);
      const double jrn = jr.dot(g->n), jrt = jr.dot(g->t);
      for (int i = 0; i < n; ++i) {
        const Vec2 col = jac(0, i) * e1 + jac(1, i) * e2;
        s.w_n[i] = -(col.dot(g->n) + jrn * phi[i]);
        s.w_t[i] = -(col.dot(g->t) + jrt * phi[i]);
      }
    } else if (n > 0) {
      // phi and phi' at x: still in the scratch from the refinement's last evaluation.
      // H(x) q blended from the stations like H(x) itself.
      int s_h = 0;
      double t_h = 0;
      stationInterval(tm, g->tooth_x_m, &s_h, &t_h);
      const int col_h = ws->station_offset[pair.a] + s_h;
      if (from_warm) direct.update(tm, s_h, z.data() + tm.dof_offset);
      const Rotation2 rot(drive.theta_rad);
      const Vec2 e1 = rot * tm.e1_D, e2 = rot * tm.e2_D;
      const Vec2 jr = perp(r_t * g->n);
      const double e2n = e2.dot(g->n), e1n = e1.dot(g->n), jrn = jr.dot(g->n);
      const double e2t = e2.dot(g->t), e1t = e1.dot(g->t), jrt = jr.dot(g->t);
      for (int i = 0; i < n; ++i) {
        const double hq =
            from_warm ? (1.0 - t_h) * direct.hq0[i] + t_h * direct.hq1[i]
                      : (1.0 - t_h) * ws->station_Hq(i, col_h) + t_h * ws->station_Hq(i, col_h + 1);
        s.w_n[i] = -(e2n * ws->scratch_phi[i] - e1n * hq + jrn * ws->scratch_dphi[i]);
        s.w_t[i] = -(e2t * ws->scratch_phi[i] - e1t * hq + jrt * ws->scratch_dphi[i]);
      }
      // The truncated modes' compliance along n: the load (e2.n, (J r_t n).n) on (w, w').
      double r_ww, r_wt, r_tt;
      residualAtSpeed(m, pair.a, drive.omega_radps, g->tooth_x_m, ws, &r_ww, &r_wt, &r_tt);
      g->residual_mpN = e2n * e2n * r_ww + 2 * e2n * jrn * r_wt + jrn * jrn * r_tt;
    }
    // Rheonomic term: the drum carries the tooth point at Omega J p0.
    g->wtilde_n = -drive.omega_radps * cross(g->p0, g->n);
    g->wtilde_t = -drive.omega_radps * cross(g->p0, g->t);
    // Hertz: tooth flat along its side in plane (round at the tip), round (r_t) across.
    const bool at_tip = g->tooth_x_m >= tm.length_m * (1.0 - 1e-9);
    r_in = seriesRadius(at_tip ? r_t : std::numeric_limits<double>::infinity(),
                        ellipseCurvatureRadius(e, g->p1));
    r_out = seriesRadius(r_t, kern.semi_axis_b_m);
    E_star = effectiveModulus(tm.youngs_modulus_Pa, tm.poisson_ratio, kern.youngs_modulus_Pa,
                              kern.poisson_ratio);
  } else if (pair.kind == PairKind::kKernelKernel) {
    // Ellipse a against ellipse b; normal from a to b.
    const KernelModel& ka = m.kernels[pair.a];
    const Ellipse ea = kernelEllipse(m, z, pair.a);
    // Supporting-line gap along the line of centres.
    const Vec2 d_ab = e.center - ea.center;
    const double dist_ab = d_ab.norm();
    const double bound =
        !tight_bound
            ? dist_ab - e.a_m - ea.a_m
            : (dist_ab > 0.0 ? dist_ab - width(d_ab / dist_ab) - EllipseWidth(ea)(d_ab / dist_ab)
                             : -e.a_m - ea.a_m);
    if (bound > far_m) {
      g->gap_m = bound;
      g->far = true;
      return;
    }
    const Proximity p = ellipseEllipse(ea, e);
    g->gap_m = p.distance_m;
    g->n = p.normal;
    g->t = perp(g->n);
    g->p0 = p.point1;
    g->p1 = p.point2;
    g->tooth_x_m = 0;
    BodyJac& s = g->side[0];
    s.body = kernelBody(m, pair.a);
    kernelRow(g->p0, ea.center, g->n, -1.0, &s.w_n);
    kernelRow(g->p0, ea.center, g->t, -1.0, &s.w_t);
    g->rho0_m = ellipseCurvatureRadius(ea, g->p0);
    g->rho1_m = p.radius2_m;
    r_in = seriesRadius(g->rho0_m, p.radius2_m);
    r_out = seriesRadius(ka.semi_axis_b_m, kern.semi_axis_b_m);
    E_star = effectiveModulus(ka.youngs_modulus_Pa, ka.poisson_ratio, kern.youngs_modulus_Pa,
                              kern.poisson_ratio);
  } else {
    // Fixed obstacle against the kernel; normal from the obstacle to the kernel.
    const ObstacleModel& o = m.obstacles[pair.b];
    double bound = 0.0;
    if (o.type == ObstacleType::kPlane) {
      bound = o.normal.dot(e.center - o.point_m) - (!tight_bound ? e.a_m : width(o.normal));
    } else if (o.type == ObstacleType::kCircle) {
      bound = (!tight_bound ? (e.center - o.center_m).norm() - e.a_m
                            : gapLowerBound(e, width, o.center_m)) -
              o.radius_m;
    } else {
      const Vec2 ab = o.point_b_m - o.point_m;
      const double f = std::clamp((e.center - o.point_m).dot(ab) / ab.squaredNorm(), 0.0, 1.0);
      const Vec2 p = o.point_m + f * ab;
      bound =
          (!tight_bound ? (e.center - p).norm() - e.a_m : gapLowerBound(e, width, p)) - o.radius_m;
    }
    if (bound > far_m) {
      g->gap_m = bound;
      g->far = true;
      return;
    }
    Proximity p;
    double r_obst = std::numeric_limits<double>::infinity();
    if (o.type == ObstacleType::kPlane) {
      p = planeEllipse(o.point_m, o.normal, e);
    } else if (o.type == ObstacleType::kCircle) {
      p = circleEllipse(o.center_m, o.radius_m, e);
      r_obst = o.radius_m;
    } else {
      p = segmentEllipse(o.point_m, o.point_b_m, e);
      p.distance_m -= o.radius_m;
      p.point1 += o.radius_m * p.normal;
    }
    // The surface's own curvature (a plate: flat along it, round with its radius at either end).
    g->rho0_m = o.type == ObstacleType::kCircle ||
                        (o.type == ObstacleType::kSegment && (p.param <= 0.0 || p.param >= 1.0))
                    ? o.radius_m
                    : std::numeric_limits<double>::infinity();
    g->rho1_m = p.radius2_m;
    g->gap_m = p.distance_m;
    g->n = p.normal;
    g->t = perp(g->n);
    g->p0 = p.point1;
    g->p1 = p.point2;
    g->tooth_x_m = 0;
    r_in = seriesRadius(r_obst, p.radius2_m);
    r_out = kern.semi_axis_b_m;  // bars and plates are straight along the drum axis
    E_star = effectiveModulus(o.youngs_modulus_Pa, o.poisson_ratio, kern.youngs_modulus_Pa,
                              kern.poisson_ratio);
  }

  // Kernel side (body 1) and the relative velocities.
  BodyJac& s1 = g->side[1];
  s1.body = kernelBody(m, kb);
  kernelRow(g->p1, e.center, g->n, 1.0, &s1.w_n);
  kernelRow(g->p1, e.center, g->t, 1.0, &s1.w_t);
  g->vn = g->wtilde_n;
  g->vt = g->wtilde_t;
  for (const BodyJac& s : g->side) {
    if (s.body < 0 || s.w_n.size() == 0) continue;
    const auto ub = u.segment(bodyDofOffset(m, s.body), s.w_n.size());
    g->vn += s.w_n.dot(ub);
    g->vt += s.w_t.dot(ub);
  }
  g->hertz_K = hertzConstant(E_star, r_in, r_out);
}

namespace {

// Drift of a pair of rigid convex surfaces (kernel-kernel, kernel-obstacle): body 0 (a kernel
// with centre c0 and speed omega0, or fixed) and body 1 (the kernel), with radii of curvature
// rho0, rho1 at p0, p1 and p1 - p0 = gap n. The normal turns at
//   phi' = (v_T + rho0 omega0 + rho1 omega1) / (rho0 + rho1 + gap)
// (the contact points slide over the surfaces at rho (phi' - omega)), so that
//   d(v_N)/dt = phi' v_T + omega1 [rho1 (phi' - omega1) - omega1 n.(p1 - c1)]
//                        + omega0 [rho0 (phi' - omega0) + omega0 n.(p0 - c0)],
//   d(v_T)/dt = -phi' v_N - omega1^2 t.(p1 - c1) + omega0^2 t.(p0 - c0).
Vec2 rigidPairDrift(const ContactGeom& g, const Vec2& c0, double omega0, const Vec2& c1,
                    double omega1) {
  const double rho0 = g.rho0_m, rho1 = g.rho1_m;
  double phi_rate = 0.0;  // a flat body 0 (fixed) keeps the normal
  if (std::isfinite(rho0))
    phi_rate = (g.vt + rho0 * omega0 + rho1 * omega1) / (rho0 + rho1 + g.gap_m);
  double dvn =
      phi_rate * g.vt + omega1 * (rho1 * (phi_rate - omega1) - omega1 * g.n.dot(g.p1 - c1));
  if (omega0 != 0.0) dvn += omega0 * (rho0 * (phi_rate - omega0) + omega0 * g.n.dot(g.p0 - c0));
  const double dvt = -phi_rate * g.vn - omega1 * omega1 * g.t.dot(g.p1 - c1) +
                     omega0 * omega0 * g.t.dot(g.p0 - c0);
  return Vec2(dvn, dvt);
}

// Deformed centreline of a tooth at its material coordinate x along the motion (u frozen):
// position, tangent and their rates in the drum frame, with the foreshortening w_c blended
// between the stations as the narrow phase does (w_c = -q^T H(x) q / 2, H linear in x).
struct CentrelineMotion {
  Vec2 r, r_x;       // r_D(x) [m], d r_D / dx [-]
  Vec2 v, v_x, a;    // material rate of r_D, of d r_D / dx [m/s, 1/s], d^2 r_D / dt^2 [m/s^2]
  Vec2 rt_x, rt_xx;  // the narrow phase's tangent (1 - w'^2/2) e1 + w' e2 [-] and its
                     // x-derivative [1/m]
  Vec2 rt_x_rate;    // its material rate [1/s]
  double dslope_rate_dx = 0;  // d(w'_dot)/dx = phi'' . qdot [1/(m s)]
};

// The same for a large-deflection rod, from its exact kinematics: the narrow phase's tangent is
// the centreline's own (unit) tangent, and the surface offset turns with theta(x) = phi . q.
CentrelineMotion rodMotion(const Model& m, int tooth, const VecX& z, const VecX& u, double x_m,
                           Workspace* ws) {
  const ToothModel& tm = m.teeth[tooth];
  const LdConfig& cfg = ldConfigOf(m, tooth, z, ws);
  Vec2 r_s, r_ss, v, a, v_s;
  const Vec2 r = ldPoint(tm, cfg, x_m, &r_s, &r_ss, nullptr);
  ldPointMotion(tm, cfg, u.data() + tm.dof_offset, x_m, &v, &a, &v_s);
  double phi[kLdMaxShapes], dphi[kLdMaxShapes];
  ldShapes(tm, x_m, phi, dphi);
  double dthd = 0.0;
  for (int i = 0; i < tm.n_modes; ++i) dthd += dphi[i] * u[tm.dof_offset + i];
  auto toD = [&](const Vec2& p) { return Vec2(p.x() * tm.e1_D + p.y() * tm.e2_D); };
  CentrelineMotion cm;
  cm.r = toD(r);
  cm.r_x = toD(r_s);
  cm.v = toD(v);
  cm.v_x = toD(v_s);
  cm.a = toD(a);
  cm.rt_x = cm.r_x;
  cm.rt_xx = toD(r_ss);
  cm.rt_x_rate = cm.v_x;
  cm.dslope_rate_dx = dthd;
  return cm;
}

CentrelineMotion centrelineMotion(const Model& m, int tooth, const VecX& z, const VecX& u,
                                  double x_m, Workspace* ws) {
  const ToothModel& tm = m.teeth[tooth];
  if (tm.beam_model == ToothBeamModel::kLargeDeflection) return rodMotion(m, tooth, z, u, x_m, ws);
  const int n = tm.n_modes;
  CentrelineMotion cm;
  double w = 0, w1 = 0, w2 = 0, wd = 0, wd1 = 0, wd2 = 0, wc = 0, wc1 = 0, wcd = 0, wcd1 = 0,
         wcdd = 0;
  int s = 0;
  double t = 0;
  stationInterval(tm, x_m, &s, &t);
  if (n > 0) {
    const auto q = z.segment(tm.dof_offset, n);
    const auto qd = u.segment(tm.dof_offset, n);
    evaluateModes(tm, x_m, &ws->scratch_phi, &ws->scratch_dphi);
    evaluateModeCurvatures(tm, x_m, &ws->scratch_ddphi);
    w = ws->scratch_phi.dot(q);
    w1 = ws->scratch_dphi.dot(q);
    w2 = ws->scratch_ddphi.dot(q);
    wd = ws->scratch_phi.dot(qd);
    wd1 = ws->scratch_dphi.dot(qd);
    wd2 = ws->scratch_ddphi.dot(qd);
    // Stations s, s + 1: w_c, H q (as updateStations computes them) and qdot^T H qdot.
    StationPair st;
    st.update(tm, s, z.data() + tm.dof_offset);
    const double dx = tm.station_x_m[s + 1] - tm.station_x_m[s];
    double hq_d0 = 0, hq_d1 = 0, qhq0 = 0, qhq1 = 0;
    for (int i = 0; i < n; ++i) {
      hq_d0 += st.hq0[i] * qd[i];
      hq_d1 += st.hq1[i] * qd[i];
      double h0 = 0, h1 = 0;
      for (int j = 0; j < n; ++j) {
        h0 += tm.H_s[s](i, j) * qd[j];
        h1 += tm.H_s[s + 1](i, j) * qd[j];
      }
      qhq0 += qd[i] * h0;
      qhq1 += qd[i] * h1;
    }
    wc = (1.0 - t) * st.wc0 + t * st.wc1;
    wc1 = (st.wc1 - st.wc0) / dx;
    wcd = -((1.0 - t) * hq_d0 + t * hq_d1);
    wcd1 = -(hq_d1 - hq_d0) / dx;
    wcdd = -((1.0 - t) * qhq0 + t * qhq1);
  }
  const Vec2& e1 = tm.e1_D;
  const Vec2& e2 = tm.e2_D;
  cm.r = tm.p_DR_D + (x_m + wc) * e1 + w * e2;
  cm.r_x = (1.0 + wc1) * e1 + w1 * e2;
  cm.v = wcd * e1 + wd * e2;
  cm.v_x = wcd1 * e1 + wd1 * e2;
  cm.a = wcdd * e1;
  cm.rt_x = (1.0 - 0.5 * w1 * w1) * e1 + w1 * e2;
  cm.rt_xx = (-w1 * w2) * e1 + w2 * e2;
  cm.rt_x_rate = (-w1 * wd1) * e1 + wd1 * e2;
  cm.dslope_rate_dx = wd2;
  return cm;
}

// Drift of a tooth-kernel pair. The centreline point r(x) (distance d = gap + r_t from the
// ellipse, radius of curvature rho1 at the foot p1 = r + d n) moves relative to the kernel
// at w = r_dot - V1(r); v_N = -n.w and v_T = -t.w + omega1 d - r_t (Omega + w'_dot). The
// closest point x* follows n.rt_x = 0 (the narrow phase's condition; fixed at an end of the
// tooth), the normal turns at phi' = omega1 - t.(w + r_x x*') / (rho1 + d), and
//   d(v_N)/dt = -phi' t.w - n.w',  d(v_T)/dt = phi' n.w - t.w' + omega1 d' - r_t (alpha +
//   phi''.qdot x*'),  w' = r_ddot + r_dot_x x*' - omega1 J (r_dot + r_x x*' - v1),
// d' = -n.(w + r_x x*'), everything in world (the drum frame turned by theta).
Vec2 toothPairDrift(const Model& m, const VecX& z, const VecX& u, const Drive& drive,
                    const ContactGeom& g, Workspace* ws) {
  const ToothModel& tm = m.teeth[g.pair.a];
  const KernelModel& k = m.kernels[g.pair.b];
  const double x = g.tooth_x_m;
  const CentrelineMotion cm = centrelineMotion(m, g.pair.a, z, u, x, ws);
  const Rotation2 rot(drive.theta_rad);
  const double om = drive.omega_radps, al = drive.alpha_radps2;
  // World vectors of the centreline point (the drum turns them at Omega).
  const Vec2 r = rot * cm.r, r_x = rot * cm.r_x;
  const Vec2 r_dot = rot * (om * perp(cm.r) + cm.v);
  const Vec2 r_dot_x = rot * (om * perp(cm.r_x) + cm.v_x);
  const Vec2 r_ddot = rot * (al * perp(cm.r) - om * om * cm.r + 2.0 * om * perp(cm.v) + cm.a);
  const Vec2 rt_x = rot * cm.rt_x, rt_xx = rot * cm.rt_xx;
  const Vec2 rt_x_rate = rot * (om * perp(cm.rt_x) + cm.rt_x_rate);
  // The kernel.
  const Vec2 c1 = z.segment<2>(k.dof_offset), v1 = u.segment<2>(k.dof_offset);
  const double om1 = u[k.dof_offset + 2];
  const Vec2 w = r_dot - (v1 + om1 * perp(r - c1));
  const double r_t = 0.5 * tm.diameter_m;
  const double d = g.gap_m + r_t;
  const double kappa = 1.0 / (g.rho1_m + d);
  // Normal turning rate phi' = beta0 + beta1 x*'; x*' from d/dt (n.rt_x) = 0.
  const double beta0 = om1 - kappa * g.t.dot(w), beta1 = -kappa * g.t.dot(r_x);
  double x_rate = 0.0;
  if (x > 0.0 && x < tm.length_m) {
    const double den = beta1 * g.t.dot(rt_x) + g.n.dot(rt_xx);
    if (den != 0.0) x_rate = -(beta0 * g.t.dot(rt_x) + g.n.dot(rt_x_rate)) / den;
  }
  const double phi_rate = beta0 + beta1 * x_rate;
  const Vec2 move = r_dot + x_rate * r_x;  // velocity of the closest centreline point
  const Vec2 w_rate = r_ddot + x_rate * r_dot_x - om1 * perp(move - v1);
  const double dvn = -(phi_rate * g.t.dot(w) + g.n.dot(w_rate));
  const double dvt = phi_rate * g.n.dot(w) - g.t.dot(w_rate) - om1 * g.n.dot(w + x_rate * r_x) -
                     r_t * (al + cm.dslope_rate_dx * x_rate);
  return Vec2(dvn, dvt);
}

}  // namespace

Vec2 contactVelocityDrift(const Model& m, const VecX& z, const VecX& u, const Drive& drive,
                          const ContactGeom& g, Workspace* ws) {
  if (g.pair.kind == PairKind::kToothKernel) return toothPairDrift(m, z, u, drive, g, ws);
  const int kb = g.pair.kind == PairKind::kKernelObstacle ? g.pair.a : g.pair.b;
  const int o1 = m.kernels[kb].dof_offset;
  Vec2 c0 = Vec2::Zero();
  double omega0 = 0.0;
  if (g.pair.kind == PairKind::kKernelKernel) {
    const int o0 = m.kernels[g.pair.a].dof_offset;
    c0 = z.segment<2>(o0);
    omega0 = u[o0 + 2];
  }
  return rigidPairDrift(g, c0, omega0, z.segment<2>(o1), u[o1 + 2]);
}

void addGeneralised(const Model& m, const ContactGeom& g, double fn, double ft, VecX* f) {
  for (const BodyJac& s : g.side) {
    if (s.body < 0 || s.w_n.size() == 0) continue;
    f->segment(bodyDofOffset(m, s.body), s.w_n.size()) += fn * s.w_n + ft * s.w_t;
  }
}

namespace {

// The Hertz-Hunt-Crossley force with a spring of flexibility r [m/N] in series, as a function
// of the Hertz indentation x [m] at the approach rate rate_mps = d(delta)/dt:
//   Phi(x) = K x^{3/2} D(x),  D = 1 + chi rate / (1 + r s),  s = dF_e/dx = 3/2 K x^{1/2},
// with its partial derivatives in x and in the rate. Zero (no adhesion) where D <= 0.
struct SeriesHertz {
  double K, chi, r, rate;  // [N/m^{3/2}], [s/m], [m/N], [m/s]
  double force(double x, double* d_x, double* d_rate) const {
    const double sq = std::sqrt(x);
    const double split = 1.0 + r * 1.5 * K * sq;  // 1 + r s
    const double D = 1.0 + chi * rate / split;
    if (x <= 0.0 || D <= 0.0) {
      *d_x = *d_rate = 0.0;
      return 0.0;
    }
    *d_x = 1.5 * K * sq * D - chi * rate * r * 0.75 * K * K * x / (split * split);
    *d_rate = K * x * sq * chi / split;
    return K * x * sq * D;
  }
};

// Hertz indentation x in [0, delta] with x + r Phi(x) = delta, by Newton's method kept inside a
// shrinking bracket (bisection where a step leaves it); at most 60 iterations.
double seriesIndentation(const SeriesHertz& h, double delta) {
  double lo = 0.0, hi = delta, x = delta;
  for (int it = 0; it < 60; ++it) {
    double d_x, d_rate;
    const double res = x + h.r * h.force(x, &d_x, &d_rate) - delta;
    if (res > 0.0)
      hi = x;
    else
      lo = x;
    double next = x - res / (1.0 + h.r * d_x);
    if (!(next > lo && next < hi)) next = 0.5 * (lo + hi);
    if (std::abs(next - x) <= 1e-15 * delta || hi - lo <= 1e-15 * delta) return next;
    x = next;
  }
  return x;
}

}  // namespace

double compliantNormalForce(const ContactGeom& g, double K, double v_in_mps, double v_floor_mps) {
  const double delta = -g.gap_m;
  if (delta <= 0.0) return 0.0;
  // F = K delta^{3/2} (1 + chi d(delta)/dt), chi = c* / v_in, clamped: no adhesion.
  const double chi = g.params->hc_damping_factor / std::max(v_in_mps, v_floor_mps);
  if (g.residual_mpN <= 0.0) {
    const double f = K * delta * std::sqrt(delta) * (1.0 - chi * g.vn);
    return std::max(f, 0.0);
  }
  const SeriesHertz h{K, chi, g.residual_mpN, -g.vn};
  double d_x, d_rate;
  return h.force(seriesIndentation(h, delta), &d_x, &d_rate);
}

double compliantNormalForceSigned(const ContactGeom& g, double K, double v_in_mps,
                                  double v_floor_mps) {
  const double delta = std::max(-g.gap_m, 0.0);
  const double chi = g.params->hc_damping_factor / std::max(v_in_mps, v_floor_mps);
  if (g.residual_mpN <= 0.0 || delta <= 0.0)
    return K * delta * std::sqrt(delta) * (1.0 - chi * g.vn);
  // Where the damping would pull, the series spring carries no force: x = delta.
  const SeriesHertz h{K, chi, g.residual_mpN, -g.vn};
  const double x = seriesIndentation(h, delta);
  const double sq = std::sqrt(x);
  return K * x * sq * (1.0 + chi * h.rate / (1.0 + h.r * 1.5 * K * sq));
}

double compliantNormalForceRate(const ContactGeom& g, double K, double v_in_mps, double v_floor_mps,
                                double acc_n_mps2) {
  const double delta = -g.gap_m;
  if (delta <= 0.0) return 0.0;
  const double chi = g.params->hc_damping_factor / std::max(v_in_mps, v_floor_mps);
  const SeriesHertz h{K, chi, std::max(g.residual_mpN, 0.0), -g.vn};
  const double x = h.r > 0.0 ? seriesIndentation(h, delta) : delta;
  double d_x, d_rate;
  if (h.force(x, &d_x, &d_rate) <= 0.0) return 0.0;
  // x + r Phi(x, rate) = delta differentiated in time: x' (1 + r Phi_x) = delta' - r Phi_rate
  // delta'', with delta' = -g_N', delta'' = -g_N''.
  const double x_rate = (h.rate + h.r * d_rate * acc_n_mps2) / (1.0 + h.r * d_x);
  return d_x * x_rate - d_rate * acc_n_mps2;
}

Vec2 pedicelForce(const Model& m, const VecX& z, const VecX& u, int i, Vec2* p_WP) {
  const KernelModel& k = m.kernels[i];
  const Vec2 c = z.segment<2>(k.dof_offset);
  const Vec2 r = rotate(z[k.dof_offset + 2], k.pedicel.p_KP_K);
  *p_WP = c + r;
  const Vec2 v = u.segment<2>(k.dof_offset) + u[k.dof_offset + 2] * perp(r);
  const Vec2 d = *p_WP - k.pedicel.p_WA_W;
  const double len = d.norm();
  if (len <= 0.0) return Vec2::Zero();
  const Vec2 dir = d / len;
  // Linear spring on the stem's elongation, viscous damper on its rate.
  const double tension = k.pedicel.stiffness_Npm * (len - k.pedicel.rest_length_m) +
                         k.pedicel.damping_Nspm * dir.dot(v);
  return -tension * dir;
}

void smoothForces(const Model& m, const Data& d, const VecX& z, const VecX& u, const Drive& drive,
                  VecX* f) {
  f->setZero(m.n_dof);
  // Teeth: -D qdot - [Lambda + Omega^2 (K_G - I)] q - dOmega/dt p.
  const double w2 = drive.omega_radps * drive.omega_radps;
  for (size_t k = 0; k < m.teeth.size(); ++k) {
    const ToothModel& tm = m.teeth[k];
    const int n = tm.n_modes;
    if (n == 0) continue;
    const auto q = z.segment(tm.dof_offset, n);
    const auto qd = u.segment(tm.dof_offset, n);
    auto out = f->segment(tm.dof_offset, n);
    if (tm.beam_model == ToothBeamModel::kLargeDeflection) {
      // The rod's elastic, damping and inertial (centrifugal, Coriolis, Euler) forces.
      LdVec fr;
      ldDynamics(tm, ldConfigOf(m, static_cast<int>(k), z, d.ws.get()), q.data(), qd.data(),
                 drive.omega_radps, drive.alpha_radps2, nullptr, &fr, nullptr, nullptr);
      out = fr;
      continue;
    }
    // -Omega^2 K_G q by plain loops (a dynamic-size product costs more than the arithmetic).
    for (int i = 0; i < n; ++i) {
      double kq = 0.0;
      for (int j = 0; j < n; ++j) kq += tm.K_G(i, j) * q[j];
      out[i] = -w2 * kq;
    }
    out.array() += -(tm.omega0_sq.array() - w2) * q.array() -
                   tm.damping_coeff.array() * qd.array() -
                   drive.alpha_radps2 * tm.p_inertia.array();
  }
  // Kernels: gravity, and the pedicel while it holds.
  for (size_t i = 0; i < m.kernels.size(); ++i) {
    const KernelModel& k = m.kernels[i];
    f->segment<2>(k.dof_offset) += k.mass_kg * m.gravity_mps2;
    if (k.pedicel.present && d.kernel_attached[i]) {
      Vec2 p_WP;
      const Vec2 F = pedicelForce(m, z, u, static_cast<int>(i), &p_WP);
      f->segment<2>(k.dof_offset) += F;
      (*f)[k.dof_offset + 2] += cross(p_WP - z.segment<2>(k.dof_offset), F);
    }
  }
}

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

}  // namespace

bool solveContactIslands(const Model& m, const std::vector<MatX>* tooth_minv, Workspace* ws) {
  const int k = static_cast<int>(ws->active.size());
  growTo(&ws->lambda, 2 * k);
  growTo(&ws->y, 2 * k);
  ws->lambda.head(2 * k).setZero();
  if (k == 0) return true;

  // Union-find over bodies: two contacts sharing a moving body are in the same island.
  const int nb = numBodies(m);
  ws->island_parent.resize(nb);
  for (int i = 0; i < nb; ++i) ws->island_parent[i] = i;
  for (int c = 0; c < k; ++c) {
    const ContactGeom& g = ws->geoms[ws->active[c]];
    if (g.side[0].body >= 0) {
      const int r0 = findRoot(&ws->island_parent, g.side[0].body);
      const int r1 = findRoot(&ws->island_parent, g.side[1].body);
      ws->island_parent[r0] = r1;
    }
  }
  // Order the contacts by island root (stable, so the order inside an island is the input's).
  ws->island_contacts.resize(k);
  ws->island_of_body.resize(k);
  for (int c = 0; c < k; ++c) {
    ws->island_contacts[c] = c;
    ws->island_of_body[c] = findRoot(&ws->island_parent, ws->geoms[ws->active[c]].side[1].body);
  }
  // (std::stable_sort would allocate a buffer; ties broken by index give the same order.)
  std::sort(ws->island_contacts.begin(), ws->island_contacts.end(), [&](int a, int b) {
    return ws->island_of_body[a] < ws->island_of_body[b] ||
           (ws->island_of_body[a] == ws->island_of_body[b] && a < b);
  });

  bool all_ok = true;
  for (int begin = 0; begin < k;) {
    int end = begin + 1;
    const int root = ws->island_of_body[ws->island_contacts[begin]];
    while (end < k && ws->island_of_body[ws->island_contacts[end]] == root) ++end;
    const int ki = end - begin;

    // Delassus matrix G = W^T Minv W of the island, and its right-hand side.
    growTo(&ws->G_island, 2 * ki, 2 * ki);
    growTo(&ws->b_island, 2 * ki);
    growTo(&ws->lambda_island, 2 * ki);
    growTo(&ws->y_island, 2 * ki);
    auto G_island = ws->G_island.topLeftCorner(2 * ki, 2 * ki);
    G_island.setZero();
    ws->rows_island.resize(ki);
    for (int i = 0; i < ki; ++i) {
      const int ci = ws->island_contacts[begin + i];
      const ContactGeom& gi = ws->geoms[ws->active[ci]];
      ws->b_island.segment<2>(2 * i) = ws->b.segment<2>(2 * ci);
      ws->rows_island[i] = ws->rows[ci];
      for (int j = 0; j <= i; ++j) {
        const ContactGeom& gj = ws->geoms[ws->active[ws->island_contacts[begin + j]]];
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

    // One complementarity problem over the island's contacts.
    const bool ok =
        solveContactProblem(G_island, ws->b_island.head(2 * ki), ws->rows_island,
                            ws->lambda_island.head(2 * ki), ws->y_island.head(2 * ki), &ws->lcp);
    all_ok = all_ok && ok;
    for (int i = 0; i < ki; ++i) {
      const int ci = ws->island_contacts[begin + i];
      ws->lambda.segment<2>(2 * ci) = ok ? Vec2(ws->lambda_island.segment<2>(2 * i)) : Vec2::Zero();
      ws->y.segment<2>(2 * ci) =
          ok ? Vec2(ws->y_island.segment<2>(2 * i)) : Vec2(ws->b_island.segment<2>(2 * i));
    }
    begin = end;
  }
  return all_ok;
}

}  // namespace internal
}  // namespace threshing_sim
