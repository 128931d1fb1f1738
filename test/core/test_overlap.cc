// bodiesOverlap (core/overlap.h) on the default scene (testutil::defaultSceneModel): the initial
// state is clear; a kernel moved onto the tooth, into another kernel, below the floor or into
// the concave bar is reported with the pair named; the tooth's deflection counts; the tolerance
// lets a graze pass.
#include <gtest/gtest.h>

#include <string>

#include "sim_test_util.h"
#include "threshing_sim/core/state_overlap.h"
#include "threshing_sim/core/simulator.h"

namespace threshing_sim {
namespace {

struct Scene {
  Model m;
  Data d;
  explicit Scene(Model model) : m(std::move(model)) {
    compileModel(&m);
    resetData(m, &d);
  }
  void place(int kernel, const Vec2& p_m, double angle_rad = 0) {
    d.z.segment<2>(m.kernels[kernel].dof_offset) = p_m;
    d.z[m.kernels[kernel].dof_offset + 2] = angle_rad;
  }
};

Model twoKernels() {
  Model m = testutil::defaultSceneModel(IntegratorType::kEventDriven);
  KernelModel k = m.kernels[0];
  k.initial_position_m = Vec2(0.235, 0.05);
  m.kernels.push_back(k);
  return m;
}

TEST(Overlap, InitialStateIsClear) {
  Scene s(twoKernels());
  std::string what = "untouched";
  EXPECT_FALSE(bodiesOverlap(s.m, s.d, &what));
  EXPECT_EQ(what, "untouched");
}

TEST(Overlap, KernelOnTheTooth) {
  Scene s(twoKernels());
  s.place(0, Vec2(0.235, 0.004));  // tooth along +x at y = 0, radius 5 mm; b = 1.3 mm
  std::string what;
  EXPECT_TRUE(bodiesOverlap(s.m, s.d, &what));
  EXPECT_NE(what.find("tooth 0 and kernel 0 overlap by"), std::string::npos) << what;
  // Clear again once the drum has turned the tooth away.
  s.d.theta_rad = 1.0;
  EXPECT_FALSE(bodiesOverlap(s.m, s.d, &what));
}

TEST(Overlap, DeflectedToothCounts) {
  Scene s(twoKernels());
  s.place(0, Vec2(0.255, 0.0075));  // 1.2 mm clear of the straight tooth's surface
  EXPECT_FALSE(bodiesOverlap(s.m, s.d));
  // Bend the tooth towards the kernel by its first mode until the tip moves 3 mm.
  const ToothModel& t = s.m.teeth[0];
  s.d.z[t.dof_offset] = 1.0;
  const double w_tip = toothDeflection(s.m, s.d, 0, t.length_m);
  s.d.z[t.dof_offset] = 3e-3 / w_tip;
  std::string what;
  EXPECT_TRUE(bodiesOverlap(s.m, s.d, &what)) << "tip deflection " << w_tip;
  EXPECT_NE(what.find("tooth 0 and kernel 0"), std::string::npos) << what;
}

TEST(Overlap, KernelKernelAndObstacles) {
  Scene s(twoKernels());
  s.place(1, Vec2(0.239, 0.012));  // 4 mm beside kernel 0, long axes parallel: overlap
  std::string what;
  EXPECT_TRUE(bodiesOverlap(s.m, s.d, &what));
  EXPECT_NE(what.find("kernel 0 and kernel 1 overlap"), std::string::npos) << what;
  s.place(1, Vec2(0.235, 0.05));
  s.place(0, Vec2(0.0, -0.281));  // into the concave bar at (0, -0.28), r 5 mm
  EXPECT_TRUE(bodiesOverlap(s.m, s.d, &what));
  EXPECT_NE(what.find("kernel 0 and obstacle 1"), std::string::npos) << what;
  s.place(0, Vec2(0.1, -0.5005));  // through the floor at y = -0.5
  EXPECT_TRUE(bodiesOverlap(s.m, s.d, &what));
  EXPECT_NE(what.find("kernel 0 and obstacle 0"), std::string::npos) << what;
}

TEST(Overlap, ToleranceLetsAGrazePass) {
  Scene s(twoKernels());
  s.place(0, Vec2(0.1, -0.5 + 1.3e-3 - 2e-5));  // 20 um into the floor
  EXPECT_TRUE(bodiesOverlap(s.m, s.d));
  EXPECT_FALSE(bodiesOverlap(s.m, s.d, nullptr, 5e-5));
}

}  // namespace
}  // namespace threshing_sim
