// Tests of the per-kernel outcomes: on synthetic event streams and contact samples (counting
// rules, damage thresholds, peak separation, impulses), then on short runs of the threshing
// scenes in config/scenes (the behaviours the paper claims, where this model shows them).
#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <string>
#include <vector>

#include "threshing_sim/core/simulator.h"
#include "threshing_sim/scene/outcomes.h"
#include "threshing_sim/scene/scene_loader.h"

namespace threshing_sim {
namespace {

// ---------------------------------------------------------------------------------------------
// Synthetic streams.

// Two kernels of 28 and 30 mg; the outcomes only read masses and counts from the model.
Model twoKernelModel() {
  Model m;
  m.kernels.resize(2);
  m.kernels[0].mass_kg = 2.8e-5;
  m.kernels[1].mass_kg = 3.0e-5;
  return m;
}

ContactEvent impact(double t_s, PairKind kind, int a, int b, int macro, int sub,
                    double vn_before_mps = -1.0, double impulse_Ns = 1e-4) {
  ContactEvent e;
  e.t_s = t_s;
  e.pair = PairId{kind, a, b};
  e.from = ContactState::kSlip;
  e.to = ContactState::kSeparated;
  e.is_impact = true;
  e.vn_before_mps = vn_before_mps;
  e.impulse_normal_Ns = impulse_Ns;
  e.macro_collision = macro;
  e.sub_collision = sub;
  return e;
}

ContactInfo contact(PairKind kind, int a, int b, double fn_N, double ft_N,
                    double impulse_acc_Ns = 0.0) {
  ContactInfo c;
  c.pair = PairId{kind, a, b};
  c.state = fn_N > 0 ? ContactState::kSlip : ContactState::kSeparated;
  c.normal_force_N = fn_N;
  c.tangential_force_N = ft_N;
  c.impulse_normal_Ns = impulse_acc_Ns;
  return c;
}

// Data as the tracker sees it at the end of a run with the given per-kernel statistics: the
// largest normal force of any contact and the detach time of each kernel, and optionally the
// tooth force peaks.
Data endOfRun(const std::vector<double>& stats_peak_N, const std::vector<double>& detach_s,
              const std::vector<KernelToothPeaks>& tooth_peaks = {}) {
  Data d;
  d.stats.kernel_peak_normal_force_N = stats_peak_N;
  d.stats.kernel_detach_time_s = detach_s;
  d.stats.kernel_tooth_peaks = tooth_peaks;
  if (tooth_peaks.empty()) d.stats.kernel_tooth_peaks.resize(stats_peak_N.size());
  return d;
}

TEST(Outcomes, CountsSubCollisionsPerToothMacroCollision) {
  const Model m = twoKernelModel();
  OutcomeTracker tracker(m, DamageThresholds());
  // Tooth 0 on kernel 0: macro 0 holds three sub-collisions, macro 1 one; tooth 1 on kernel 0:
  // one more macro-collision. The obstacle impact and the transition are not sub-collisions.
  ContactEvent transition = impact(0.5e-3, PairKind::kToothKernel, 0, 0, -1, -1);
  transition.is_impact = false;
  tracker.addEvents({impact(1.0e-3, PairKind::kToothKernel, 0, 0, 0, 0), transition,
                     impact(1.2e-3, PairKind::kToothKernel, 0, 0, 0, 1),
                     impact(1.3e-3, PairKind::kKernelObstacle, 0, 3, 0, 0)});
  tracker.addEvents({impact(1.5e-3, PairKind::kToothKernel, 0, 0, 0, 2),
                     impact(6.0e-3, PairKind::kToothKernel, 0, 0, 1, 0),
                     impact(7.0e-3, PairKind::kToothKernel, 1, 0, 0, 0)});
  const std::vector<KernelOutcome> out = tracker.outcomes(endOfRun({0, 0}, {-1, -1}));
  ASSERT_EQ(out.size(), 2u);
  EXPECT_EQ(out[0].impacts, 6);
  EXPECT_EQ(out[0].macro_collisions, 3);
  EXPECT_EQ(out[0].sub_collisions, 5);
  EXPECT_EQ(out[0].max_sub_collisions, 3);
  EXPECT_DOUBLE_EQ(out[0].subCollisionsPerMacro(), 5.0 / 3.0);
  EXPECT_EQ(out[1].impacts, 0);
  EXPECT_EQ(out[1].macro_collisions, 0);
  EXPECT_DOUBLE_EQ(out[1].subCollisionsPerMacro(), 0.0);
}

TEST(Outcomes, KernelKernelImpactsCountForBothWithReducedMass) {
  const Model m = twoKernelModel();
  OutcomeTracker tracker(m, DamageThresholds());
  tracker.addEvents({impact(1e-3, PairKind::kKernelKernel, 0, 1, 0, 0, -2.0),
                     impact(2e-3, PairKind::kToothKernel, 0, 1, 0, 0, -1.0)});
  const std::vector<KernelOutcome> out = tracker.outcomes(endOfRun({0, 0}, {-1, -1}));
  const double reduced_kg = 2.8e-5 * 3.0e-5 / (2.8e-5 + 3.0e-5);
  EXPECT_EQ(out[0].impacts, 1);
  EXPECT_EQ(out[1].impacts, 2);
  EXPECT_DOUBLE_EQ(out[0].max_impact_energy_J, 0.5 * reduced_kg * 4.0);
  EXPECT_DOUBLE_EQ(out[1].max_impact_energy_J, 0.5 * reduced_kg * 4.0);  // > 0.5 m 1^2
  EXPECT_EQ(out[0].macro_collisions, 0);
  EXPECT_EQ(out[1].macro_collisions, 1);
}

TEST(Outcomes, DamageThresholds) {
  const DamageThresholds rice;
  EXPECT_EQ(classifyDamage(0.0, rice), DamageClass::kNone);
  EXPECT_EQ(classifyDamage(138.99, rice), DamageClass::kNone);
  EXPECT_EQ(classifyDamage(139.0, rice), DamageClass::kPlastic);
  EXPECT_EQ(classifyDamage(145.99, rice), DamageClass::kPlastic);
  EXPECT_EQ(classifyDamage(146.0, rice), DamageClass::kFracture);
  const DamageThresholds custom{50.0, 80.0};
  EXPECT_EQ(classifyDamage(60.0, custom), DamageClass::kPlastic);
  EXPECT_STREQ(toString(DamageClass::kFracture), "fracture");

  // The class comes from the largest force of any contact, the core's statistic (here 140 N
  // on kernel 0, of which a tooth contributed only 30 N), not from the tooth peak.
  const Model m = twoKernelModel();
  OutcomeTracker tracker(m, rice);
  const std::vector<KernelOutcome> out =
      tracker.outcomes(endOfRun({140.0, 150.0}, {-1, -1}, {{30.0, 1e-3, 5.0, 1e-3}, {}}));
  EXPECT_DOUBLE_EQ(out[0].peak_normal_force_N, 30.0);
  EXPECT_DOUBLE_EQ(out[0].max_contact_force_N, 140.0);
  EXPECT_EQ(out[0].damage, DamageClass::kPlastic);
  EXPECT_DOUBLE_EQ(out[1].peak_normal_force_N, 0.0);
  EXPECT_DOUBLE_EQ(out[1].max_contact_force_N, 150.0);
  EXPECT_EQ(out[1].damage, DamageClass::kFracture);
}

TEST(Outcomes, PeaksAndSeparationFromCoreStatistics) {
  const Model m = twoKernelModel();
  OutcomeTracker tracker(m, DamageThresholds());
  // Kernel 0: tangential peak (8 N) 30 us before the normal peak (40 N); contact samples do not
  // change the peaks any more (a larger sampled tooth force is ignored).
  Data d;
  d.t_s = 190e-6;
  d.contacts = {contact(PairKind::kToothKernel, 0, 0, 99.0, 50.0)};
  tracker.sample(d);
  const std::vector<KernelOutcome> out =
      tracker.outcomes(endOfRun({90.0, 0.0}, {-1, -1}, {{40.0, 160e-6, 8.0, 130e-6}, {}}));
  EXPECT_DOUBLE_EQ(out[0].peak_normal_force_N, 40.0);
  EXPECT_DOUBLE_EQ(out[0].time_of_peak_normal_s, 160e-6);
  EXPECT_DOUBLE_EQ(out[0].peak_tangential_force_N, 8.0);
  EXPECT_DOUBLE_EQ(out[0].time_of_peak_tangential_s, 130e-6);
  EXPECT_NEAR(out[0].peak_separation_s, -30e-6, 1e-18);
  EXPECT_DOUBLE_EQ(out[0].max_contact_force_N, 90.0);
  // No tooth contact: no peak times, no separation.
  EXPECT_LT(out[1].time_of_peak_normal_s, 0.0);
  EXPECT_DOUBLE_EQ(out[1].peak_separation_s, 0.0);
}

TEST(Outcomes, ImpulseAndDetachment) {
  const Model m = twoKernelModel();
  OutcomeTracker tracker(m, DamageThresholds());
  // Pair (tooth 0, kernel 0): events 2e-4 + 3e-4, samples saw 4e-4 accumulated -> 5e-4.
  // Pair (kernel 0, obstacle 0): one impact of 1e-4, samples saw 7e-4 (persistent contact).
  tracker.addEvents({impact(1e-3, PairKind::kToothKernel, 0, 0, 0, 0, -1.0, 2e-4),
                     impact(2e-3, PairKind::kToothKernel, 0, 0, 0, 1, -1.0, 3e-4),
                     impact(3e-3, PairKind::kKernelObstacle, 0, 0, 0, 0, -1.0, 1e-4)});
  Data d;
  d.contacts = {contact(PairKind::kToothKernel, 0, 0, 0.0, 0.0, 4e-4),
                contact(PairKind::kKernelObstacle, 0, 0, 0.0, 0.0, 7e-4)};
  tracker.sample(d);
  const std::vector<KernelOutcome> out = tracker.outcomes(endOfRun({0, 0}, {2.5e-3, -1}));
  EXPECT_NEAR(out[0].total_normal_impulse_Ns, 5e-4 + 7e-4, 1e-15);
  EXPECT_TRUE(out[0].detached);
  EXPECT_DOUBLE_EQ(out[0].detach_time_s, 2.5e-3);
  EXPECT_FALSE(out[1].detached);
  EXPECT_DOUBLE_EQ(out[1].total_normal_impulse_Ns, 0.0);
}

// ---------------------------------------------------------------------------------------------
// The core's tooth force peaks (RunStats::kernel_tooth_peaks) on the default scene: a nylon tooth
// strikes a free kernel; the contact slides, sticks at t = 291.5 us and slides again before it
// parts. The knead peak is the sliding force mu N just before the stick, between two samples.

Model defaultScene(std::vector<std::string> overrides = {}) {
  return loadScene(std::string(THRESHING_SIM_SOURCE_DIR) + "/config/default_scene.yaml", overrides);
}

// Per step: the peaks are at least every published tooth force. Under time stepping (forces
// once per step, each a step's mean) the normal peak is exactly the largest of them, at the
// step it occurred; the knead peak is the sliding force mu N at the end of the slip, located
// inside its step (docs/model.md §9): above every step's mean, off the step grid.
// The global scheme's steps (integrator.islands: false): a step of the island scheme is a whole
// scheduling window, whose end need not fall inside the contact.
TEST(ToothPeaks, AreTheLargestForceOfEveryAcceptedStep) {
  for (const char* integrator : {"event_driven", "time_stepping"}) {
    const Model m = defaultScene({std::string("integrator.type=") + integrator, "duration=4e-4",
                                  "integrator.islands=false"});
    Data d;
    resetData(m, &d);
    KernelToothPeaks seen;  // largest published tooth forces and when
    while (d.t_s < m.duration_s) {
      ASSERT_NE(step(m, &d), StepStatus::kFailed);
      for (const ContactInfo& c : d.contacts) {
        if (c.pair.kind != PairKind::kToothKernel || c.state == ContactState::kSeparated) continue;
        if (c.normal_force_N > seen.normal_force_N)
          seen = {c.normal_force_N, d.t_s, seen.tangential_force_N, seen.time_of_tangential_s};
        if (std::abs(c.tangential_force_N) > seen.tangential_force_N) {
          seen.tangential_force_N = std::abs(c.tangential_force_N);
          seen.time_of_tangential_s = d.t_s;
        }
      }
    }
    const KernelToothPeaks& core = d.stats.kernel_tooth_peaks.at(0);
    ASSERT_GT(seen.normal_force_N, 10.0) << integrator;
    EXPECT_GE(core.normal_force_N, seen.normal_force_N) << integrator;
    EXPECT_GE(core.tangential_force_N, seen.tangential_force_N) << integrator;
    if (m.integrator.type == IntegratorType::kTimeStepping) {
      EXPECT_EQ(core.normal_force_N, seen.normal_force_N);
      EXPECT_EQ(core.time_of_normal_s, seen.time_of_normal_s);
      const double mu = m.contact[static_cast<int>(PairKind::kToothKernel)].friction;
      EXPECT_GT(core.tangential_force_N, 1.5 * seen.tangential_force_N);
      EXPECT_LE(core.tangential_force_N, mu * core.normal_force_N);
      const double steps = core.time_of_tangential_s / m.integrator.dt_s;
      EXPECT_GT(std::abs(steps - std::round(steps)), 1e-3);
    }
  }
}

// Event-driven: the knead peak sits on the located slip -> stick event, and neither it nor the
// normal peak depends on how often the caller stops the integrator (1 us or 100 us).
TEST(ToothPeaks, DoNotDependOnTheSamplingInterval) {
  const Model m = defaultScene({"duration=4e-4"});
  std::vector<KernelToothPeaks> peaks;
  for (const double interval_s : {1e-6, 1e-4}) {
    Data d;
    resetData(m, &d);
    double stick_s = -1;  // first slip -> stick transition of the tooth contact
    const long n = std::lround(m.duration_s / interval_s);
    for (long i = 1; i <= n; ++i) {
      ASSERT_NE(advanceTo(m, &d, i * interval_s), StepStatus::kFailed);
      for (const ContactEvent& e : d.events) {
        if (stick_s < 0 && e.pair.kind == PairKind::kToothKernel && e.from == ContactState::kSlip &&
            e.to == ContactState::kStick) {
          stick_s = e.t_s;
        }
      }
      d.events.clear();
    }
    const KernelToothPeaks& p = d.stats.kernel_tooth_peaks.at(0);
    ASSERT_GT(stick_s, 0.0) << "interval " << interval_s;
    EXPECT_EQ(p.time_of_tangential_s, stick_s) << "interval " << interval_s;
    EXPECT_LT(p.time_of_tangential_s, p.time_of_normal_s);
    peaks.push_back(p);
  }
  EXPECT_NEAR(peaks[1].tangential_force_N, peaks[0].tangential_force_N,
              1e-4 * peaks[0].tangential_force_N);
  EXPECT_NEAR(peaks[1].time_of_tangential_s, peaks[0].time_of_tangential_s, 1e-9);
  // The normal peak is smooth: the accepted steps around it bound the error.
  EXPECT_NEAR(peaks[1].normal_force_N, peaks[0].normal_force_N, 1e-2 * peaks[0].normal_force_N);
}

// ---------------------------------------------------------------------------------------------
// Short runs of the threshing scenes.

constexpr double kSample_s = 1e-6;  // contact sampling interval, as simulate's default

// A scene of config/scenes with a tooth variant of config/scenes/teeth and extra overrides.
Model scene(const std::string& name, const std::string& variant,
            std::vector<std::string> extra = {}) {
  const std::string dir = std::string(THRESHING_SIM_SOURCE_DIR) + "/config/scenes/";
  std::vector<std::string> overrides = overridesFromFile(dir + "teeth/" + variant + ".yaml");
  overrides.insert(overrides.end(), extra.begin(), extra.end());
  return loadScene(dir + name + ".yaml", overrides);
}

// The outcomes and every event of a run to the scene's duration, contacts sampled every
// kSample_s.
struct RunResult {
  std::vector<KernelOutcome> outcomes;
  std::vector<ContactEvent> events;
};

RunResult run(const Model& model) {
  Data data;
  resetData(model, &data);
  OutcomeTracker tracker(model, DamageThresholds());
  RunResult result;
  const long n = std::lround(model.duration_s / kSample_s);
  for (long i = 1; i <= n; ++i) {
    EXPECT_NE(advanceTo(model, &data, i * kSample_s), StepStatus::kFailed) << "t = " << data.t_s;
    tracker.addEvents(data.events);
    result.events.insert(result.events.end(), data.events.begin(), data.events.end());
    data.events.clear();
    tracker.sample(data);
  }
  result.outcomes = tracker.outcomes(data);
  return result;
}

// Claim 1: in the knead scene the polyurethane tooth's tangential force peaks well before its
// normal force (the contact sticks while the normal force peaks). The stiffer teeth slide at
// their force peak, and with Coulomb sliding the two peaks then coincide (docs/findings.md).
TEST(ThreshingScenes, KneadNormalAndTangentialPeaksAreSeparated) {
  const KernelOutcome k = run(scene("knead", "polyurethane")).outcomes.at(0);
  RecordProperty("peak_separation_us", std::to_string(1e6 * k.peak_separation_s));
  ASSERT_GT(k.peak_normal_force_N, 0.0);
  EXPECT_GT(std::abs(k.peak_separation_s), 10 * kSample_s)
      << "normal peak at " << k.time_of_peak_normal_s << " s, tangential at "
      << k.time_of_peak_tangential_s << " s";
}

// The knead force is a Coulomb friction force: at most mu times the normal force. At 1000 rpm
// the wedged kernel's stick -> slip event is located where the stick solution has run far out
// of the friction cone (kilonewtons); the recorded force at that transition is mu fn.
TEST(ThreshingScenes, KneadForceStaysWithinTheFrictionCone) {
  for (const char* variant : {"polyurethane", "nylon"}) {
    const Model m = scene("knead", variant, {"drum.speed=104.71975511965977"});
    const double mu = m.contact[static_cast<int>(PairKind::kToothKernel)].friction;
    const KernelOutcome k = run(m).outcomes.at(0);
    ASSERT_GT(k.peak_normal_force_N, 0.0) << variant;
    EXPECT_LE(k.peak_tangential_force_N, mu * k.peak_normal_force_N) << variant;
  }
}

// Claim 3: on the same knead scene the polyurethane tooth kneads with less force than the rigid.
TEST(ThreshingScenes, PolyurethaneKneadsLessThanRigid) {
  const KernelOutcome rigid = run(scene("knead", "rigid")).outcomes.at(0);
  const KernelOutcome soft = run(scene("knead", "polyurethane")).outcomes.at(0);
  RecordProperty("knead_rigid_N", std::to_string(rigid.peak_tangential_force_N));
  RecordProperty("knead_polyurethane_N", std::to_string(soft.peak_tangential_force_N));
  ASSERT_GT(soft.peak_tangential_force_N, 0.0);
  EXPECT_LT(soft.peak_tangential_force_N, rigid.peak_tangential_force_N);
}

// Claim 2: struck at its tip, the nylon tooth hits the kernel a second time within the same
// macro-collision: the deflected tip springs back into the kernel its pedicel holds. The rigid
// tooth and the same nylon tooth frozen (no bending modes) hit it once: the extra
// sub-collision comes from the bending. (Elsewhere, e.g. in the knead scene, the rigid tooth has
// as many or more sub-collisions: docs/findings.md.)
TEST(ThreshingScenes, FlexibleToothAddsSubCollisionsWhereRigidHasOne) {
  const std::string tip =
      std::string(THRESHING_SIM_SOURCE_DIR) + "/config/scenes/cases/tip_strike.yaml";
  const std::vector<std::string> at_tip = overridesFromFile(tip);
  std::vector<std::string> frozen = at_tip;
  frozen.push_back("teeth.*.modes=0");
  const KernelOutcome rigid = run(scene("single_strike", "rigid", at_tip)).outcomes.at(0);
  const KernelOutcome nylon = run(scene("single_strike", "nylon", at_tip)).outcomes.at(0);
  const KernelOutcome still = run(scene("single_strike", "nylon", frozen)).outcomes.at(0);
  RecordProperty("sub_per_macro_rigid", std::to_string(rigid.subCollisionsPerMacro()));
  RecordProperty("sub_per_macro_nylon", std::to_string(nylon.subCollisionsPerMacro()));
  ASSERT_EQ(rigid.macro_collisions, 1);
  EXPECT_EQ(rigid.sub_collisions, 1);
  EXPECT_EQ(still.sub_collisions, 1);
  ASSERT_EQ(nylon.macro_collisions, 1);
  EXPECT_GT(nylon.subCollisionsPerMacro(), 1.0);
}

// The core's macro-collision rule, seen in the events of a run: an episode starting within
// macro_collision_gap of the previous one's end is the next sub-collision of the same
// macro-collision, otherwise the first of a new one.
void expectMacroCollisionRule(const std::vector<ContactEvent>& events, double gap_s) {
  std::map<PairId, double> start_s, last_end_s;
  std::map<PairId, std::pair<int, int>> last_index;  // (macro, sub)
  for (const ContactEvent& e : events) {
    if (e.pair.kind != PairKind::kToothKernel) continue;
    if (!e.is_impact && e.from == ContactState::kSeparated) start_s[e.pair] = e.t_s;
    if (!e.is_impact) continue;
    const auto previous = last_index.find(e.pair);
    if (previous == last_index.end()) {
      EXPECT_EQ(e.macro_collision, 0);
      EXPECT_EQ(e.sub_collision, 0);
    } else if (start_s.at(e.pair) - last_end_s.at(e.pair) > gap_s) {
      EXPECT_EQ(e.macro_collision, previous->second.first + 1) << "t = " << e.t_s;
      EXPECT_EQ(e.sub_collision, 0) << "t = " << e.t_s;
    } else {
      EXPECT_EQ(e.macro_collision, previous->second.first) << "t = " << e.t_s;
      EXPECT_EQ(e.sub_collision, previous->second.second + 1) << "t = " << e.t_s;
    }
    last_index[e.pair] = {e.macro_collision, e.sub_collision};
    last_end_s[e.pair] = e.t_s;
  }
}

TEST(ThreshingScenes, MacroCollisionsFollowTheGapRule) {
  // The rigid tooth in the knead scene: several episodes (the kernel rebounds between tooth and
  // bar) less than 2 ms apart make one macro-collision.
  const RunResult wide = run(scene("knead", "rigid"));
  expectMacroCollisionRule(wide.events, 2e-3);
  const KernelOutcome k = wide.outcomes.at(0);
  EXPECT_EQ(k.macro_collisions, 1);
  EXPECT_GT(k.sub_collisions, 1);

  // With a 1 us gap the same episodes are separate macro-collisions.
  const RunResult narrow = run(scene("knead", "rigid", {"macro_collision_gap=1e-6"}));
  expectMacroCollisionRule(narrow.events, 1e-6);
  EXPECT_EQ(narrow.outcomes.at(0).macro_collisions, k.sub_collisions);
  EXPECT_EQ(narrow.outcomes.at(0).max_sub_collisions, 1);
}

// Pedicel force magnitude of kernel i as the core computes it (spring on the elongation, damper
// on its rate) [N].
double pedicelForce(const Model& m, const Data& d, int i) {
  const KernelModel& k = m.kernels[i];
  const double psi = d.z[k.dof_offset + 2];
  const Vec2 r(std::cos(psi) * k.pedicel.p_KP_K.x() - std::sin(psi) * k.pedicel.p_KP_K.y(),
               std::sin(psi) * k.pedicel.p_KP_K.x() + std::cos(psi) * k.pedicel.p_KP_K.y());
  const Vec2 v = d.u.segment<2>(k.dof_offset) + d.u[k.dof_offset + 2] * Vec2(-r.y(), r.x());
  const Vec2 stem = d.z.segment<2>(k.dof_offset) + r - k.pedicel.p_WA_W;
  const double length = stem.norm();
  return std::abs(k.pedicel.stiffness_Npm * (length - k.pedicel.rest_length_m) +
                  k.pedicel.damping_Nspm * stem.dot(v) / length);
}

// Steps the single strike until the pedicel breaks; returns the pedicel force just before and
// at the step that broke it, and checks the detach time is that step's end.
std::pair<double, double> forcesAroundDetachment(const Model& m) {
  Data d;
  resetData(m, &d);
  double before_N = pedicelForce(m, d, 0);
  while (d.kernel_attached[0] && d.t_s < m.duration_s) {
    before_N = pedicelForce(m, d, 0);
    EXPECT_NE(step(m, &d), StepStatus::kFailed);
  }
  EXPECT_FALSE(d.kernel_attached[0]) << "the pedicel never broke";
  EXPECT_DOUBLE_EQ(d.stats.kernel_detach_time_s[0], d.t_s);
  return {before_N, pedicelForce(m, d, 0)};
}

// Steps of the global scheme (integrator.islands: false): the island scheme's step is a whole
// scheduling window, past the located break inside it.
TEST(ThreshingScenes, DetachmentExactlyWhenPedicelForcePassesThreshold) {
  // Event-driven: the crossing is located, so the force at detachment is the threshold.
  const Model ed = scene("single_strike", "nylon", {"integrator.islands=false"});
  const double threshold_N = ed.kernels[0].pedicel.detachment_force_N;
  const auto [ed_before_N, ed_at_N] = forcesAroundDetachment(ed);
  EXPECT_LT(ed_before_N, threshold_N);
  EXPECT_NEAR(ed_at_N, threshold_N, 1e-3 * threshold_N);

  // Time stepping: the first step whose end state passes the threshold breaks it.
  const Model ts = scene("single_strike", "nylon",
                         {"integrator.type=time_stepping", "integrator.islands=false"});
  const auto [ts_before_N, ts_at_N] = forcesAroundDetachment(ts);
  EXPECT_LE(ts_before_N, threshold_N);
  EXPECT_GT(ts_at_N, threshold_N);
}

}  // namespace
}  // namespace threshing_sim
