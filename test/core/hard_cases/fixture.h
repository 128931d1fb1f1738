// The shared fixture of the hard-case tests (test/core/hard_cases/*.cc): loading and running
// the scenes of config/hard/, the invariants every scene is checked for, convergence sweeps and
// closed forms. One file per property family includes it; hard_cases.cc instantiates the
// suite over both integrators.
//
// Hard cases both integrators must survive (issue 5): the ten scenes of config/hard/, short
// versions. The long versions run from scripts/stability_table.py (docs/stability.md).
//
// For every scene and both integrators (event_driven, time_stepping; the scene file's
// integrator.type is overridden) the tests check:
//   - no NaN or infinity in z, u at any sample, and advanceTo never fails;
//   - progress: time reaches the end, steps and events per simulated second are bounded;
//   - no impact raises the energy (every is_impact event loses >= -tol, and
//     stats.max_energy_gain_at_impact_J <= tol);
//   - no energy gain beyond the drive's work: E(end) - W_drive <= E(0) + tol, and, for the
//     driven scenes, a variant without drive (drum at rest) whose energy may only fall;
//   - penetration bounded: rigid pairs at the event tolerance (event-driven) or of order
//     h x approach speed (time stepping); compliant pairs by Hertz's closed form;
//   - bit-identical reruns (memcmp of z and u, every field of every event);
//   - convergence as the integrator's knob is refined (tolerance, h) on a key output;
//   - the two integrators agreeing within their error estimates on that key output;
//   - the closed forms where the physics has one (Zeno drop, stick/slip on an incline);
//   - scene 7: the model-validity warning when the tooth leaves the small-deflection range.
// docs/stability.md lists the fixes these scenes needed.
//
// Tolerances are stated where they are used. Two scales recur: the event-driven integrator's
// error scale is tolerance x (1e-2 m or 1 m/s) per step (src/core/event_driven/dopri.cc), and time
// stepping is first order, so its positions are off by O(h v) and event times by O(h).
#pragma once

#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <initializer_list>
#include <string>
#include <vector>

#include "../sim_test_util.h"
#include "threshing_sim/core/constants.h"
#include "threshing_sim/core/simulator.h"
#include "threshing_sim/scene/scene_loader.h"

namespace threshing_sim {
namespace hard_cases {

inline constexpr double kG = 9.81;  // |gravity| in every hard scene [m/s^2]
inline constexpr IntegratorType kED = IntegratorType::kEventDriven;
inline constexpr IntegratorType kTS = IntegratorType::kTimeStepping;

// ---------------------------------------------------------------------------------------------
// Loading and running.

inline const char* integratorName(IntegratorType type) {
  return type == kED ? "event_driven" : "time_stepping";
}

// A number as an override value, exactly (17 significant digits).
inline std::string num(double value) {
  char text[40];
  std::snprintf(text, sizeof(text), "%.17g", value);
  return text;
}
inline std::string vec(double x, double y) { return "[" + num(x) + ", " + num(y) + "]"; }

// config/hard/<file> with the overrides, then the integrator type.
inline Model loadHard(const std::string& file, IntegratorType type,
                      std::vector<std::string> overrides = {}) {
  overrides.push_back(std::string("integrator.type=") + integratorName(type));
  overrides.push_back(testutil::schemeOverride());
#ifdef THRESHING_SIM_CONTACT_STEPS
  // test_hard_cases_contact_phase: compliant contacts by the contact phase's fixed steps (first,
  // so that a test's own integrator.contact_steps wins).
  overrides.insert(overrides.begin(),
                   "integrator.contact_steps=" + std::to_string(THRESHING_SIM_CONTACT_STEPS));
#endif
  return loadScene(std::string(THRESHING_SIM_SOURCE_DIR) + "/config/hard/" + file, overrides);
}

// A drum target speed applied at a step boundary (setDrumTarget).
struct DrumCommand {
  double t_s;
  double target_radps;
};

// What a run leaves for the checks.
struct RunLog {
  Data d;                            // final state and statistics
  std::vector<ContactEvent> events;  // every event of the run, in order
  double t_end_s = 0;
  int samples = 0;
  StepStatus worst = StepStatus::kOk;
  bool finite = true;               // z and u finite at every sample
  double worst_rigid_gap_m = 0;     // most negative gap of a rigid pair seen at a sample [m]
  std::string worst_rigid_what;     // that pair, its state and the time, for failure messages
  double max_tip_deflection_m = 0;  // largest |w(L)| of any tooth at a sample [m]
  double omega_error_radps = 0;     // largest |Omega - the commanded ramp| at a sample
  double multi_contact_s = 0;       // time (by samples) with two or more contacts closed [s]
  double closed_rigid_gap_m = 0;    // largest |gap| of a closed rigid contact at a sample [m]
  double rss_third_bytes = 0;       // resident memory after a third of the samples [bytes]
  double rss_end_bytes = 0;         // and at the end [bytes]
};

// The drum speed the drive must follow: piecewise-linear ramps at the acceleration limit
// between the commands (exact; used to check Omega at the samples).
inline double expectedOmega(const Model& m, const std::vector<DrumCommand>& commands, double t) {
  double omega = m.drum.initial_speed_radps, target = omega, t_prev = 0.0;
  const double a = m.drum.max_acceleration_radps2;
  auto advance = [&](double t_next) {
    const double dt = t_next - t_prev;
    const double gap = target - omega;
    omega = std::abs(gap) <= a * dt ? target : omega + (gap > 0 ? a : -a) * dt;
    t_prev = t_next;
  };
  for (const DrumCommand& c : commands) {
    if (c.t_s > t) break;
    advance(c.t_s);
    target = c.target_radps;
  }
  advance(t);
  return omega;
}

// Resident set size of this process [bytes] (/proc/self/statm, second field in pages).
inline double residentBytes() {
  std::ifstream statm("/proc/self/statm");
  long size = 0, resident = 0;
  statm >> size >> resident;
  return static_cast<double>(resident) * static_cast<double>(sysconf(_SC_PAGESIZE));
}

// Runs from the initial state to t_end, sampling `samples` times at equal intervals (and at
// every command time), applying the drum commands at their times.
inline RunLog runScene(const Model& m, double t_end, int samples = 400,
                       const std::vector<DrumCommand>& commands = {}) {
  RunLog r;
  r.t_end_s = t_end;
  r.samples = samples;
  resetData(m, &r.d);
  std::vector<double> stops;
  for (int i = 1; i <= samples; ++i) stops.push_back(t_end * i / samples);
  for (const DrumCommand& c : commands) {
    if (c.t_s > 0 && c.t_s < t_end) stops.push_back(c.t_s);
  }
  std::sort(stops.begin(), stops.end());
  size_t next_command = 0;
  for (const double t : stops) {
    while (next_command < commands.size() && commands[next_command].t_s <= r.d.t_s + 1e-12) {
      setDrumTarget(m, &r.d, commands[next_command++].target_radps);
    }
    const StepStatus s = advanceTo(m, &r.d, t);
    if (s == StepStatus::kFailed) r.worst = s;
    if (s == StepStatus::kRecovered && r.worst == StepStatus::kOk) r.worst = s;
    r.events.insert(r.events.end(), r.d.events.begin(), r.d.events.end());
    r.d.events.clear();
    r.finite = r.finite && r.d.z.allFinite() && r.d.u.allFinite();
    for (const ContactInfo& c : r.d.contacts) {
      if (m.contact[static_cast<int>(c.pair.kind)].law != ContactLaw::kRigid) continue;
      if (c.gap_m >= r.worst_rigid_gap_m) continue;
      r.worst_rigid_gap_m = c.gap_m;
      r.worst_rigid_what = std::string(toString(c.pair.kind)) + " (" + std::to_string(c.pair.a) +
                           ", " + std::to_string(c.pair.b) + "), " + toString(c.state) +
                           ", at t = " + num(r.d.t_s) + " s";
    }
    for (size_t k = 0; k < m.teeth.size(); ++k) {
      const double w = toothDeflection(m, r.d, static_cast<int>(k), m.teeth[k].length_m);
      r.max_tip_deflection_m = std::max(r.max_tip_deflection_m, std::abs(w));
    }
    r.omega_error_radps = std::max(r.omega_error_radps,
                                   std::abs(r.d.omega_radps - expectedOmega(m, commands, r.d.t_s)));
    int closed = 0;
    for (const ContactInfo& c : r.d.contacts) closed += c.state != ContactState::kSeparated ? 1 : 0;
    if (closed >= 2) r.multi_contact_s += t_end / samples;
    for (const ContactInfo& c : r.d.contacts) {
      if (c.state != ContactState::kSeparated &&
          m.contact[static_cast<int>(c.pair.kind)].law == ContactLaw::kRigid)
        r.closed_rigid_gap_m = std::max(r.closed_rigid_gap_m, std::abs(c.gap_m));
    }
    if (t == stops[stops.size() / 3]) r.rss_third_bytes = residentBytes();
    if (r.worst == StepStatus::kFailed) break;
  }
  r.rss_end_bytes = residentBytes();
  return r;
}

inline Vec2 kernelVelocity(const Model& m, const Data& d, int i) {
  return d.u.segment<2>(m.kernels[i].dof_offset);
}

// Velocity of every kernel, stacked (vx, vy, omega a per kernel: the spin as the speed of the
// kernel's ends, so that all entries are m/s): the usual key output.
inline VecX kernelVelocities(const Model& m, const Data& d) {
  VecX v(3 * m.kernels.size());
  for (size_t i = 0; i < m.kernels.size(); ++i) {
    const int o = m.kernels[i].dof_offset;
    v.segment<3>(3 * i) << d.u[o], d.u[o + 1], d.u[o + 2] * m.kernels[i].semi_axis_a_m;
  }
  return v;
}

inline int countImpacts(const std::vector<ContactEvent>& events, PairKind kind) {
  int n = 0;
  for (const ContactEvent& e : events) n += (e.is_impact && e.pair.kind == kind) ? 1 : 0;
  return n;
}

// ---------------------------------------------------------------------------------------------
// Common properties.

struct Limits {
  double energy_tol_J = 0;         // impact energy gain and the run's energy balance [J]
  double rigid_penetration_m = 0;  // -gap of any rigid pair at a sample [m]
  double penetration_m = 0;        // stats.max_penetration_m, every law [m]
  double max_steps_per_s = 0;      // accepted steps per simulated second
  double max_events_per_s = 0;     // events per simulated second
};

// Steps per simulated second that large-deflection rods add to a time-stepping run under the
// island scheme: a rod has no exact free motion, so it steps in an island of its own (1/h per
// second) while the kernels' islands step too; data.steps counts every island's steps.
inline double rodIslandStepsPerSecond(const Model& m) {
  if (!testutil::kIslandScheme || m.integrator.type != IntegratorType::kTimeStepping) return 0.0;
  double rods = 0.0;
  for (const ToothModel& t : m.teeth)
    if (t.beam_model == ToothBeamModel::kLargeDeflection) rods += 1.0;
  return rods / m.integrator.dt_s;
}

// The properties every run must have, whatever the scene.
inline void expectCommon(const Model& m, const RunLog& r, const Limits& lim) {
  SCOPED_TRACE(std::string("integrator ") + integratorName(m.integrator.type));
  const RunStats& st = r.d.stats;
  // No failure, no NaN/inf, and the run got to its end: event-driven exactly, time stepping
  // within half a step (advanceTo's contract).
  ASSERT_NE(r.worst, StepStatus::kFailed) << "advanceTo failed at t = " << r.d.t_s;
  EXPECT_TRUE(r.finite) << "non-finite z or u";
  if (m.integrator.type == kED) {
    EXPECT_EQ(r.d.t_s, r.t_end_s);
  } else {
    EXPECT_NEAR(r.d.t_s, r.t_end_s, 0.5 * m.integrator.dt_s);
  }
  // Progress: a step counter that rose, bounded work per simulated second.
  EXPECT_GT(r.d.steps, 0);
  EXPECT_LE(r.d.steps / r.t_end_s, lim.max_steps_per_s) << "steps " << r.d.steps;
  EXPECT_LE(r.events.size() / r.t_end_s, lim.max_events_per_s) << "events " << r.events.size();
  // No impact raises the energy (net of the drive's work during it).
  for (const ContactEvent& e : r.events) {
    if (!e.is_impact) continue;
    EXPECT_GE(e.energy_lost_J, -lim.energy_tol_J)
        << "impact at t = " << e.t_s << " of " << toString(e.pair.kind) << " (" << e.pair.a << ", "
        << e.pair.b << ") gained energy";
  }
  EXPECT_LE(st.max_energy_gain_at_impact_J, lim.energy_tol_J);
  // Over the run: mechanical energy minus the drive's work may only fall.
  const double gain = mechanicalEnergy(m, r.d) - st.drive_work_J - st.energy_initial_J;
  EXPECT_LE(gain, lim.energy_tol_J) << "energy gained beyond the drive's work";
  // Penetration: rigid pairs (incl. missed contacts, which stats do not see) and all laws.
  EXPECT_LE(-r.worst_rigid_gap_m, lim.rigid_penetration_m)
      << "a rigid pair penetrates: " << r.worst_rigid_what;
  EXPECT_LE(st.max_penetration_m, lim.penetration_m);
}

// Bit-identical reruns compare with testutil::sameBits / sameEvents (sim_test_util.h).
using testutil::sameBits;
using testutil::sameEvents;

// A second run of the same model (fresh Data) must repeat the first bit for bit.
inline void expectBitIdenticalRerun(const Model& m, const RunLog& first,
                                    const std::vector<DrumCommand>& commands = {}) {
  const RunLog second = runScene(m, first.t_end_s, first.samples, commands);
  EXPECT_TRUE(sameBits(first.d.z, second.d.z))
      << integratorName(m.integrator.type) << ": z differs";
  EXPECT_TRUE(sameBits(first.d.u, second.d.u))
      << integratorName(m.integrator.type) << ": u differs";
  EXPECT_TRUE(sameEvents(first.events, second.events))
      << integratorName(m.integrator.type) << ": events differ";
  EXPECT_EQ(first.d.steps, second.d.steps);
}

// ---------------------------------------------------------------------------------------------
// Convergence and agreement.

// A key output computed at several knob values, coarse to fine.
struct Sweep {
  std::vector<double> knob;
  std::vector<VecX> out;
};

inline double maxAbs(const VecX& v) { return v.cwiseAbs().maxCoeff(); }

// The error of each sweep entry against a reference must fall from the coarsest to the
// finest knob value, by at least `factor`, and never rise by more than `slack` (absolute)
// from one entry to the next (event timing makes the fall uneven).
inline void expectConverges(const char* what, const Sweep& s, const VecX& reference, double factor,
                            double slack) {
  std::vector<double> err;
  std::string text;
  for (size_t i = 0; i < s.out.size(); ++i) {
    err.push_back(maxAbs(s.out[i] - reference));
    char line[96];
    std::snprintf(line, sizeof(line), "  knob %.3g: error %.3e\n", s.knob[i], err.back());
    text += line;
  }
  SCOPED_TRACE(std::string(what) + "\n" + text);
  EXPECT_LE(err.back(), factor * err.front());
  for (size_t i = 1; i < err.size(); ++i) EXPECT_LE(err[i], err[i - 1] + slack);
}

// The two integrators agree within their error estimates: each estimate is the change of the
// key output when the knob is made one sweep step coarser (for first-order time stepping that
// is the error of the finer value; for the event-driven run it bounds it, the error falls
// faster than the knob). `floor` absorbs the case of two estimates near round-off.
inline void expectAgree(const char* what, const VecX& ed, const VecX& ed_coarser, const VecX& ts,
                        const VecX& ts_coarser, double floor) {
  const double est_ed = maxAbs(ed - ed_coarser);
  const double est_ts = maxAbs(ts - ts_coarser);
  const double diff = maxAbs(ed - ts);
  EXPECT_LE(diff, 2.0 * (est_ed + est_ts) + floor)
      << what << ": event-driven and time stepping differ by " << diff << " with error estimates "
      << est_ed << " (event-driven) and " << est_ts << " (time stepping)";
}

// ---------------------------------------------------------------------------------------------
// Hertz closed form.

// Largest indentation of a Hertz contact F = K delta^{3/2} entered at normal speed v by a body
// of mass m against an immovable one, without damping: (5 m v^2 / (4 K))^{2/5} [m]. Damping,
// a flexible tooth and friction only lower it.
inline double hertzIndentation(double mass_kg, double v_mps, double K) {
  return std::pow(5.0 * mass_kg * v_mps * v_mps / (4.0 * K), 0.4);
}

// Smallest Hertz constant K = 4/3 E* sqrt(R*) of a tooth-kernel contact
// (src/core/contact/narrow_phase.cc): R* = sqrt(r_in r_out) smallest where the kernel is most
// curved (b^2 / a) and the tooth is its round tip (radius d/2); across the plane
// r_out = (1/(d/2) + 1/b)^-1.
inline double toothKernelHertzMin(const ToothModel& t, const KernelModel& k) {
  const double e_star = 1.0 / ((1 - t.poisson_ratio * t.poisson_ratio) / t.youngs_modulus_Pa +
                               (1 - k.poisson_ratio * k.poisson_ratio) / k.youngs_modulus_Pa);
  const double r_t = 0.5 * t.diameter_m;
  const double r_k = k.semi_axis_b_m * k.semi_axis_b_m / k.semi_axis_a_m;
  const double r_in = 1.0 / (1.0 / r_t + 1.0 / r_k);
  const double r_out = 1.0 / (1.0 / r_t + 1.0 / k.semi_axis_b_m);
  return 4.0 / 3.0 * e_star * std::sqrt(std::sqrt(r_in * r_out));
}

// Largest approach speed of any contact episode or impact in the run [m/s].
inline double maxApproachSpeed(const std::vector<ContactEvent>& events, PairKind kind) {
  double v = 0.0;
  for (const ContactEvent& e : events) {
    if (e.pair.kind == kind) v = std::max(v, -e.vn_before_mps);
  }
  return v;
}

// The same strike seen from the tooth: the drum at rest and every kernel moving at minus the
// drum's velocity at its centre, Omega (y, -x). Nothing drives the system, so its mechanical
// energy may only fall (centrifugal stiffening is gone, the impact is the same to first order).
// `after` is applied last (a scene may need to place the tooth or set the velocity itself).
inline Model noDriveModel(const std::string& file, IntegratorType type, double t_end,
                          std::vector<std::string> ov = {},
                          const std::vector<std::string>& after = {}) {
  const Model driven = loadHard(file, type, ov);
  const double omega = driven.drum.initial_speed_radps;
  ov.push_back("drum.speed=0");
  for (size_t i = 0; i < driven.kernels.size(); ++i) {
    const Vec2 c = driven.kernels[i].initial_position_m;
    ov.push_back("kernels." + std::to_string(i) +
                 ".velocity=" + vec(omega * c.y(), -omega * c.x()));
  }
  ov.push_back("duration=" + num(t_end));
  ov.insert(ov.end(), after.begin(), after.end());
  return loadHard(file, type, ov);
}

// A scene's key output out(type, knob) at a reference tolerance and over the integrators'
// knobs: event-driven at the tolerances given, time stepping at h = 4, 2, 1 us.
struct KnobSweeps {
  VecX ref;      // event-driven at the reference tolerance
  Sweep ed, ts;  // event-driven over tolerance, time stepping over h
};
template <typename Out>
KnobSweeps knobSweeps(const Out& out, std::initializer_list<double> tolerances,
                      double ref_tolerance) {
  KnobSweeps s;
  s.ref = out(kED, "integrator.tolerance=" + num(ref_tolerance));
  for (double tol : tolerances) {
    s.ed.knob.push_back(tol);
    s.ed.out.push_back(out(kED, "integrator.tolerance=" + num(tol)));
  }
  for (double h : {4e-6, 2e-6, 1e-6}) {
    s.ts.knob.push_back(h);
    s.ts.out.push_back(out(kTS, "integrator.dt=" + num(h)));
  }
  return s;
}

// The usual convergence and agreement check of a scene's key output: against the event-driven
// run at tolerance 1e-10, event-driven over four decades of tolerance (1e-4, 1e-6, 1e-8: a
// factor 100 at least) and time stepping at h = 4, 2, 1 us (first order: h / 4 halves the error
// at least), no rise beyond 1e-9 (round-off); the two integrators agree on `agreed` within
// their error estimates.
template <typename Out>
void expectKnobSweepConvergesAndAgrees(const Out& out, const char* agreed) {
  const KnobSweeps s = knobSweeps(out, {1e-4, 1e-6, 1e-8}, 1e-10);
  expectConverges("event-driven kernel velocity vs tolerance", s.ed, s.ref, 1e-2, 1e-9);
  expectConverges("time-stepping kernel velocity vs dt", s.ts, s.ref, 0.5, 1e-9);
  expectAgree(agreed, s.ed.out[1], s.ed.out[0], s.ts.out[2], s.ts.out[1], 1e-9);
}

class HardCase : public ::testing::TestWithParam<IntegratorType> {};

inline std::string paramName(const ::testing::TestParamInfo<IntegratorType>& info) {
  return integratorName(info.param);
}
}  // namespace hard_cases
}  // namespace threshing_sim
