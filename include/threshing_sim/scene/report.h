// threshing_sim result writers: run summary (JSON and prose), state trace and event log (CSV).
//
// Numbers in the machine-readable files are printed with %.17g, so two runs that agree bit for
// bit produce identical files.
#pragma once

#include <ostream>
#include <string>
#include <vector>

#include "threshing_sim/core/data.h"
#include "threshing_sim/core/model.h"
#include "threshing_sim/scene/outcomes.h"

namespace threshing_sim {

// Outcomes of a run as reported: per kernel (outcomes.h) and the thresholds they were judged by.
struct OutcomeReport {
  std::vector<KernelOutcome> kernels;
  DamageThresholds thresholds;
  double sample_interval_s = 0;  // contact sampling interval near teeth (--forces samples) [s]
};

// The island-local scheduler's work by kind (RunStats::scheduler) as a one-line JSON object.
std::string schedulerJson(const SchedulerStats& s);

// Summary of a run as one JSON object: status, times, step and impact counts, force peaks,
// energy balance, warnings and the final state of each kernel; with outcomes, an "outcomes"
// object (thresholds, totals over the kernels, one entry per kernel). Non-finite numbers are
// written as null and the status then names them.
void writeSummaryJson(std::ostream& out, const Model& model, const Data& data,
                      const std::string& status, double wall_time_s, double energy_final_J,
                      const OutcomeReport* outcomes = nullptr);

// The same key numbers as one readable paragraph (SI prefixes), then the outcomes (totals, and
// one line per kernel for up to 10 kernels), then one line per warning.
void printSummary(std::ostream& out, const Model& model, const Data& data,
                  const std::string& status, double wall_time_s, double energy_final_J,
                  const OutcomeReport* outcomes = nullptr);

// Outcomes CSV: one row per kernel (columns as KernelOutcome, damage as none/plastic/fracture,
// detach_time_s empty when attached).
void writeOutcomesCsv(std::ostream& out, const std::vector<KernelOutcome>& outcomes);

// Contact force samples: t_s, kind, a, b, state, gap_m, normal_force_N, tangential_force_N for
// every pair in data.contacts (pairs within the broad-phase margin) at data.t_s.
void writeForcesHeader(std::ostream& out);
void writeForceRows(std::ostream& out, const Data& data);

// State trace: t_s, theta_rad, omega_radps; per kernel i k{i}_x_m, k{i}_y_m, k{i}_psi_rad,
// k{i}_vx_mps, k{i}_vy_mps, k{i}_omega_radps; per tooth k tooth{k}_tip_deflection_m and its
// modal coordinates tooth{k}_q{j}.
void writeTraceHeader(std::ostream& out, const Model& model);
void writeTraceRow(std::ostream& out, const Model& model, const Data& data);

// Event log: one row per ContactEvent (t_s, kind, a, b, from, to, is_impact, velocities before
// and after, impulses, energy lost, peak force, macro- and sub-collision indices).
void writeEventsHeader(std::ostream& out);
void writeEventRows(std::ostream& out, const std::vector<ContactEvent>& events);

}  // namespace threshing_sim
