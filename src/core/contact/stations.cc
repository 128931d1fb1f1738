// threshing_sim core: tooth stations and centreline kinematics (stations.h): the deformed
// centreline at the stations, between them, and along the motion; the kernels as ellipses.
#include "stations.h"

#include <algorithm>
#include <cmath>

#include "../internal.h"
#include "threshing_sim/core/beam.h"

namespace threshing_sim {
namespace internal {

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

Vec2 centrelinePoint(const ToothModel& tm, int tooth, const Eigen::Ref<const VecX>& q,
                     const Rotation2& rot, double x_m, Workspace* ws, Vec2* dr_dx,
                     StationPair* direct) {
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
  interpolateModes(tm, x_m, &ws->centreline.scratch_phi, &ws->centreline.scratch_dphi);
  int s = 0;
  double t = 0;
  stationInterval(tm, x_m, &s, &t);
  double wc = 0.0;
  if (direct != nullptr) {
    direct->update(tm, s, q.data());
    wc = (1.0 - t) * direct->wc0 + t * direct->wc1;
  } else {
    const int s0 = ws->centreline.station_offset[tooth];
    wc = (1.0 - t) * ws->centreline.station_wc_m[s0 + s] +
         t * ws->centreline.station_wc_m[s0 + s + 1];
  }
  const double w = ws->centreline.scratch_phi.dot(q);
  const double slope = ws->centreline.scratch_dphi.dot(q);
  *dr_dx = rot * ((1.0 - 0.5 * slope * slope) * tm.e1_D + slope * tm.e2_D);
  return rot * (tm.p_DR_D + (x_m + wc) * tm.e1_D + w * tm.e2_D);
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
  ws->centreline.station_offset.resize(m.teeth.size() + 1);
  int total = 0, max_modes = 0;
  for (size_t k = 0; k < m.teeth.size(); ++k) {
    ws->centreline.station_offset[k] = total;
    total += m.teeth[k].n_stations;
    max_modes = std::max(max_modes, m.teeth[k].n_modes);
  }
  ws->centreline.station_offset[m.teeth.size()] = total;
  ws->centreline.stations_W.resize(total);
  ws->centreline.station_wc_m.resize(total);
  ws->centreline.station_Hq.resize(max_modes, total);
}

void updateToothStations(const Model& m, const VecX& z, double theta_rad, int tooth,
                         Workspace* ws) {
  // r(x) = A(theta) [ b + (x + w_c(x)) e1 + w(x) e2 ] at every station, with
  // w = phi(x_s) . q and w_c = -q^T H(x_s) q / 2 (H symmetric; H q is kept for the Jacobians).
  const ToothModel& tm = m.teeth[tooth];
  const int n = tm.n_modes;
  const int s0 = ws->centreline.station_offset[tooth];
  const Rotation2 rot(theta_rad);
  if (tm.beam_model == ToothBeamModel::kLargeDeflection) {
    // The rod's exact centreline at the stations (tooth frame T, then drum, then world).
    const LdConfig& cfg = ldConfigOf(m, tooth, z, ws);
    for (int s = 0; s < tm.n_stations; ++s) {
      const Vec2 r_T = ldPoint(tm, cfg, tm.station_x_m[s], nullptr, nullptr, nullptr);
      ws->centreline.stations_W[s0 + s] = rot * (r_T.x() * tm.e1_D + r_T.y() * tm.e2_D);
      ws->centreline.station_wc_m[s0 + s] = 0.0;
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
      ws->centreline.station_Hq(i, s0 + s) = hq[i];
      qHq += q[i] * hq[i];
    }
    const double wc = -0.5 * qHq;
    ws->centreline.station_wc_m[s0 + s] = wc;
    const Vec2 p_D = tm.p_DR_D + (tm.station_x_m[s] + wc) * tm.e1_D + w * tm.e2_D;
    ws->centreline.stations_W[s0 + s] = rot * p_D;
  }
}

void updateStations(const Model& m, const VecX& z, double theta_rad, Workspace* ws) {
  layoutStations(m, ws);
  for (size_t k = 0; k < m.teeth.size(); ++k)
    updateToothStations(m, z, theta_rad, static_cast<int>(k), ws);
}

namespace {

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
  double dthd = 0.0;  // x-derivative of the sections' turn rate, phi'^T S qdot
  for (int i = 0; i < tm.n_modes; ++i)
    for (int k = 0; k < tm.n_modes; ++k)
      dthd += dphi[k] * tm.ld_rotation_filter(k, i) * u[tm.dof_offset + i];
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
  cm.drotation_rate_dx = dthd;
  return cm;
}

}  // namespace

CentrelineMotion centrelineMotion(const Model& m, int tooth, const VecX& z, const VecX& u,
                                  double x_m, Workspace* ws) {
  const ToothModel& tm = m.teeth[tooth];
  if (tm.beam_model == ToothBeamModel::kLargeDeflection) return rodMotion(m, tooth, z, u, x_m, ws);
  const int n = tm.n_modes;
  CentrelineMotion cm;
  double w = 0, w1 = 0, w2 = 0, wd = 0, wd1 = 0, wc = 0, wc1 = 0, wcd = 0, wcd1 = 0, wcdd = 0;
  int s = 0;
  double t = 0;
  stationInterval(tm, x_m, &s, &t);
  if (n > 0) {
    const auto q = z.segment(tm.dof_offset, n);
    const auto qd = u.segment(tm.dof_offset, n);
    ws->centreline.scratch_phi.resize(n);
    ws->centreline.scratch_dphi.resize(n);
    ws->centreline.scratch_ddphi.resize(n);
    interpolateModes(tm, x_m, ws->centreline.scratch_phi.data(), ws->centreline.scratch_dphi.data(),
                     ws->centreline.scratch_ddphi.data());
    w = ws->centreline.scratch_phi.dot(q);
    w1 = ws->centreline.scratch_dphi.dot(q);
    w2 = ws->centreline.scratch_ddphi.dot(q);
    wd = ws->centreline.scratch_phi.dot(qd);
    wd1 = ws->centreline.scratch_dphi.dot(qd);
    cm.drotation_rate_dx = ws->centreline.scratch_ddphi.dot(tm.rotation_factor.cwiseProduct(qd));
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
  return cm;
}

}  // namespace internal
}  // namespace threshing_sim
