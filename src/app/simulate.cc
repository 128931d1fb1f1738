// simulate: the headless command-line simulator.
//
// Loads a scene (with --set overrides), runs it to its duration in chunks of simulation time,
// and writes a JSON summary, a state trace and an event log on request. Exit status: 0 on
// success, 1 when the integrator failed, 2 for a bad scene or command line.
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "threshing_sim/core/simulator.h"
#include "threshing_sim/scene/report.h"
#include "threshing_sim/scene/scene_loader.h"

namespace threshing_sim {
namespace {

const char kUsage[] =
    "usage: simulate SCENE.yaml [--duration S] [--integrator event_driven|time_stepping] "
    "[--dt S] [--tolerance X] [--set key.path=value]... [--summary FILE.json] "
    "[--trace FILE.csv] [--trace-every N] [--events FILE.csv] [--modes] [--quiet]";

// Simulation time between two trace samples / progress checks [s].
constexpr double kChunk_s = 1e-4;

// Revolutions per minute in one rad/s.
constexpr double kRpmPerRadps = 30.0 / 3.14159265358979323846;

// A bad option or output file (exit 2); UsageError also prints the usage line.
class OptionError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};
class UsageError : public OptionError {
 public:
  using OptionError::OptionError;
};

struct Options {
  std::string scene_path;
  std::vector<std::string> overrides;  // --set ones first, then the sugar options
  std::string summary_path;
  std::string trace_path;
  std::string events_path;
  int trace_every = 1;
  bool modes = false;
  bool quiet = false;
  bool help = false;
};

// ---------------------------------------------------------------------------------------------
// Command line.

// Accepts "--name value" and "--name=value"; the sugar options become overrides applied after
// every --set.
Options parseOptions(int argc, char** argv) {
  Options options;
  std::optional<std::string> duration, integrator, dt, tolerance;
  for (int i = 1; i < argc; ++i) {
    std::string arg = argv[i];
    std::optional<std::string> inline_value;
    const size_t equals = arg.find('=');
    if (arg.rfind("--", 0) == 0 && equals != std::string::npos) {
      inline_value = arg.substr(equals + 1);
      arg = arg.substr(0, equals);
    }
    const auto value = [&]() -> std::string {
      if (inline_value) return *inline_value;
      if (i + 1 >= argc) throw UsageError("option " + arg + " needs a value");
      return argv[++i];
    };
    const auto flag = [&]() {
      if (inline_value) throw UsageError("option " + arg + " takes no value");
      return true;
    };

    if (arg == "--duration") {
      duration = value();
    } else if (arg == "--integrator") {
      integrator = value();
    } else if (arg == "--dt") {
      dt = value();
    } else if (arg == "--tolerance") {
      tolerance = value();
    } else if (arg == "--set") {
      options.overrides.push_back(value());
    } else if (arg == "--summary") {
      options.summary_path = value();
    } else if (arg == "--trace") {
      options.trace_path = value();
    } else if (arg == "--events") {
      options.events_path = value();
    } else if (arg == "--trace-every") {
      const std::string text = value();
      size_t used = 0;
      try {
        options.trace_every = std::stoi(text, &used);
      } catch (const std::logic_error&) {
        used = 0;
      }
      if (used != text.size() || options.trace_every < 1) {
        throw UsageError("--trace-every expects an integer >= 1 (got '" + text + "')");
      }
    } else if (arg == "--modes") {
      options.modes = flag();
    } else if (arg == "--quiet") {
      options.quiet = flag();
    } else if (arg == "--help" || arg == "-h") {
      options.help = flag();
    } else if (arg.rfind("-", 0) == 0) {
      throw UsageError("unknown option '" + arg + "'");
    } else if (options.scene_path.empty()) {
      options.scene_path = arg;
    } else {
      throw UsageError("more than one scene file ('" + options.scene_path + "', '" + arg + "')");
    }
  }
  if (options.scene_path.empty() && !options.help) throw UsageError("no scene file given");

  // Sugar options, after the --set ones.
  if (duration) options.overrides.push_back("duration=" + *duration);
  if (integrator) options.overrides.push_back("integrator.type=" + *integrator);
  if (dt) options.overrides.push_back("integrator.dt=" + *dt);
  if (tolerance) options.overrides.push_back("integrator.tolerance=" + *tolerance);
  return options;
}

// ---------------------------------------------------------------------------------------------
// --modes: natural frequencies of each tooth at rest and at the scene's drum speed.

void printFrequencies(const VecX& frequencies_Hz) {
  for (Eigen::Index j = 0; j < frequencies_Hz.size(); ++j) {
    std::printf("%s%.6g", j ? ", " : " ", frequencies_Hz[j]);
  }
  std::printf(" Hz\n");
}

void printModes(const Model& model) {
  const double omega_radps = model.drum.initial_speed_radps;
  for (size_t k = 0; k < model.teeth.size(); ++k) {
    const ToothModel& tooth = model.teeth[k];
    std::printf("tooth %zu: L %.6g m, d %.6g m, E %.6g Pa, rho %.6g kg/m^3, %d modes\n", k,
                tooth.length_m, tooth.diameter_m, tooth.youngs_modulus_Pa, tooth.density_kgpm3,
                tooth.n_modes);
    if (tooth.n_modes == 0) {
      std::printf("  rigid tooth: no bending modes\n");
      continue;
    }
    std::printf("  at rest:");
    printFrequencies(toothFrequenciesHz(tooth, 0.0));
    std::printf("  at %.6g rad/s (%.6g rpm):", omega_radps, omega_radps * kRpmPerRadps);
    printFrequencies(toothFrequenciesHz(tooth, omega_radps));
  }
}

// ---------------------------------------------------------------------------------------------
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

void checkWritten(const std::string& path, std::ofstream* out) {
  if (!out->is_open()) return;
  out->close();
  if (out->fail()) throw std::runtime_error("error writing '" + path + "'");
}

// Steps to the duration chunk by chunk, writing trace rows and draining events as it goes.
// Returns the exit status.
int run(const Model& model, const Options& options) {
  // Outputs first, so that a bad path fails before the run.
  std::ofstream summary, trace, events;
  openOutput(options.summary_path, "--summary", &summary);
  openOutput(options.trace_path, "--trace", &trace);
  openOutput(options.events_path, "--events", &events);

  // Initial state and file headers.
  Data data;
  resetData(model, &data);
  if (trace.is_open()) {
    writeTraceHeader(trace, model);
    writeTraceRow(trace, model, data);
  }
  if (events.is_open()) writeEventsHeader(events);

  // Chunks of kChunk_s; the last one lands exactly on the duration. Wall time counts only the
  // time spent inside advanceTo.
  const long n_chunks = std::max(1L, std::lround(std::ceil(model.duration_s / kChunk_s - 1e-9)));
  std::chrono::steady_clock::duration stepping_time{0};
  Progress progress(options.quiet);
  std::string status = "ok";
  bool failed = false;
  for (long chunk = 1; chunk <= n_chunks; ++chunk) {
    const double t_next_s = chunk == n_chunks ? model.duration_s : chunk * kChunk_s;
    const auto started = std::chrono::steady_clock::now();
    const StepStatus step_status = advanceTo(model, &data, t_next_s);
    stepping_time += std::chrono::steady_clock::now() - started;

    // Outputs for this chunk.
    if (events.is_open()) writeEventRows(events, data.events);
    data.events.clear();
    if (step_status == StepStatus::kFailed) {
      char text[96];
      std::snprintf(text, sizeof(text), "failed: non-finite state at t = %.9g s, not recovered",
                    data.t_s);
      status = text;
      failed = true;
      break;
    }
    if (trace.is_open() && (chunk % options.trace_every == 0 || chunk == n_chunks)) {
      writeTraceRow(trace, model, data);
    }
    progress.update(data, model.duration_s);
  }
  progress.finish();

  // Summary.
  const double wall_time_s = std::chrono::duration<double>(stepping_time).count();
  const double energy_final_J = mechanicalEnergy(model, data);
  if (summary.is_open()) {
    writeSummaryJson(summary, model, data, status, wall_time_s, energy_final_J);
  }
  if (!options.quiet) printSummary(std::cout, model, data, status, wall_time_s, energy_final_J);
  checkWritten(options.summary_path, &summary);
  checkWritten(options.trace_path, &trace);
  checkWritten(options.events_path, &events);
  return failed ? 1 : 0;
}

}  // namespace
}  // namespace threshing_sim

int main(int argc, char** argv) {
  using namespace threshing_sim;
  try {
    const Options options = parseOptions(argc, argv);
    if (options.help) {
      std::cout << kUsage << "\n";
      return 0;
    }
    const Model model = loadScene(options.scene_path, options.overrides);
    if (options.modes) {
      printModes(model);
      return 0;
    }
    return run(model, options);
  } catch (const UsageError& e) {
    std::cerr << "simulate: error: " << e.what() << "\n" << kUsage << "\n";
    return 2;
  } catch (const OptionError& e) {
    std::cerr << "simulate: error: " << e.what() << "\n";
    return 2;
  } catch (const SceneError& e) {
    std::cerr << "simulate: error: " << e.what() << "\n";
    return 2;
  } catch (const std::exception& e) {
    std::cerr << "simulate: error: " << e.what() << "\n";
    return 1;
  }
}
