// One run of a compiled scene to its duration, writing its outputs to streams (files for a
// single run, strings for each run of a batch).
//
// Sampling: the state trace is written every kChunk_s (times --trace-every), event-driven at the
// first step end at or past each chunk end: no step is cut for a sample, only the duration cuts
// one (advancePast), so the steps do not depend on the sampling. Contacts are
// sampled after every advancePast(), at least every time the fastest body could cover the
// broad-phase margin (and at every trace chunk), so that the outcomes see every pair's
// accumulated impulse before it leaves the candidate set. With --forces, the samples are every
// --sample-interval while some tooth-kernel pair is within the margin, for the force histories;
// without it the run is not cut into sample intervals near contacts, as the outcomes' force
// peaks are the core's (RunStats: every accepted step, located peaks and events).
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <string>

#include "app.h"
#include "threshing_sim/core/simulator.h"
#include "threshing_sim/scene/report.h"

namespace threshing_sim {
namespace app {
namespace {

// Simulation time between two trace samples / progress checks [s].
constexpr double kChunk_s = 1e-4;

// Progress on stderr: only once the run has taken 1 s, at most twice a second; carriage-return
// style on a terminal, plain lines otherwise.

class Progress {
 public:
  explicit Progress(bool quiet) : quiet_(quiet), tty_(isatty(fileno(stderr)) != 0) {}

  void update(const Data& data, double duration_s) {
    const auto now = Clock::now();
    if (quiet_ || now - start_ < std::chrono::seconds(1) ||
        (printed_ && now - last_ < std::chrono::milliseconds(500))) {
      return;
    }
    std::fprintf(stderr, "%st=%.4f/%.4f s  impacts=%ld  peak=%.1f N%s", tty_ ? "\r" : "", data.t_s,
                 duration_s, data.stats.impacts, data.stats.peak_normal_force_N, tty_ ? "" : "\n");
    printed_ = true;
    last_ = now;
  }

  // Ends the carriage-return line.
  void finish() const {
    if (printed_ && tty_) std::fprintf(stderr, "\n");
  }

 private:
  using Clock = std::chrono::steady_clock;
  bool quiet_;
  bool tty_;
  bool printed_ = false;
  Clock::time_point start_ = Clock::now();
  Clock::time_point last_;
};

// ---------------------------------------------------------------------------------------------
// The run.

// Opens an output file, or leaves the stream closed when no path was given.
void openOutput(const std::string& path, const char* option, std::ofstream* out) {
  if (path.empty()) return;
  out->open(path);
  if (!*out) throw OptionError(std::string("cannot open ") + option + " file '" + path + "'");
}

// A write that failed (disk full, /dev/full) is refused like a bad path (exit 2).
void checkWritten(const std::string& path, const char* option, std::ofstream* out) {
  if (!out->is_open()) return;
  out->close();
  if (out->fail())
    throw OptionError(std::string("error writing ") + option + " file '" + path + "'");
}

// Whether contacts must be sampled finely: some tooth-kernel pair is within the broad-phase
// margin (the outcomes' force peaks and the --forces histories are the teeth's).
bool nearContact(const Data& data) {
  return std::any_of(data.contacts.begin(), data.contacts.end(),
                     [](const ContactInfo& c) { return c.pair.kind == PairKind::kToothKernel; });
}

// Longest coarse sampling interval: the time the fastest tooth tip or kernel needs to cover the
// broad-phase margin, so that no contact starts between two looks at data.contacts [s].
double coarseInterval(const Model& model, const Data& data) {
  double speed_mps = 1e-9;
  for (const ToothModel& tooth : model.teeth) {
    speed_mps = std::max(speed_mps, std::abs(data.omega_radps) *
                                        (model.drum.radius_m + tooth.length_m + tooth.diameter_m));
  }
  for (const KernelModel& kernel : model.kernels) {
    speed_mps = std::max(speed_mps, data.u.segment<2>(kernel.dof_offset).norm());
  }
  return std::max(model.broadphase_margin_m, 1e-6) / speed_mps;
}

// "ok", or why a run that returned no failure still has no valid result: energies not finite
// (an overflow the state guard cannot see), or time that did not reach the duration (a time
// step longer than the whole run). Sets *failed then (exit 1).
std::string checkResult(const Model& model, const Data& data, double energy_final_J, bool* failed) {
  char text[160];
  const double h =
      model.integrator.type == IntegratorType::kTimeStepping ? model.integrator.dt_s : 0.0;
  if (!std::isfinite(energy_final_J) || !std::isfinite(data.stats.energy_initial_J) ||
      !std::isfinite(data.stats.drive_work_J)) {
    std::snprintf(text, sizeof(text),
                  "failed: non-finite energy (initial %g J, final %g J, drive work %g J)",
                  data.stats.energy_initial_J, energy_final_J, data.stats.drive_work_J);
  } else if (!(data.t_s > 0) ||
             std::abs(data.t_s - model.duration_s) > 0.5 * h + 1e-9 * model.duration_s) {
    std::snprintf(text, sizeof(text),
                  "failed: simulated %.9g s of the %.9g s duration (time step %g s)", data.t_s,
                  model.duration_s, h);
  } else {
    return "ok";
  }
  *failed = true;
  return text;
}

// A run between its chunks.
struct Run {
  Data data;
  OutcomeTracker tracker;
  double min_interval_s = 0;     // time stepping never samples below one step [s]
  double sample_interval_s = 0;  // force sampling near contacts [s]
  std::chrono::steady_clock::duration stepping_time{0};  // wall time inside advanceTo
  std::string status = "ok";
  bool failed = false;
  Run(const Model& model, const DamageThresholds& damage) : tracker(model, damage) {}
};

// Advances the run to t_chunk_s in sampling intervals (event-driven: to the first step end at or
// past it, the duration's chunk exactly; time stepping: the step nearest it), writing events and
// force samples; stops on a failure. Only the contacts are read between intervals (the samples,
// the --forces rows), so lone kernels stay on their own clocks (advancePastLazy) until the
// chunk's end when `observe` (a trace row, the report) reads the whole state there: that
// interval is advancePast, which brings them to the data's time (the island scheme's catch-up,
// paid once per observation instead of once per interval).
void advanceChunk(const Model& model, double t_chunk_s, bool observe, const RunStreams& out,
                  Run* run) {
  Data& data = run->data;
  for (bool last = false; !last;) {
    const double interval_s = out.forces != nullptr && nearContact(data)
                                  ? run->sample_interval_s
                                  : std::max(coarseInterval(model, data), run->min_interval_s);
    const double t_next_s = std::min(t_chunk_s, data.t_s + interval_s);
    const auto started = std::chrono::steady_clock::now();
    // No step is cut at a sample or chunk end, only at the duration (advancePast): the run's
    // steps do not depend on where it is sampled (--forces, the node's boundaries).
    const bool sync = observe && t_next_s >= t_chunk_s;
    StepStatus step_status = sync ? advancePast(model, &data, t_next_s, model.duration_s)
                                  : advancePastLazy(model, &data, t_next_s, model.duration_s);
    last = run->min_interval_s > 0 ? t_next_s >= t_chunk_s : data.t_s >= t_chunk_s;
    // A step that passed the chunk's end before its last interval: the catch-up now.
    bool synced = sync;
    if (last && observe && !sync && step_status != StepStatus::kFailed) {
      synced = true;
      if (syncBodies(model, &data) == StepStatus::kFailed) step_status = StepStatus::kFailed;
    }
    run->stepping_time += std::chrono::steady_clock::now() - started;
    // Events and contact samples of this interval.
    if (out.events != nullptr) writeEventRows(*out.events, data.events);
    run->tracker.addEvents(data.events);
    data.events.clear();
    if (step_status == StepStatus::kFailed) {
      if (!synced) {  // the report reads the whole state: the lone kernels caught up, as
                      // advancePast does after a failure (the window's failure is the run's)
        const FailureInfo failure = data.stats.failure;
        syncBodies(model, &data);
        data.stats.failure = failure;
      }
      run->status = "failed: " + describe(data.stats.failure);
      run->failed = true;
      return;
    }
    run->tracker.sample(data);
    if (out.forces != nullptr) writeForceRows(*out.forces, data);
  }
}

// The summary, the outcomes and the printed report of a finished (or failed) run.
void reportRun(const Model& model, const DamageThresholds& damage, const Options& options,
               const RunStreams& out, Run* run) {
  const double wall_time_s = std::chrono::duration<double>(run->stepping_time).count();
  const double energy_final_J = mechanicalEnergy(model, run->data);
  if (!run->failed) run->status = checkResult(model, run->data, energy_final_J, &run->failed);
  OutcomeReport report;
  report.kernels = run->tracker.outcomes(run->data);
  report.thresholds = damage;
  report.sample_interval_s = run->sample_interval_s;
  if (out.summary != nullptr) {
    writeSummaryJson(*out.summary, model, run->data, run->status, wall_time_s, energy_final_J,
                     &report);
  }
  if (out.outcomes != nullptr) writeOutcomesCsv(*out.outcomes, report.kernels);
  if (!options.quiet) {
    printSummary(std::cout, model, run->data, run->status, wall_time_s, energy_final_J, &report);
  }
}

// The initial state and the file headers.
void startRun(const Model& model, const Options& options, const RunStreams& out, Run* run) {
  resetData(model, &run->data);
  if (out.trace != nullptr) {
    writeTraceHeader(*out.trace, model);
    writeTraceRow(*out.trace, model, run->data);
  }
  if (out.events != nullptr) writeEventsHeader(*out.events);
  if (out.forces != nullptr) writeForcesHeader(*out.forces);
  run->min_interval_s =
      model.integrator.type == IntegratorType::kTimeStepping ? model.integrator.dt_s : 0.0;
  run->sample_interval_s = std::max(options.sample_interval_s, run->min_interval_s);
}

}  // namespace

int runModel(const Model& model, const DamageThresholds& damage, const Options& options,
             const RunStreams& streams, std::string* status) {
  Run run(model, damage);
  startRun(model, options, streams, &run);
  // Chunks of kChunk_s; the last one lands exactly on the duration.
  const long n_chunks = std::max(1L, std::lround(std::ceil(model.duration_s / kChunk_s - 1e-9)));
  Progress progress(options.quiet);
  double traced_t_s = run.data.t_s;  // time of the last trace row [s]
  for (long chunk = 1; chunk <= n_chunks && !run.failed; ++chunk) {
    // The state is read at the chunk's end for a trace row and, after the last, for the report.
    const bool traced = streams.trace != nullptr && (chunk % options.trace_every == 0);
    advanceChunk(model, chunk == n_chunks ? model.duration_s : chunk * kChunk_s,
                 traced || chunk == n_chunks, streams, &run);
    if (run.failed) break;
    // One row per chunk, at the step end that passed its end (a step longer than a chunk gives
    // one row for the chunks it spans).
    if (streams.trace != nullptr && (chunk % options.trace_every == 0 || chunk == n_chunks) &&
        run.data.t_s > traced_t_s) {
      writeTraceRow(*streams.trace, model, run.data);
      traced_t_s = run.data.t_s;
    }
    progress.update(run.data, model.duration_s);
  }
  progress.finish();
  reportRun(model, damage, options, streams, &run);
  if (status != nullptr) *status = run.status;
  return run.failed ? 1 : 0;
}

int runToFiles(const Model& model, const DamageThresholds& damage, const Options& options) {
  // Opened before the run, so that a bad path fails first.
  std::ofstream summary, trace, events, outcomes, forces;
  openOutput(options.summary_path, "--summary", &summary);
  openOutput(options.trace_path, "--trace", &trace);
  openOutput(options.events_path, "--events", &events);
  openOutput(options.outcomes_path, "--outcomes", &outcomes);
  openOutput(options.forces_path, "--forces", &forces);
  auto stream = [](std::ofstream& f) -> std::ostream* { return f.is_open() ? &f : nullptr; };
  const RunStreams streams{stream(summary), stream(trace), stream(events), stream(outcomes),
                           stream(forces)};
  const int status = runModel(model, damage, options, streams, nullptr);
  checkWritten(options.summary_path, "--summary", &summary);
  checkWritten(options.trace_path, "--trace", &trace);
  checkWritten(options.events_path, "--events", &events);
  checkWritten(options.outcomes_path, "--outcomes", &outcomes);
  checkWritten(options.forces_path, "--forces", &forces);
  return status;
}

}  // namespace app
}  // namespace threshing_sim
