// simulate: the headless command-line simulator.
//
// Loads a scene (with --set overrides), runs it to its duration in chunks of simulation time,
// and writes a JSON summary, a state trace, an event log, per-kernel outcomes and contact force
// samples on request. Exit status: 0 on success, 1 when the integrator failed, 2 for a bad scene
// or command line. --check only loads and validates the scene (with its overrides) and prints it
// resolved; --check-batch does that for every line of a file (scripts/sweep validates a whole
// sweep in one process).
//
// Sampling: the state trace is written every kChunk_s (times --trace-every). Contacts are
// sampled after every advanceTo(), at least every time the fastest body could cover the
// broad-phase margin (and at every trace chunk), so that the outcomes see every pair's
// accumulated impulse before it leaves the candidate set. With --forces, the samples are every
// --sample-interval while some tooth-kernel pair is within the margin, for the force histories;
// without it the run is not cut into sample intervals near contacts, as the outcomes' force
// peaks are the core's (RunStats: every accepted step, located peaks and events).
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <map>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "threshing_sim/core/constants.h"
#include "threshing_sim/core/simulator.h"
#include "threshing_sim/scene/report.h"
#include "threshing_sim/scene/scene_loader.h"

namespace threshing_sim {
namespace {

const char kUsage[] =
    "usage: simulate SCENE.yaml [--duration S] [--integrator event_driven|time_stepping] "
    "[--dt S] [--tolerance X] [--set-file FILE.yaml]... [--set key.path=value]... "
    "[--summary FILE.json] [--trace FILE.csv] [--trace-every N] [--events FILE.csv] "
    "[--outcomes FILE.csv] [--forces FILE.csv] [--sample-interval S] [--modes] [--quiet] "
    "[--print-schema] [--check] [--check-batch FILE]";

// Simulation time between two trace samples / progress checks [s].
constexpr double kChunk_s = 1e-4;

// Default contact sampling interval near contacts [s]: a few percent of a Hertz contact time
// (32-43 us for a paddy kernel, docs/model.md §9a).
constexpr double kSampleInterval_s = 1e-6;

// Revolutions per minute in one rad/s.
constexpr double kRpmPerRadps = 30.0 / kPi;

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
  std::vector<std::string> set_files;  // override files, applied before every --set
  std::vector<std::string> overrides;  // --set ones first, then the sugar options
  std::string summary_path;
  std::string trace_path;
  std::string events_path;
  std::string outcomes_path;
  std::string forces_path;
  double sample_interval_s = kSampleInterval_s;
  int trace_every = 1;
  bool modes = false;
  bool quiet = false;
  bool check = false;            // validate and print the resolved scene, do not run
  std::string check_batch_path;  // lines of tab-separated arguments to validate, "-" = stdin
  bool help = false;
  bool print_schema = false;  // print the scene key table (types, units, ranges) and exit
};

// ---------------------------------------------------------------------------------------------
// Command line.

// --sample-interval: a number > 0 [s].
double parseSampleInterval(const std::string& text) {
  size_t used = 0;
  double value = 0;
  try {
    value = std::stod(text, &used);
  } catch (const std::logic_error&) {
    used = 0;
  }
  if (text.empty() || used != text.size() || !(value > 0) || !std::isfinite(value))
    throw UsageError("--sample-interval expects a number > 0 in seconds (got '" + text + "')");
  return value;
}

// --trace-every: an integer >= 1.
int parseTraceEvery(const std::string& text) {
  size_t used = 0;
  int value = 0;
  try {
    value = std::stoi(text, &used);
  } catch (const std::logic_error&) {
    used = 0;
  }
  if (text.empty() || used != text.size() || value < 1)
    throw UsageError("--trace-every expects an integer >= 1 (got '" + text + "')");
  return value;
}

// The sugar options, turned into overrides after every --set.
struct Sugar {
  std::optional<std::string> duration, integrator, dt, tolerance;
};

// One command-line option: its name, whether it takes a value, and what it sets.
struct OptionSpec {
  const char* name;
  bool takes_value;
  void (*apply)(const std::string& value, Options* options, Sugar* sugar);
};

const OptionSpec kOptionSpecs[] = {
    {"--duration", true, [](const std::string& v, Options*, Sugar* s) { s->duration = v; }},
    {"--integrator", true, [](const std::string& v, Options*, Sugar* s) { s->integrator = v; }},
    {"--dt", true, [](const std::string& v, Options*, Sugar* s) { s->dt = v; }},
    {"--tolerance", true, [](const std::string& v, Options*, Sugar* s) { s->tolerance = v; }},
    {"--set", true, [](const std::string& v, Options* o, Sugar*) { o->overrides.push_back(v); }},
    {"--set-file", true,
     [](const std::string& v, Options* o, Sugar*) { o->set_files.push_back(v); }},
    {"--summary", true, [](const std::string& v, Options* o, Sugar*) { o->summary_path = v; }},
    {"--trace", true, [](const std::string& v, Options* o, Sugar*) { o->trace_path = v; }},
    {"--events", true, [](const std::string& v, Options* o, Sugar*) { o->events_path = v; }},
    {"--outcomes", true, [](const std::string& v, Options* o, Sugar*) { o->outcomes_path = v; }},
    {"--forces", true, [](const std::string& v, Options* o, Sugar*) { o->forces_path = v; }},
    {"--sample-interval", true,
     [](const std::string& v, Options* o, Sugar*) {
       o->sample_interval_s = parseSampleInterval(v);
     }},
    {"--trace-every", true,
     [](const std::string& v, Options* o, Sugar*) { o->trace_every = parseTraceEvery(v); }},
    {"--modes", false, [](const std::string&, Options* o, Sugar*) { o->modes = true; }},
    {"--check", false, [](const std::string&, Options* o, Sugar*) { o->check = true; }},
    {"--check-batch", true,
     [](const std::string& v, Options* o, Sugar*) { o->check_batch_path = v; }},
    {"--quiet", false, [](const std::string&, Options* o, Sugar*) { o->quiet = true; }},
    {"--print-schema", false,
     [](const std::string&, Options* o, Sugar*) { o->print_schema = true; }},
    {"--help", false, [](const std::string&, Options* o, Sugar*) { o->help = true; }},
    {"-h", false, [](const std::string&, Options* o, Sugar*) { o->help = true; }},
};

const OptionSpec* findOption(const std::string& name) {
  for (const OptionSpec& spec : kOptionSpecs)
    if (name == spec.name) return &spec;
  return nullptr;
}

// A scene path: the first argument that is not an option.
void takeScenePath(const std::string& arg, Options* options) {
  if (arg.rfind("-", 0) == 0) throw UsageError("unknown option '" + arg + "'");
  if (!options->scene_path.empty())
    throw UsageError("more than one scene file ('" + options->scene_path + "', '" + arg + "')");
  options->scene_path = arg;
}

// Accepts "--name value" and "--name=value"; the sugar options become overrides applied after
// every --set.
Options parseOptions(int argc, char** argv) {
  Options options;
  Sugar sugar;
  for (int i = 1; i < argc; ++i) {
    std::string arg = argv[i];
    std::optional<std::string> inline_value;
    const size_t equals = arg.find('=');
    if (arg.rfind("--", 0) == 0 && equals != std::string::npos) {
      inline_value = arg.substr(equals + 1);
      arg = arg.substr(0, equals);
    }
    const OptionSpec* spec = findOption(arg);
    if (spec == nullptr) {
      takeScenePath(arg, &options);
      continue;
    }
    if (!spec->takes_value && inline_value) throw UsageError("option " + arg + " takes no value");
    if (spec->takes_value && !inline_value && i + 1 >= argc)
      throw UsageError("option " + arg + " needs a value");
    spec->apply(!spec->takes_value ? std::string()
                : inline_value     ? *inline_value
                                   : argv[++i],
                &options, &sugar);
  }
  if (options.scene_path.empty() && !options.help && !options.print_schema &&
      options.check_batch_path.empty()) {
    throw UsageError("no scene file given");
  }
  if (sugar.duration) options.overrides.push_back("duration=" + *sugar.duration);
  if (sugar.integrator) options.overrides.push_back("integrator.type=" + *sugar.integrator);
  if (sugar.dt) options.overrides.push_back("integrator.dt=" + *sugar.dt);
  if (sugar.tolerance) options.overrides.push_back("integrator.tolerance=" + *sugar.tolerance);
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
    if (tooth.modes_auto) {
      std::printf("  modes: auto (Hertz contact time estimate %.3g us, see README)\n",
                  tooth.contact_time_s * 1e6);
    }
    if (tooth.residual_modes > tooth.n_modes) {
      std::printf(
          "  static correction from mode %d on: the truncated modes below it are slower than "
          "the contact (Hertz time %.3g us) and left out (docs/model.md 9b; modes: auto or more "
          "modes keeps them)\n",
          tooth.residual_modes + 1, tooth.residual_contact_time_s * 1e6);
    }
    if (tooth.n_modes == 0) {
      std::printf("  rigid tooth: no bending modes\n");
      continue;
    }
    std::printf("  at rest:");
    printFrequencies(toothFrequenciesHz(tooth, 0.0));
    if (tooth.beam_model == ToothBeamModel::kLargeDeflection) {
      std::printf("  large-deflection rod, %d shape functions, linearised at rest:", tooth.n_modes);
      printFrequencies(tooth.ld_frequencies_Hz);
    }
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

// Steps to the duration chunk by chunk, writing trace rows, draining events and sampling
// contacts as it goes. Returns the exit status.
// The run's output files, opened before the run so that a bad path fails first.
struct RunFiles {
  std::ofstream summary, trace, events, outcomes, forces;
  explicit RunFiles(const Options& o) {
    openOutput(o.summary_path, "--summary", &summary);
    openOutput(o.trace_path, "--trace", &trace);
    openOutput(o.events_path, "--events", &events);
    openOutput(o.outcomes_path, "--outcomes", &outcomes);
    openOutput(o.forces_path, "--forces", &forces);
  }
  void checkAllWritten(const Options& o) {
    checkWritten(o.summary_path, "--summary", &summary);
    checkWritten(o.trace_path, "--trace", &trace);
    checkWritten(o.events_path, "--events", &events);
    checkWritten(o.outcomes_path, "--outcomes", &outcomes);
    checkWritten(o.forces_path, "--forces", &forces);
  }
};

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

// Advances the run to t_chunk_s in sampling intervals (the last one lands on t_chunk_s),
// writing events and force samples; stops on a failure.
void advanceChunk(const Model& model, double t_chunk_s, RunFiles* files, Run* run) {
  Data& data = run->data;
  for (bool last = false; !last;) {
    const double interval_s = files->forces.is_open() && nearContact(data)
                                  ? run->sample_interval_s
                                  : std::max(coarseInterval(model, data), run->min_interval_s);
    const double t_next_s = std::min(t_chunk_s, data.t_s + interval_s);
    last = t_next_s >= t_chunk_s;
    const auto started = std::chrono::steady_clock::now();
    const StepStatus step_status = advanceTo(model, &data, t_next_s);
    run->stepping_time += std::chrono::steady_clock::now() - started;
    // Events and contact samples of this interval.
    if (files->events.is_open()) writeEventRows(files->events, data.events);
    run->tracker.addEvents(data.events);
    data.events.clear();
    if (step_status == StepStatus::kFailed) {
      run->status = "failed: " + describe(data.stats.failure);
      run->failed = true;
      return;
    }
    run->tracker.sample(data);
    if (files->forces.is_open()) writeForceRows(files->forces, data);
  }
}

// The summary, the outcomes and the printed report of a finished (or failed) run.
void reportRun(const Model& model, const DamageThresholds& damage, const Options& options,
               RunFiles* files, Run* run) {
  const double wall_time_s = std::chrono::duration<double>(run->stepping_time).count();
  const double energy_final_J = mechanicalEnergy(model, run->data);
  if (!run->failed) run->status = checkResult(model, run->data, energy_final_J, &run->failed);
  OutcomeReport report;
  report.kernels = run->tracker.outcomes(run->data);
  report.thresholds = damage;
  report.sample_interval_s = run->sample_interval_s;
  if (files->summary.is_open()) {
    writeSummaryJson(files->summary, model, run->data, run->status, wall_time_s, energy_final_J,
                     &report);
  }
  if (files->outcomes.is_open()) writeOutcomesCsv(files->outcomes, report.kernels);
  if (!options.quiet) {
    printSummary(std::cout, model, run->data, run->status, wall_time_s, energy_final_J, &report);
  }
}

int run(const Model& model, const DamageThresholds& damage, const Options& options) {
  RunFiles files(options);
  // Initial state and file headers.
  Run run(model, damage);
  resetData(model, &run.data);
  if (files.trace.is_open()) {
    writeTraceHeader(files.trace, model);
    writeTraceRow(files.trace, model, run.data);
  }
  if (files.events.is_open()) writeEventsHeader(files.events);
  if (files.forces.is_open()) writeForcesHeader(files.forces);
  run.min_interval_s =
      model.integrator.type == IntegratorType::kTimeStepping ? model.integrator.dt_s : 0.0;
  run.sample_interval_s = std::max(options.sample_interval_s, run.min_interval_s);
  // Chunks of kChunk_s; the last one lands exactly on the duration.
  const long n_chunks = std::max(1L, std::lround(std::ceil(model.duration_s / kChunk_s - 1e-9)));
  Progress progress(options.quiet);
  for (long chunk = 1; chunk <= n_chunks && !run.failed; ++chunk) {
    advanceChunk(model, chunk == n_chunks ? model.duration_s : chunk * kChunk_s, &files, &run);
    if (run.failed) break;
    if (files.trace.is_open() && (chunk % options.trace_every == 0 || chunk == n_chunks))
      writeTraceRow(files.trace, model, run.data);
    progress.update(run.data, model.duration_s);
  }
  progress.finish();
  reportRun(model, damage, options, &files, &run);
  files.checkAllWritten(options);
  return run.failed ? 1 : 0;
}

// ---------------------------------------------------------------------------------------------
// --check and --check-batch: validation without a run.

// Override files first, so that --set wins over them.
std::vector<std::string> collectOverrides(const Options& options) {
  std::vector<std::string> overrides;
  for (const std::string& path : options.set_files) {
    const std::vector<std::string> from_file = overridesFromFile(path);
    overrides.insert(overrides.end(), from_file.begin(), from_file.end());
  }
  overrides.insert(overrides.end(), options.overrides.begin(), options.overrides.end());
  return overrides;
}

// --check-batch: the tree of each scene with each list of override files applied, parsed once
// for all the lines that share them (key: scene path and file paths, tab-separated).
using TreeCache = std::map<std::string, YAML::Node>;

// The scene's tree with its override files applied (from the cache when given).
YAML::Node sceneWithFiles(const Options& options, TreeCache* cache) {
  std::string key = options.scene_path;
  for (const std::string& path : options.set_files) key += "\t" + path;
  if (cache != nullptr && cache->count(key) != 0) return YAML::Clone(cache->at(key));
  YAML::Node root = loadSceneYaml(options.scene_path);
  for (const std::string& path : options.set_files) {
    for (const std::string& assignment : overridesFromFile(path)) applyOverride(&root, assignment);
  }
  if (cache != nullptr) (*cache)[key] = YAML::Clone(root);
  return root;
}

// The tree as one line of flow-style YAML. Plain scalars made of safe characters are written
// as they are (yaml-cpp's emitter checks every scalar: a large part of a check's time); any
// other scalar goes through the emitter.
void writeFlow(const YAML::Node& node, std::string* out) {
  if (node.IsMap() || node.IsSequence()) {
    *out += node.IsMap() ? "{" : "[";
    bool first = true;
    for (const auto& item : node) {
      if (!first) *out += ", ";
      first = false;
      if (node.IsMap()) {
        writeFlow(item.first, out);
        *out += ": ";
        writeFlow(item.second, out);
      } else {
        writeFlow(item, out);
      }
    }
    *out += node.IsMap() ? "}" : "]";
    return;
  }
  const std::string& text = node.IsScalar() ? node.Scalar() : std::string();
  const bool plain = node.IsScalar() && node.Tag() != "!" && !text.empty() &&
                     std::all_of(text.begin(), text.end(), [](char c) {
                       return std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == '.' ||
                              c == '+' || c == '-';
                     });
  if (plain) {
    *out += text;
    return;
  }
  YAML::Emitter emitter;
  emitter << YAML::Flow << node;
  std::string emitted = emitter.c_str();
  std::replace(emitted.begin(), emitted.end(), '\n', ' ');
  *out += emitted;
}

// A copy of the tree for validation in which every contact restitution that is a number in
// [0, 1] reads 1. Compiling matches a Hunt-Crossley factor to each restitution (tens of ms, a
// function of the restitution alone, whose only check is that range); with 1 it costs nothing,
// and every other check runs on the real values. Others are kept for the loader to refuse.
YAML::Node withoutRestitutionFit(const YAML::Node& root) {
  YAML::Node copy = YAML::Clone(root);
  // Looked up through const nodes: a non-const operator[] would add missing keys.
  const YAML::Node contact = root.IsMap() ? root["contact"] : YAML::Node();
  if (!contact.IsMap()) return copy;
  for (const auto& pair : contact) {
    const YAML::Node law = pair.second;
    const YAML::Node e = law.IsMap() ? law["restitution"] : YAML::Node();
    double value = 0;
    if (e.IsScalar() && e.Tag() != "!" && YAML::convert<double>::decode(e, value) && value >= 0.0 &&
        value <= 1.0) {
      copy["contact"][pair.first.Scalar()]["restitution"] = 1.0;
    }
  }
  return copy;
}

// Loads, overrides, validates and compiles the scene as a run would, and returns the resolved
// scene (every override applied) as one line of flow-style YAML. Throws SceneError.
std::string resolvedScene(const Options& options, TreeCache* cache = nullptr) {
  YAML::Node root = sceneWithFiles(options, cache);
  for (const std::string& assignment : options.overrides) applyOverride(&root, assignment);
  try {
    modelFromYaml(withoutRestitutionFit(root));
    damageFromYaml(root);
  } catch (const SceneError& e) {
    throw SceneError(options.scene_path + ": " + e.what());
  }
  std::string text;
  writeFlow(root, &text);
  return text;
}

// Each line of the file: the arguments of one run (scene, --set, --set-file, ...) separated by
// tabs. Prints one line per input line, "ok<TAB>resolved scene" or "error<TAB>message".
// Returns 0 when every line is valid, else 2.
int checkBatch(const std::string& path) {
  std::ifstream file;
  if (path != "-") {
    file.open(path);
    if (!file) throw OptionError("cannot open --check-batch file '" + path + "'");
  }
  std::istream& in = path == "-" ? std::cin : file;
  int status = 0;
  TreeCache cache;
  for (std::string line; std::getline(in, line);) {
    std::vector<std::string> args = {"simulate"};
    for (size_t start = 0, tab = 0; tab != std::string::npos; start = tab + 1) {
      tab = line.find('\t', start);
      args.push_back(line.substr(start, tab == std::string::npos ? tab : tab - start));
    }
    std::vector<char*> argv;
    for (std::string& arg : args) argv.push_back(arg.data());
    try {
      const std::string scene =
          resolvedScene(parseOptions(static_cast<int>(argv.size()), argv.data()), &cache);
      std::cout << "ok\t" << scene << "\n";
    } catch (const std::exception& e) {
      std::string message = e.what();
      std::replace(message.begin(), message.end(), '\n', ' ');
      std::cout << "error\t" << message << "\n";
      status = 2;
    }
  }
  return status;
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
    if (options.print_schema) {
      std::cout << sceneSchemaTable();
      return 0;
    }
    if (!options.check_batch_path.empty()) return checkBatch(options.check_batch_path);
    if (options.check) {
      std::cout << resolvedScene(options) << "\n";
      return 0;
    }
    DamageThresholds damage;
    const Model model = loadScene(options.scene_path, collectOverrides(options), &damage);
    if (options.modes) {
      printModes(model);
      return 0;
    }
    return run(model, damage, options);
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
