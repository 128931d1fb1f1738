// Hard cases, strikes of a driven flexible tooth: stiff, soft and with a wedged kernel (scenes
// 6-8), with the modal tooth and the large-deflection tooth.
// Fixture and the checks every scene gets: fixture.h.
#include "fixture.h"

namespace threshing_sim {
namespace hard_cases {
namespace {

// =============================================================================================
// 6-8. Strikes of a driven tooth: stiff (spring steel, 6 modes, 1500 rpm), soft (rubber,
// 1500 rpm) and a kernel wedged between the tooth and a concave bar (800 rpm).

struct StrikeScene {
  const char* file;
  double t_end;           // short version [s]
  double extra_indent_m;  // indentation not from the impact speed: the wedge's interference [m]
  std::vector<std::string> no_drive;  // overrides of the no-drive variant, applied last
};
const StrikeScene kStiff{"06_stiff_tooth.yaml", 0.002, 0.0, {}};
const StrikeScene kSoft{"07_soft_tooth.yaml", 0.004, 0.0, {}};
// Kernel 2.6 mm thick in a 2.0 mm gap: 0.6 mm of interference. Without drive the tooth is
// put at the bottom (drum angle 0.12 rad) and the kernel slides into it along the bar from
// 12 mm ahead at the tip speed, 21.8 m/s.
const StrikeScene kWedged{
    "08_wedged.yaml",
    0.004,
    0.6e-3,
    {"drum.angle=0.12", "kernels.0.position=[0.012, -0.2657]", "kernels.0.velocity=[-21.8, 0.0]"}};

Model strikeModel(const StrikeScene& sc, IntegratorType type, std::vector<std::string> ov = {}) {
  ov.push_back("duration=" + num(sc.t_end));
  return loadHard(sc.file, type, ov);
}

// Limits of a strike run. Energies: the tooth carries 1-6 J of rotation, the kernel ~0.02 J
// after the strike; the energy balance is exact to the integrator's accuracy on the kernel
// and the tooth's vibration. 1e-7 J is 5e-6 of the kernel's energy: the event-driven error at
// tolerance 1e-6 and the time-stepping error of the explicit Hertz force over a 1 us step are
// both below it (the strikes lose 0.015-0.17 J).
Limits strikeLimits(const Model& m, const RunLog& r, const StrikeScene& sc) {
  Limits lim;
  lim.energy_tol_J = 1e-7;
  const double h = m.integrator.dt_s;
  const bool ed = m.integrator.type == kED;
  // Compliant tooth-kernel: Hertz's closed form at the largest approach speed, with the
  // kernel's mass (the tooth, driven, acts as infinitely heavy), 5 % for the kernel's curvature
  // varying over the contact; time stepping may overshoot by one step at that speed; plus
  // any geometric interference.
  const double v = maxApproachSpeed(r.events, PairKind::kToothKernel);
  const double hertz =
      hertzIndentation(m.kernels[0].mass_kg, v, toothKernelHertzMin(m.teeth[0], m.kernels[0]));
  lim.penetration_m = 1.05 * hertz + sc.extra_indent_m + (ed ? 0.0 : h * v);
  // Rigid kernel-bar (scene 8): 10 x the event tolerance. Time stepping: h x 1 m/s (the kernel
  // meets the bar at well under 1 m/s normal speed while it slides along it) plus the drift
  // of one step under the squeeze, h^2 F / m (a velocity-level scheme does not push back out).
  const double squeeze = r.d.stats.peak_normal_force_N / m.kernels[0].mass_kg;
  lim.rigid_penetration_m = ed ? 10 * m.integrator.tolerance * 1e-2 : h * 1.0 + h * h * squeeze;
  // Event-driven: the broad-phase margin over the tooth's speed (2 mm / 41 m/s = 49 us), the
  // stability of an explicit step on the steel tooth's 85 kHz mode (~6 us) and the tolerance
  // during contact: 3e5 steps/s measured at most; 2e6 (0.5 us per step) would be a stall.
  // Time stepping: 1/h (and 1/h per rod under the island scheme, rodIslandStepsPerSecond).
  lim.max_steps_per_s = ed ? 2e6 : 1.0 / h + 1 + rodIslandStepsPerSecond(m);
  lim.max_events_per_s = 1e4;  // ~5 events per strike
  // The kernel jammed in the wedge without drive (scene 8) rocks between stick and slip on the
  // tooth and the bar as the tooth rings: 31 transitions in 4 ms with 4 modes, 65 with the
  // large-deflection rod's 4 shape functions (spaced 5-100 us apart, not a chatter).
  if (m.teeth[0].beam_model == ToothBeamModel::kLargeDeflection) lim.max_events_per_s = 2e4;
  return lim;
}

// Invariants of the driven strike and of the same strike without drive.
// `ov`: extra overrides (the large-deflection tooth).
void expectStrikeInvariants(const StrikeScene& sc, IntegratorType type,
                            const std::vector<std::string>& ov = {}) {
  const Model m = strikeModel(sc, type, ov);
  const RunLog r = runScene(m, sc.t_end);
  expectCommon(m, r, strikeLimits(m, r, sc));
  expectBitIdenticalRerun(m, r);
  // The kernel was struck (no missed contact) and left the tooth.
  EXPECT_GE(countImpacts(r.events, PairKind::kToothKernel), 1);
  EXPECT_GT(kernelVelocity(m, r.d, 0).norm(), 10.0);
  // Without drive, energy may only fall.
  const Model nd = noDriveModel(sc.file, type, sc.t_end, ov, sc.no_drive);
  const RunLog rn = runScene(nd, sc.t_end);
  expectCommon(nd, rn, strikeLimits(nd, rn, sc));
  EXPECT_EQ(rn.d.stats.drive_work_J, 0.0);
  EXPECT_LT(mechanicalEnergy(nd, rn.d), rn.d.stats.energy_initial_J);
  // It meets the tooth (in the wedge it stays jammed there: the episode never ends).
  EXPECT_GE(rn.d.stats.contact_episodes, 1);
}

// Convergence of the kernel's velocity after the strike, and agreement.
void expectStrikeConvergesAndAgrees(const StrikeScene& sc) {
  auto out = [&](IntegratorType type, const std::string& knob) {
    const Model m = strikeModel(sc, type, {knob});
    return kernelVelocities(m, runScene(m, sc.t_end, 10).d);
  };
  expectKnobSweepConvergesAndAgrees(out, "kernel velocity after the strike");
}

TEST_P(HardCase, Scene06StiffToothStrike) {
  // The scene is stiff as claimed: 6 modes spanning 1 kHz to 85 kHz at 1500 rpm.
  const Model m = strikeModel(kStiff, GetParam());
  const VecX f = toothFrequenciesHz(m.teeth[0], m.drum.initial_speed_radps);
  ASSERT_EQ(f.size(), 6);
  EXPECT_LT(f[0], 1.1e3);
  EXPECT_GT(f[5], 8e4);
  expectStrikeInvariants(kStiff, GetParam());
}
TEST(HardCases, Scene06StiffToothConvergesAndIntegratorsAgree) {
  expectStrikeConvergesAndAgrees(kStiff);
}

TEST_P(HardCase, Scene07SoftToothStrike) { expectStrikeInvariants(kSoft, GetParam()); }
TEST(HardCases, Scene07SoftToothConvergesAndIntegratorsAgree) {
  expectStrikeConvergesAndAgrees(kSoft);
}

// The strike bends the rubber tooth beyond 0.1 L, where the small-deflection beam model stops
// being valid; the simulator must warn.
TEST_P(HardCase, Scene07SoftToothWarnsOutsideTheSmallDeflectionRange) {
  const Model m = strikeModel(kSoft, GetParam());
  const RunLog r = runScene(m, kSoft.t_end);
  // Sampled every 10 us over 4 ms: the tip deflection peaks at 7.9 mm = 0.13 L.
  EXPECT_GT(r.max_tip_deflection_m, 0.1 * m.teeth[0].length_m);
  // One warning, naming the deflection, at the first step end beyond 0.1 L; the largest ratio
  // seen at the step ends is at least the sampled one.
  ASSERT_EQ(r.d.stats.warnings.size(), 1u);
  EXPECT_NE(r.d.stats.warnings[0].find("tip deflection"), std::string::npos)
      << r.d.stats.warnings[0];
  EXPECT_NE(r.d.stats.warnings[0].find("teeth.0.model: large_deflection"), std::string::npos)
      << r.d.stats.warnings[0];
  EXPECT_GT(r.d.stats.deflection_warning_time_s, 0.0);
  EXPECT_LT(r.d.stats.deflection_warning_time_s, kSoft.t_end);
  EXPECT_GE(r.d.stats.max_tip_deflection_ratio,
            r.max_tip_deflection_m / m.teeth[0].length_m * (1 - 1e-12));
  // A validity fraction above the peak gives no warning.
  const Model lax = strikeModel(kSoft, GetParam(), {"deflection_validity=0.5"});
  const RunLog rl = runScene(lax, kSoft.t_end, 10);
  EXPECT_TRUE(rl.d.stats.warnings.empty());
  EXPECT_LT(rl.d.stats.deflection_warning_time_s, 0.0);
}

TEST_P(HardCase, Scene08WedgedKernelStrike) {
  const IntegratorType type = GetParam();
  expectStrikeInvariants(kWedged, type);
  const Model m = strikeModel(kWedged, type);
  const RunLog r = runScene(m, kWedged.t_end);
  // Persistent multiple contacts: tooth-kernel and kernel-bar closed together for 0.6 ms of
  // the squeeze (measured ~0.75 ms), with a peak force of tens of newtons (Hertz at 0.6 mm of
  // interference through a nylon tooth that bends: 84 N measured), below the 139 N damage
  // threshold of rice (docs/model.md §10) -- the tooth yields, nothing jams.
  EXPECT_GE(r.multi_contact_s, 0.6e-3);
  EXPECT_GT(r.d.stats.peak_normal_force_N, 40.0);
  EXPECT_LT(r.d.stats.peak_normal_force_N, 139.0);
  // The tooth bends out of the way by at least half the interference, and the kernel leaves
  // along the bar (dragged at the tip speed, 21.8 m/s).
  EXPECT_GT(r.max_tip_deflection_m, 0.3e-3);
  EXPECT_GT(kernelVelocity(m, r.d, 0).x(), 15.0);
}
TEST(HardCases, Scene08WedgedConvergesAndIntegratorsAgree) {
  expectStrikeConvergesAndAgrees(kWedged);
}

// The kernel leaves the bar at its end (2.73 ms): the rigid contact's normal force reaches zero
// with the gap at round-off (+-5e-17 m) and the normal velocity at the constraint's drift
// (-9e-6 m/s at tolerance 1e-6, -8e-7 at 1e-7). That is no approach: the pair must not be
// opened again at once for a (plastic) impact. It was, whenever the gap's round-off landed at or
// below zero: under the global scheme at tolerances 1e-5 and 3e-7, under the island scheme at
// 1e-6 to 1e-8 (one extra impact event, hard case 8 of issue 22). The kernel meets the bar once
// (it settles on it at the start) at every tolerance.
TEST(HardCases, Scene08WedgedKernelLeavesTheBarWithoutAnotherImpact) {
  for (const char* tol : {"1e-5", "3e-6", "1e-6", "3e-7", "1e-7", "1e-8"}) {
    SCOPED_TRACE(std::string("tolerance ") + tol);
    const Model m = strikeModel(kWedged, kED, {std::string("integrator.tolerance=") + tol});
    const RunLog r = runScene(m, kWedged.t_end, 10);
    EXPECT_EQ(countImpacts(r.events, PairKind::kKernelObstacle), 1);
    EXPECT_EQ(countImpacts(r.events, PairKind::kToothKernel), 1);
    // It did leave the bar (and the kernel-bar contact ended).
    ASSERT_FALSE(r.events.empty());
    EXPECT_EQ(r.events.back().pair.kind, PairKind::kKernelObstacle);
    EXPECT_EQ(r.events.back().to, ContactState::kSeparated);
  }
}

// =============================================================================================
// The tooth scenes again with the large-deflection tooth (teeth.0.model: large_deflection,
// issue 12), whose shape functions replace the modes, under both schemes (the island scheme
// integrates the rod in an island of its own, issue 23). The same invariants: no energy gain
// at an impact nor beyond the drive's work, bounded penetration and progress, bit-identical
// reruns.
const std::vector<std::string> kRod = {"teeth.0.model=large_deflection"};
TEST_P(HardCase, Scene06StiffToothStrikeLargeDeflection) {
  expectStrikeInvariants(kStiff, GetParam(), kRod);
}
TEST_P(HardCase, Scene07SoftToothStrikeLargeDeflection) {
  expectStrikeInvariants(kSoft, GetParam(), kRod);
  // Valid at any deflection: the rubber tooth bends past 0.1 L without a warning.
  const Model m = strikeModel(kSoft, GetParam(), kRod);
  const RunLog r = runScene(m, kSoft.t_end, 10);
  EXPECT_GT(r.d.stats.max_tip_deflection_ratio, 0.1);
  EXPECT_TRUE(r.d.stats.warnings.empty());
}
TEST_P(HardCase, Scene08WedgedKernelStrikeLargeDeflection) {
  expectStrikeInvariants(kWedged, GetParam(), kRod);
}

}  // namespace
}  // namespace hard_cases
}  // namespace threshing_sim
