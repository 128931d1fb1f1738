// threshing_sim core, private: tooth stations, the kinematics of the bodies' surfaces that the
// contact stages share: the deformed centreline of every tooth at its stations (and between
// them), its motion, and the kernels as ellipses (src/core/contact/stations.cc).
#pragma once

#include <cmath>
#include <vector>

#include "../small_vec.h"
#include "planar.h"
#include "threshing_sim/core/constants.h"
#include "threshing_sim/core/data.h"
#include "threshing_sim/core/geometry.h"
#include "threshing_sim/core/model.h"

namespace threshing_sim {
namespace internal {

// The deformed centrelines at the stations and the mode values at one material point
// (Workspace::centreline).
struct CentrelineScratch {
  std::vector<Vec2> stations_W;      // deformed tooth centrelines, all teeth [m]
  std::vector<int> station_offset;   // first station of each tooth in stations_W
  std::vector<double> station_wc_m;  // foreshortening w_c at each station [m]
  MatX station_Hq;                   // H(x_s) q, one column per station [1/sqrt(kg)]
  // phi, phi' and phi'' of a tooth's modes at the last material point evaluated [1/sqrt(kg),
  // 1/(sqrt(kg) m), 1/(sqrt(kg) m^2)].
  VecX scratch_phi, scratch_dphi, scratch_ddphi;
};

// Deformed centreline of every tooth at its stations, in world, for configuration z (with the
// stations' foreshortening and H q, which the narrow phase interpolates).
void updateStations(const Model& m, const VecX& z, double theta_rad, Workspace* ws);
// Sizes the station arrays for the model (updateStations does it too).
void layoutStations(const Model& m, Workspace* ws);
// The same for one tooth only; the arrays must be laid out.
void updateToothStations(const Model& m, const VecX& z, double theta_rad, int tooth, Workspace* ws);
// Kernel as a geometric ellipse.
Ellipse kernelEllipse(const Model& m, const VecX& z, int i);
// Largest speed of any point of kernel i at velocities u: centre speed plus spin times the long
// semi-axis [m/s].
inline double kernelSpeedBound(const Model& m, const VecX& u, int i) {
  const KernelModel& k = m.kernels[i];
  return u.segment<2>(k.dof_offset).norm() + std::abs(u[k.dof_offset + 2]) * k.semi_axis_a_m;
}

// Station interval [x_s, x_{s+1}] holding x and the blend weight t of x_{s+1}, as in
// interpolateH (beam.cc): a guess from the equal spacing, corrected against the stored
// station positions so that x == x_s gives weight exactly 0 on the next station.
void stationInterval(const ToothModel& tm, double x_m, int* s_out, double* t_out);

// H(x_s) q [1/sqrt(kg)] and w_c(x_s) = -q^T H(x_s) q / 2 [m] of station s for modal
// coordinates q, with the operations of updateToothStations (so the same bits).
void stationHq(const ToothModel& tm, int s, const double* q, double* hq, double* wc);

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

// Deformed centreline point at material coordinate x in world, A(theta) [b + (x + w_c) e1 + w e2],
// and its tangent dr/dx = A(theta) [(1 + w_c') e1 + w' e2] with w_c' = -(w')^2 / 2.
// The foreshortening w_c(x) = -q^T H(x) q / 2 blends the stations' values linearly, as H(x)
// blends the station matrices; updateStations stored them for this q (or, with `direct`,
// they are computed here for the interval holding x). Leaves phi(x) and phi'(x) of a modal
// tooth (interpolateModes: the mode table) in ws->centreline.scratch_phi and scratch_dphi.
Vec2 centrelinePoint(const ToothModel& tm, int tooth, const Eigen::Ref<const VecX>& q,
                     const Rotation2& rot, double x_m, Workspace* ws, Vec2* dr_dx,
                     StationPair* direct = nullptr);

// Deformed centreline of a tooth at its material coordinate x along the motion (u frozen):
// position, tangent and their rates in the drum frame, with the foreshortening w_c blended
// between the stations as the narrow phase does (w_c = -q^T H(x) q / 2, H linear in x).
struct CentrelineMotion {
  Vec2 r, r_x;       // r_D(x) [m], d r_D / dx [-]
  Vec2 v, v_x, a;    // material rate of r_D, of d r_D / dx [m/s, 1/s], d^2 r_D / dt^2 [m/s^2]
  Vec2 rt_x, rt_xx;  // the narrow phase's tangent (1 - w'^2/2) e1 + w' e2 [-] and its
                     // x-derivative [1/m]
  Vec2 rt_x_rate;    // its material rate [1/s]
  double drotation_rate_dx = 0;  // x-derivative of the sections' rotation rate: modal
                                 // (rotation_factor phi'') . qdot, rod phi'^T S qdot [1/(m s)]
};
CentrelineMotion centrelineMotion(const Model& m, int tooth, const VecX& z, const VecX& u,
                                  double x_m, Workspace* ws);

}  // namespace internal
}  // namespace threshing_sim
