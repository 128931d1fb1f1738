// The parts of the headless simulator (simulate.cc's main) shared by its modes: the command
// line (options.cc), one run to its outputs (run.cc), validation without a run (check.cc) and
// many runs in one process (batch.cc, its JSON lines read by json.cc).
#pragma once

#include <map>
#include <ostream>
#include <stdexcept>
#include <string>
#include <vector>

#include "threshing_sim/core/feed.h"
#include "threshing_sim/core/model.h"
#include "threshing_sim/core/tooth_cache.h"
#include "threshing_sim/scene/outcomes.h"
#include "threshing_sim/scene/scene_tree.h"

namespace threshing_sim {
namespace app {

extern const char kUsage[];

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
  double sample_interval_s = 1e-6;  // contact sampling near contacts (--forces) [s]
  std::string feed_series_path;     // a feed's time series, one row per interval (CSV)
  double feed_interval_s = 0.01;    // the feed series' interval [s]
  int trace_every = 1;
  bool modes = false;
  bool quiet = false;
  bool check = false;            // validate and print the resolved scene, do not run
  std::string check_batch_path;  // lines of tab-separated arguments to validate, "-" = stdin
  bool resolve_only = false;     // --check-batch: resolve (overrides, keys) without compiling
  std::string batch_path;        // JSON lines of runs to run in this process, "-" = stdin
  bool help = false;
  bool print_schema = false;  // print the scene key table (types, units, ranges) and exit
};

// The command line (argv[0] is skipped). Throws UsageError.
Options parseOptions(int argc, char** argv);

// Where a run writes its outputs; a null stream is an output not asked for.
struct RunStreams {
  std::ostream* summary = nullptr;
  std::ostream* trace = nullptr;
  std::ostream* events = nullptr;
  std::ostream* outcomes = nullptr;
  std::ostream* forces = nullptr;
};

// Runs the model to its duration, writing the outputs to the streams (and, unless
// options.quiet, progress to stderr and the readable summary to stdout). *status gets the
// summary's status ("ok" or why it failed). Returns the exit status: 0, or 1 when it failed.
int runModel(const Model& model, const DamageThresholds& damage, const Options& options,
             const RunStreams& streams, std::string* status);

// runModel with the output files of the options (opened first, so that a bad path fails
// before the run; a failed write is an OptionError).
int runToFiles(const Model& model, const DamageThresholds& damage, const Options& options);

// A scene with a feed (core/feed.h) run to its duration (feed_run.cc): the feed updated at
// every feed step, the retired kernels' outcomes (--outcomes), the time series per
// --feed-interval (--feed-series), totals in the summary (--summary and stdout). Returns the
// exit status: 0, or 1 when the run failed (the integrator, or a pool with no free slot).
int runFeedToFiles(Model model, const FeedSpec& feed, const DamageThresholds& damage,
                   const Options& options);

// Scene trees with their override files applied, by scene and file paths: one parse for all
// the runs that share them.
using TreeCache = std::map<std::string, SceneNode>;

// The scene's tree with its override files applied (from the cache when given; a copy).
// Throws SceneError.
SceneNode sceneWithFiles(const Options& options, TreeCache* cache);

// Base scenes (a scene with its override files applied) as one line of flow-style YAML, by the
// TreeCache's key.
using BaseTexts = std::map<std::string, std::string>;

// Loads, overrides, validates and compiles the scene as a run would, and returns the resolved
// scene as one line of flow-style YAML. With bases and base given, *base points to the base
// scene's text (before the --set overrides; kept in *bases). With teeth given, the teeth are
// compiled through it (core/tooth_cache.h). Throws SceneError.
// With compile false, the model is neither built nor checked (only the overrides are applied).
std::string resolvedScene(const Options& options, TreeCache* cache = nullptr,
                          BaseTexts* bases = nullptr, const std::string** base = nullptr,
                          ToothCache* teeth = nullptr, bool compile = true);

// --check-batch: one line of tab-separated arguments per run; prints
// "ok<TAB>resolved scene<TAB>base scene" or "error<TAB>message" per line. Returns 0 when
// every line is valid, else 2. With resolve_only the scenes are resolved (override files and
// --set values applied: a bad key path is refused) but not compiled: the --batch processes
// that run them validate the rest (batch.cc, "hold" and "barrier").
int checkBatch(const std::string& path, bool resolve_only = false);

// --batch: one JSON object per line, one run each; prints one JSON line per run as it ends.
// Returns the highest exit status of the runs (0, 1 or 2). Defined in batch.cc.
int runBatch(const std::string& path);

}  // namespace app
}  // namespace threshing_sim
