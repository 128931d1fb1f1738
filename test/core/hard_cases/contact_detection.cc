// Hard cases, contact detection: Zeno accumulation of impacts (scene 1) and grazing contacts,
// of the tooth tip and of a spinning kernel on a wall (scene 2).
// Fixture and the checks every scene gets: fixture.h.
#include "fixture.h"

namespace threshing_sim {
namespace hard_cases {
namespace {

// =============================================================================================
// 1. Zeno: a kernel dropped on a plate with e = 0.5 comes to rest.

// Closed form of the drop (config/hard/01_zeno.yaml): lowest point h above the plate, at rest.
struct ZenoDrop {
  double h = 0.005, e = 0.5;
  double t0() const { return std::sqrt(2 * h / kG); }  // first impact [s]
  double v0() const { return kG * t0(); }              // first impact speed [m/s]
  // Impact k (0-based) at t0 (1 + 2 e (1 - e^k) / (1 - e)), speed v0 e^k.
  double impactTime(int k) const { return t0() * (1 + 2 * e * (1 - std::pow(e, k)) / (1 - e)); }
  // The accumulation point: t0 (1 + e) / (1 - e) = t0 (1 + 2 e / (1 - e)).
  double restTime() const { return t0() * (1 + e) / (1 - e); }
};

// Impact events of the run (kernel-plate).
std::vector<ContactEvent> impactsOf(const RunLog& r) {
  std::vector<ContactEvent> out;
  for (const ContactEvent& e : r.events)
    if (e.is_impact) out.push_back(e);
  return out;
}

// The drop's closed form: the number of impacts the Zeno rule leaves, their times and speeds,
// and the time of rest.
void expectZenoClosedForm(const Model& m, const RunLog& r) {
  const ZenoDrop drop;
  const IntegratorType type = m.integrator.type;
  const double vz = m.integrator.zeno_velocity_mps, h = m.integrator.dt_s;
  // Event-driven: bounce k leaves at v0 e^(k+1); the first one slower than v_z
  // closes the contact, so the last impact is k* = ceil(log(v_z / v0) / log e) - 1 and the
  // kernel rests from t_k*. Time stepping applies the rule to the approach speed: bounces
  // while v0 e^k > v_z (k <= k_b = floor(log(v_z / v0) / log e)), then one plastic impact.
  const double n = std::log(vz / drop.v0()) / std::log(drop.e);
  const int last = type == kED ? static_cast<int>(std::ceil(n)) - 1 : static_cast<int>(n) + 1;
  const std::vector<ContactEvent> imp = impactsOf(r);
  // Time stepping sees each approach speed up to 2 (k + 1) g h off (below): where that blurs
  // the comparison with v_z, one bounce more or fewer is within its accuracy.
  int slack = 0;
  for (int k = 0; type == kTS && k <= last + 1; ++k) {
    if (std::abs(drop.v0() * std::pow(drop.e, k) - vz) < 2.0 * (k + 1) * kG * h) slack = 1;
  }
  ASSERT_LE(std::abs(static_cast<int>(imp.size()) - (last + 1)), slack)
      << "finite number of impacts: " << imp.size() << ", closed form " << last + 1;
  for (int i = 0; i <= last && i < static_cast<int>(imp.size()); ++i) {
    // Event-driven: located to 1e-15 s per event, times accurate to 1e-9 s (the flights are
    // parabolas, integrated exactly). Time stepping: each impact lands on the step grid and
    // carries the earlier ones' errors: (i + 1) h, doubled for the speed error's effect.
    const double tol_t = type == kED ? 1e-9 : 2.0 * (i + 1) * h;
    EXPECT_NEAR(imp[i].t_s, drop.impactTime(i), tol_t) << "impact " << i;
    // Impact speeds v0 e^i: event-driven to 1e-7 relative; time stepping within g h per
    // impact of the speed accumulated since (the midpoint detection shifts each by <= g h).
    const double v = drop.v0() * std::pow(drop.e, i);
    const double tol_v = type == kED ? 1e-7 * drop.v0() : 2.0 * (i + 1) * kG * h;
    EXPECT_NEAR(-imp[i].vn_before_mps, v, tol_v) << "impact " << i;
  }
  // Rest before the accumulation point t0 (1 + e) / (1 - e), and not sooner than the Zeno
  // rule allows: the bounces it drops last 2 v_z / (g (1 - e)) in all.
  const double t_rest = imp.back().t_s;
  EXPECT_LE(t_rest, drop.restTime() + h);
  EXPECT_GE(t_rest, drop.restTime() - 2 * vz / (kG * (1 - drop.e)) - 20 * h);
}

TEST_P(HardCase, Scene01ZenoRestsOnThePlateAtTheClosedFormTime) {
  const IntegratorType type = GetParam();
  const Model m = loadHard("01_zeno.yaml", type);
  const ZenoDrop drop;
  const double h = m.integrator.dt_s;
  const RunLog r = runScene(m, m.duration_s);
  const KernelModel& k = m.kernels[0];

  // Energy scale m g h = 1.4e-6 J; 1e-6 of it (1.4e-12 J) is far above the round-off of these
  // energies (~1e-21 J) and below the loss of every bounce (the last loses 1.6e-11 J).
  Limits lim;
  lim.energy_tol_J = 1e-6 * k.mass_kg * kG * drop.h;
  // Event-driven: impacts located to ~1e-15 s at < 0.4 m/s: 1e-10 m is the event tolerance
  // (1e-9 x 1e-2 m) with a factor 10 to spare. Time stepping: contact is detected at the
  // midpoint, so a contact closes up to h x v0 deep (3.1e-6 m at h = 1e-5 s).
  lim.rigid_penetration_m = type == kED ? 10 * m.integrator.tolerance * 1e-2 : h * drop.v0();
  lim.penetration_m = lim.rigid_penetration_m;
  // Event-driven: max_step 1e-4 s caps steps at ~1e4 per second; 1e5 leaves room for events.
  // Time stepping: exactly 1/h.
  lim.max_steps_per_s = type == kED ? 1e5 : 1.0 / h + 1;
  lim.max_events_per_s = 1000;  // about 20 events in the 0.2 s run
  expectCommon(m, r, lim);
  expectBitIdenticalRerun(m, r);

  expectZenoClosedForm(m, r);

  // At rest on the plate: lying flat, the centre b above it, not moving.
  const double y_rest = r.d.z[k.dof_offset + 1];
  EXPECT_NEAR(y_rest, k.semi_axis_b_m, lim.rigid_penetration_m);
  EXPECT_LE(r.d.u.segment<3>(k.dof_offset).norm(), 1e-12);
  ASSERT_FALSE(r.d.contacts.empty());
  EXPECT_NE(r.d.contacts[0].state, ContactState::kSeparated);

  // No drift through the plate: 0.8 s more at rest (80 000 steps of time stepping) moves the
  // kernel by less than 1e-12 m.
  RunLog rest = runScene(m, 1.0, 50);
  EXPECT_NEAR(rest.d.z[k.dof_offset + 1], y_rest, 1e-12);
  EXPECT_LE(-rest.worst_rigid_gap_m, lim.rigid_penetration_m);
}

// Convergence: the event-driven knob here is the Zeno rule (the flights are exact), the rest
// time's error against the accumulation point falls with v_z; time stepping's error in the
// impact times falls with h. The two agree on the first four impact times.
TEST(HardCases, Scene01ZenoConvergesAndIntegratorsAgree) {
  const ZenoDrop drop;
  auto restTime = [&](IntegratorType type, const std::vector<std::string>& ov) {
    const Model m = loadHard("01_zeno.yaml", type, ov);
    const std::vector<ContactEvent> imp = impactsOf(runScene(m, 0.12, 20));
    VecX out(1);
    out[0] = imp.empty() ? 0.0 : imp.back().t_s;
    return out;
  };
  auto firstImpacts = [&](IntegratorType type, const std::vector<std::string>& ov) {
    const Model m = loadHard("01_zeno.yaml", type, ov);
    const std::vector<ContactEvent> imp = impactsOf(runScene(m, 0.09, 20));
    VecX out = VecX::Zero(4);
    for (int i = 0; i < 4 && i < static_cast<int>(imp.size()); ++i) out[i] = imp[i].t_s;
    return out;
  };
  VecX rest_ref(1);
  rest_ref[0] = drop.restTime();
  Sweep ed;
  for (double vz : {1e-1, 1e-2, 1e-3}) {
    ed.knob.push_back(vz);
    ed.out.push_back(restTime(kED, {"integrator.zeno_velocity=" + num(vz)}));
  }
  // Error ~ 2 v_z / (g (1 - e)) (the dropped bounces): two decades of v_z, a factor 20 at
  // least; the closed form allows no rise.
  expectConverges("event-driven rest time vs zeno_velocity", ed, rest_ref, 0.05, 0.0);

  VecX times_ref(4);
  for (int i = 0; i < 4; ++i) times_ref[i] = drop.impactTime(i);
  Sweep ts;
  for (double h : {1e-4, 3e-5, 1e-5}) {
    ts.knob.push_back(h);
    ts.out.push_back(firstImpacts(kTS, {"integrator.dt=" + num(h)}));
  }
  // First order: a decade of h, a factor 3 at least (the grid makes it uneven).
  expectConverges("time-stepping impact times vs dt", ts, times_ref, 0.3, 0.0);

  const VecX ed_fine = firstImpacts(kED, {});
  const VecX ed_coarse = firstImpacts(kED, {"integrator.tolerance=1e-7"});
  // Floor 1e-12 s: the event-driven impact times agree to round-off.
  expectAgree("first four impact times", ed_fine, ed_coarse, ts.out[2], ts.out[1], 1e-12);
}

// A finer Zeno rule must only add bounces (to the closed form's count), never lose the plate.
// With zeno_velocity 1e-4 m/s the tenth bounce (0.3 mm/s, a 62 us flight) is shorter than one
// 100 us step; with max_step 1e-3 s already the eighth (5 mm/s, 1 ms).
TEST_P(HardCase, Scene01ZenoFinerRuleKeepsTheClosedFormAndThePlate) {
  for (const char* ov : {"integrator.zeno_velocity=1e-4", "integrator.max_step=1e-3"}) {
    SCOPED_TRACE(ov);
    const Model m = loadHard("01_zeno.yaml", GetParam(), {ov});
    const RunLog r = runScene(m, 0.2, 20);
    const KernelModel& k = m.kernels[0];
    expectZenoClosedForm(m, r);
    // 10 x the event tolerance (event-driven) or h x v0 (time stepping), as in the file's run.
    const double pen = GetParam() == kED ? 10 * m.integrator.tolerance * 1e-2
                                         : m.integrator.dt_s * ZenoDrop().v0();
    EXPECT_NEAR(r.d.z[k.dof_offset + 1], k.semi_axis_b_m, pen);
    EXPECT_GE(r.worst_rigid_gap_m, -pen) << r.worst_rigid_what;
  }
}

// =============================================================================================
// 2. Grazing: a kernel falls past the tooth tip; its flank's path overlaps the tip surface by
// -offset (config/hard/02_grazing.yaml: x_centre = 0.2663 m + offset).

constexpr double kGrazeX = 0.2663;  // kernel centre x at which its flank just grazes the tip [m]
constexpr double kGrazeY = 0.012;   // kernel start height [m]
constexpr double kGrazeEnd = 0.01;  // s: the kernel passes the tip at ~6 ms and is clear by 7 ms

Model grazingModel(IntegratorType type, double offset_m, std::vector<std::string> ov = {}) {
  ov.push_back("kernels.0.position=" + vec(kGrazeX + offset_m, kGrazeY));
  ov.push_back("duration=" + num(kGrazeEnd));
  return loadHard("02_grazing.yaml", type, ov);
}

// Limits of one grazing run: the overlap of the two paths bounds the indentation.
Limits grazingLimits(const Model& m, double offset_m) {
  Limits lim;
  // Kernel kinetic energy 0.5 x 2.8e-5 x 2^2 = 5.6e-5 J. Event-driven at tolerance 1e-9:
  // energy exact to ~1e-12 J; time stepping moves the Hertz force explicitly within a step:
  // 1e-3 of the kinetic energy (5.6e-8 J) is still 100 times below the smallest loss of a
  // graze here (the -1e-7 m one loses ~2e-8 J... the bound is on a gain, any sign flip shows).
  lim.energy_tol_J = m.integrator.type == kED ? 1e-11 : 5.6e-8;
  // The indentation can never exceed the overlap of the undeflected paths; 1 % for the
  // ellipse's curvature change along the flank (the tooth only yields).
  lim.rigid_penetration_m = 0.0;
  lim.penetration_m = 1.01 * std::max(-offset_m, 0.0);
  // Event-driven: ~6e4 steps/s measured (contact at tolerance 1e-9); 5e5 allows tighter
  // tolerances. Time stepping: exactly 1/h.
  lim.max_steps_per_s = m.integrator.type == kED ? 5e5 : 1.0 / m.integrator.dt_s + 1;
  lim.max_events_per_s = 2000;  // a handful of events per graze in 10 ms
  return lim;
}

// The kernel's sideways speed after the graze is the response; it must vanish continuously as
// the overlap goes to zero, every overlap must be seen, and no clearance may give an impact.
TEST_P(HardCase, Scene02GrazingResponseIsContinuousWithNoMissedOrSpuriousContact) {
  const IntegratorType type = GetParam();
  std::vector<double> vx;
  for (double offset : {-1e-4, -1e-5, -1e-6, -1e-7}) {
    SCOPED_TRACE("offset " + num(offset));
    const Model m = grazingModel(type, offset);
    const RunLog r = runScene(m, kGrazeEnd);
    expectCommon(m, r, grazingLimits(m, offset));
    // No missed contact: one contact episode (the graze), pushed sideways (+x).
    EXPECT_EQ(r.d.stats.contact_episodes, 1);
    vx.push_back(kernelVelocity(m, r.d, 0).x());
    EXPECT_GT(vx.back(), 0.0);
  }
  // Continuous response: strictly falling with the overlap, and at 1e-7 m below 1 % of the
  // 1e-4 m one (measured: 0.219, 0.074, 0.014, 0.00065 m/s).
  for (size_t i = 1; i < vx.size(); ++i) EXPECT_LT(vx[i], vx[i - 1]);
  EXPECT_LT(vx.back(), 1e-2 * vx.front());
  // No spurious impact: a path clear of the tip by 1e-7 m, 1e-6 m or just grazing (0) leaves
  // the kernel untouched, bit for bit: no event, no sideways speed, no spin.
  for (double offset : {0.0, 1e-7, 1e-6}) {
    SCOPED_TRACE("offset " + num(offset));
    const Model m = grazingModel(type, offset);
    const RunLog r = runScene(m, kGrazeEnd);
    expectCommon(m, r, grazingLimits(m, offset));
    EXPECT_TRUE(r.events.empty());
    EXPECT_EQ(kernelVelocity(m, r.d, 0).x(), 0.0);
    EXPECT_EQ(r.d.u[m.kernels[0].dof_offset + 2], 0.0);
  }
  // The scene file itself (offset -1e-5 m) reruns bit for bit.
  const Model m = loadHard("02_grazing.yaml", type, {"duration=" + num(kGrazeEnd)});
  expectBitIdenticalRerun(m, runScene(m, kGrazeEnd));
}

// A 10 nm overlap lasts 8 us at 2.1 m/s: 1000 times the event-driven position tolerance
// (1e-9 x 1e-2 m), and 8 time steps of 1 us, so both integrators must see it.
TEST_P(HardCase, Scene02GrazingTenNanometreOverlapIsNotMissed) {
  const Model m = grazingModel(GetParam(), -1e-8);
  const RunLog r = runScene(m, kGrazeEnd);
  expectCommon(m, r, grazingLimits(m, -1e-8));
  EXPECT_EQ(r.d.stats.contact_episodes, 1);
  EXPECT_GT(kernelVelocity(m, r.d, 0).x(), 0.0);
}

// Convergence of the response at the file's offset (-1e-5 m) and agreement.
TEST(HardCases, Scene02GrazingConvergesAndIntegratorsAgree) {
  auto response = [](IntegratorType type, const std::vector<std::string>& ov) {
    const Model m = grazingModel(type, -1e-5, ov);
    const RunLog r = runScene(m, kGrazeEnd, 10);
    return VecX(r.d.u.segment<3>(m.kernels[0].dof_offset));
  };
  const KnobSweeps s = knobSweeps(
      [&](IntegratorType type, const std::string& knob) { return response(type, {knob}); },
      {1e-5, 1e-7, 1e-9}, 1e-11);
  const VecX& ref = s.ref;
  const Sweep &ed = s.ed, &ts = s.ts;
  // Four decades of tolerance: the error must fall by 100 at least (measured 1e-4 relative at
  // 1e-5, round-off at 1e-9); first-order time stepping: h / 4, error / 2.5 at least.
  expectConverges("event-driven kernel velocity vs tolerance", ed, ref, 1e-2, 0.0);
  expectConverges("time-stepping kernel velocity vs dt", ts, ref, 0.4, 0.0);
  // Floor 1e-9 m/s (rad/s): round-off of the velocities.
  expectAgree("kernel velocity after the graze", ed.out[2], ed.out[1], ts.out[2], ts.out[1], 1e-9);
}

// A graze the tooth is not part of: a paddy kernel flying at 1 m/s parallel to a steel wall,
// spinning at w (no gravity), its centre a - dip above the wall, so that its long end dips
// below the wall's surface for a moment each half turn and the first dip kicks it off. At
// w = 2000 rad/s the dip of 0.5 um lasts ~1.3 us of a free-flight step of ~1e-4 s: the gap
// at both ends of the step is tens of micrometres. The event-driven integrator used to
// evaluate such a separated kernel-wall pair only as a bound beyond 1 um, with no rate, so the
// graze check had nothing to interpolate and the contact was missed (0 impacts); every
// separated kernel pair that could close within the step is now exact at its ends.
// Checked for both integrators: every dip is seen (one impact, sent off the wall), the
// response falls continuously with the dip, and a clearance of 0.1 um touches nothing.
Model spinningGrazeModel(IntegratorType type, double dip_m, double w_radps = 2000.0) {
  const double a = 5e-3, b = 1.3e-3;
  Model m = testutil::bareModel(type);
  m.gravity_mps2 = Vec2::Zero();
  KernelModel k = testutil::makeKernel(a, b, Vec2(0.0, a - dip_m), Vec2(1.0, 0.0), 0.0);
  k.initial_angular_velocity_radps = w_radps;
  m.kernels = {k};
  m.obstacles = {testutil::planeObstacle(Vec2::Zero(), Vec2(0.0, 1.0))};
  testutil::setAllContacts(&m, ContactLaw::kRigid, 0.47, 0.5);  // wheat-steel
  m.integrator.tolerance = 1e-6;
  m.integrator.dt_s = 1e-7;  // 13 steps across the 0.5 um dip
  compileModel(&m);
  return m;
}
// Past the first dip (the long axis upright at pi / (2 w) = 0.79 ms) and before the next.
constexpr double kSpinGrazeEnd = 1.2e-3;  // s

TEST_P(HardCase, Scene02SpinningKernelGrazingAWallIsNotMissed) {
  const IntegratorType type = GetParam();
  std::vector<double> vy;
  for (double dip : {5e-6, 5e-7, 5e-8}) {
    SCOPED_TRACE("dip " + num(dip));
    const Model m = spinningGrazeModel(type, dip);
    const RunLog r = runScene(m, kSpinGrazeEnd, 10);
    EXPECT_EQ(r.d.stats.impacts, 1);
    vy.push_back(kernelVelocity(m, r.d, 0).y());
    EXPECT_GT(vy.back(), 0.0);
    EXPECT_TRUE(r.d.z.allFinite() && r.d.u.allFinite());
  }
  // Measured (event-driven): 0.583, 0.196, 0.063 m/s.
  EXPECT_LT(vy[1], vy[0]);
  EXPECT_LT(vy[2], vy[1]);
  const Model clear = spinningGrazeModel(type, -1e-7);
  const RunLog r = runScene(clear, kSpinGrazeEnd, 10);
  EXPECT_TRUE(r.events.empty());
  EXPECT_EQ(kernelVelocity(clear, r.d, 0).y(), 0.0);
}

// The two integrators agree on the kick within their error estimates (event-driven: tolerance
// 1e-6 against 1e-5; time stepping: h = 1e-7 against 2e-7).
TEST(HardCases, Scene02SpinningKernelGrazeIntegratorsAgree) {
  auto response = [](IntegratorType type, const std::string& ov) {
    Model m = spinningGrazeModel(type, 5e-7);
    if (type == kED) m.integrator.tolerance = std::stod(ov);
    if (type == kTS) m.integrator.dt_s = std::stod(ov);
    const RunLog r = runScene(m, kSpinGrazeEnd, 10);
    return VecX(r.d.u.segment<3>(m.kernels[0].dof_offset));
  };
  expectAgree("kernel velocity after the spinning graze", response(kED, "1e-6"),
              response(kED, "1e-5"), response(kTS, "1e-7"), response(kTS, "2e-7"), 1e-9);
}

}  // namespace
}  // namespace hard_cases
}  // namespace threshing_sim
