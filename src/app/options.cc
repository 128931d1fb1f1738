// simulate's command line: the options, their values and the usage line.
#include <cmath>
#include <optional>
#include <string>
#include <vector>

#include "app.h"
#include "threshing_sim/scene/number_text.h"
#include "threshing_sim/scene/scene_loader.h"

namespace threshing_sim {
namespace app {

const char kUsage[] =
    "usage: simulate SCENE.yaml [--duration S] [--integrator event_driven|time_stepping] "
    "[--dt S] [--tolerance X] [--set-file FILE.yaml]... [--set key.path=value]... "
    "[--summary FILE.json] [--trace FILE.csv] [--trace-every N] [--events FILE.csv] "
    "[--outcomes FILE.csv] [--forces FILE.csv] [--sample-interval S] [--feed-series FILE.csv] "
    "[--feed-interval S] [--modes] [--quiet] "
    "[--print-schema] [--check] [--check-batch FILE [--resolve-only]] [--batch FILE.jsonl]";

namespace {

// --sample-interval: a number > 0 [s].
double parseSampleInterval(const std::string& text) {
  const std::optional<double> value = doubleFromText(text);
  if (!value || !(*value > 0))
    throw UsageError("--sample-interval expects a number > 0 in seconds (got '" + text + "')");
  return *value;
}

// --feed-interval: a number in [1e-4, 1e4] [s] (at least the feed's update interval).
double parseFeedInterval(const std::string& text) {
  const std::optional<double> value = doubleFromText(text);
  if (!value || !(*value >= 1e-4 && *value <= 1e4))
    throw UsageError("--feed-interval expects a number in [1e-4, 1e4] seconds (got '" + text +
                     "')");
  return *value;
}

// --trace-every: an integer >= 1.
int parseTraceEvery(const std::string& text) {
  const std::optional<int> value = intFromText(text);
  if (!value || *value < 1)
    throw UsageError("--trace-every expects an integer >= 1 (got '" + text + "')");
  return *value;
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
    {"--feed-series", true,
     [](const std::string& v, Options* o, Sugar*) { o->feed_series_path = v; }},
    {"--feed-interval", true,
     [](const std::string& v, Options* o, Sugar*) { o->feed_interval_s = parseFeedInterval(v); }},
    {"--trace-every", true,
     [](const std::string& v, Options* o, Sugar*) { o->trace_every = parseTraceEvery(v); }},
    {"--modes", false, [](const std::string&, Options* o, Sugar*) { o->modes = true; }},
    {"--check", false, [](const std::string&, Options* o, Sugar*) { o->check = true; }},
    {"--check-batch", true,
     [](const std::string& v, Options* o, Sugar*) { o->check_batch_path = v; }},
    {"--resolve-only", false,
     [](const std::string&, Options* o, Sugar*) { o->resolve_only = true; }},
    {"--batch", true, [](const std::string& v, Options* o, Sugar*) { o->batch_path = v; }},
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

}  // namespace

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
      options.check_batch_path.empty() && options.batch_path.empty()) {
    throw UsageError("no scene file given");
  }
  if (options.resolve_only && options.check_batch_path.empty())
    throw UsageError("--resolve-only goes with --check-batch");
  if (sugar.duration) options.overrides.push_back("duration=" + *sugar.duration);
  if (sugar.integrator) options.overrides.push_back("integrator.type=" + *sugar.integrator);
  if (sugar.dt) options.overrides.push_back("integrator.dt=" + *sugar.dt);
  if (sugar.tolerance) options.overrides.push_back("integrator.tolerance=" + *sugar.tolerance);
  return options;
}

}  // namespace app
}  // namespace threshing_sim
