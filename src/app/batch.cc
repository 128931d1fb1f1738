// --batch: many runs in one simulate process (scripts/sweep's runner sends its runs this way).
//
// Input: one JSON object per line (blank lines are skipped), one run each:
//   {"id": "r1", "args": ["scene.yaml", "--set-file", "tooth.yaml", "--set", "drum.speed=80"],
//    "return": ["summary", "outcomes", "events"]}
// "args" are simulate's own arguments (a scene path, --set-file, --set, --duration, ...,
// --sample-interval, --trace-every, output files); "scene_yaml" gives the scene's text instead
// of a scene path in "args"; "return" lists the outputs put into the result line (default
// summary and outcomes; also events, forces, trace). Output files named in "args" are written
// too. Scene trees are parsed once per scene and list of override files (a bounded cache), so
// that runs differing in their --set values do not re-read the base scene (an inline scene
// from its second line on, or its first when it has --set values); each run applies its --set
// values in place to a copy of the cached tree.
//
// Output: one JSON line per run, in input order, flushed as the run ends:
//   {"id": "r1", "status": "ok", "exit": 0, "message": "", "cpu_s": ..., "wall_s": ...,
//    "summary": "<the --summary file's text>", "outcomes": "<the --outcomes CSV>", ...}
// status is "ok", "failed" (the integrator failed: exit 1, message = the summary's status) or
// "error" (a bad line, option or scene: exit 2, message names the value; anything else exit 1).
// A bad line does not stop the batch. cpu_s is this thread's CPU time for the line (parse,
// load, run and output), wall_s its wall time. The outputs are the very bytes a separate
// simulate process writes into its files.
#include <time.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <sstream>
#include <string>
#include <unordered_set>
#include <vector>

#include "app.h"
#include "json.h"
#include "threshing_sim/scene/scene_loader.h"

namespace threshing_sim {
namespace app {
namespace {

// Scene trees kept at most (the cache is emptied when full: a sweep's runs come in order).
constexpr size_t kMaxCachedTrees = 64;

// Hashes of the inline scenes seen, kept at most (then forgotten).
constexpr size_t kMaxSeenScenes = 4096;

// Parsed scene trees (with their override files applied), the inline scenes seen once, and
// the compiled teeth (the runs of a sweep share few teeth).
struct SceneCache {
  TreeCache trees;
  std::unordered_set<size_t> seen;
  ToothCache teeth;
};

// The scene path shown in messages for a line whose scene is "scene_yaml".
const char kInlineScene[] = "(scene_yaml)";

// The outputs a run can write, with the option that names their file.
struct OutputKind {
  const char* name;
  std::string Options::*path;
};
const OutputKind kOutputs[] = {
    {"summary", &Options::summary_path}, {"outcomes", &Options::outcomes_path},
    {"events", &Options::events_path},   {"forces", &Options::forces_path},
    {"trace", &Options::trace_path},
};
constexpr size_t kNumOutputs = sizeof(kOutputs) / sizeof(kOutputs[0]);

// A line of the batch, read.
struct BatchLine {
  std::string id;
  std::vector<std::string> args;
  bool inline_scene = false;
  std::string scene_yaml;
  bool returned[kNumOutputs] = {true, true, false, false, false};
};

// A run's result line, before it is written.
struct Result {
  std::string id;
  std::string status = "error";
  int exit = 2;
  std::string message;
  std::string outputs[kNumOutputs];
  bool returned[kNumOutputs] = {};
};

// ---------------------------------------------------------------------------------------------
// The lines in.

using Kind = JsonValue::Kind;

std::vector<std::string> stringList(const JsonValue& value, const char* key) {
  if (value.kind != Kind::kArray)
    throw OptionError(std::string(key) + ": expected a list of strings (got " + showJson(value) +
                      ")");
  std::vector<std::string> items;
  for (const JsonValue& item : value.items) {
    if (item.kind != Kind::kString)
      throw OptionError(std::string(key) + ": expected a string (got " + showJson(item) + ")");
    items.push_back(item.text);
  }
  return items;
}

// "return": output names among kOutputs.
void readReturned(const JsonValue& value, BatchLine* line) {
  std::fill(std::begin(line->returned), std::end(line->returned), false);
  for (const std::string& name : stringList(value, "return")) {
    size_t k = 0;
    while (k < kNumOutputs && name != kOutputs[k].name) ++k;
    if (k == kNumOutputs)
      throw OptionError("return: unknown output '" + name +
                        "' (expected summary, outcomes, events, forces or trace)");
    line->returned[k] = true;
  }
}

// A line's id: a string or a number.
void readId(const JsonValue& object, BatchLine* line) {
  for (const auto& [key, value] : object.members) {
    if (key != "id") continue;
    if (value.kind != Kind::kString && value.kind != Kind::kNumber)
      throw OptionError("id: expected a string or number (got " + showJson(value) + ")");
    line->id = value.text;
  }
}

// One input line into *line (its id first, for the error line); throws OptionError naming
// the bad key or value.
void readLine(const std::string& text, BatchLine* line) {
  JsonValue object;
  try {
    object = parseJson(text);
  } catch (const JsonError& e) {
    throw OptionError(std::string("not a JSON line (") + e.what() + ")");
  }
  if (object.kind != Kind::kObject)
    throw OptionError("expected a JSON object (got " + showJson(object) + ")");
  readId(object, line);
  for (const auto& [key, value] : object.members) {
    if (key == "args") {
      line->args = stringList(value, "args");
    } else if (key == "scene_yaml") {
      if (value.kind != Kind::kString)
        throw OptionError("scene_yaml: expected the scene's text (got " + showJson(value) + ")");
      line->inline_scene = true;
      line->scene_yaml = value.text;
    } else if (key == "return") {
      readReturned(value, line);
    } else if (key != "id") {
      throw OptionError("unknown key '" + key + "' (expected id, args, scene_yaml, return)");
    }
  }
}

// ---------------------------------------------------------------------------------------------
// One run.

// The line's options: simulate's command line, with the scene placeholder for "scene_yaml".
Options lineOptions(const BatchLine& line) {
  std::vector<std::string> args = {"simulate"};
  if (line.inline_scene) args.push_back(kInlineScene);
  args.insert(args.end(), line.args.begin(), line.args.end());
  std::vector<char*> argv;
  for (std::string& arg : args) argv.push_back(arg.data());
  Options options = parseOptions(static_cast<int>(argv.size()), argv.data());
  if (options.modes || options.check || options.help || options.print_schema ||
      !options.check_batch_path.empty() || !options.batch_path.empty()) {
    throw UsageError(
        "--modes, --check, --check-batch, --batch, --help and --print-schema are not runs "
        "(not allowed in a --batch line)");
  }
  options.quiet = true;  // stdout holds the result lines
  return options;
}

// The scene's text parsed as loadSceneYaml parses a file.
YAML::Node parseSceneText(const std::string& text) {
  try {
    return YAML::Load(text);
  } catch (const YAML::ParserException& e) {
    throw SceneError(std::string(kInlineScene) + ":" + std::to_string(e.mark.line + 1) + ":" +
                     std::to_string(e.mark.column + 1) + ": YAML syntax error: " + e.msg);
  }
}

// The line's scene tree with its override files applied (parsed once per scene and files).
// A scene text is kept from its second line on (a copy for the cache costs a tenth of a short
// run, wasted on a resolved scene that no other line carries), or from its first when the line
// has --set values: then it is a base scene, which the runner sends for many runs.
YAML::Node baseTree(const BatchLine& line, const Options& options, SceneCache* cache) {
  if (cache->trees.size() >= kMaxCachedTrees) cache->trees.clear();
  if (cache->seen.size() >= kMaxSeenScenes) cache->seen.clear();
  if (!line.inline_scene) return sceneWithFiles(options, &cache->trees);
  std::string key = std::string(1, '\1') + line.scene_yaml;
  for (const std::string& path : options.set_files) key += "\t" + path;
  const auto found = cache->trees.find(key);
  if (found != cache->trees.end()) return YAML::Clone(found->second);
  YAML::Node root = parseSceneText(line.scene_yaml);
  if (root.IsMap()) {
    for (const std::string& path : options.set_files) {
      for (const std::string& assignment : overridesFromFile(path))
        applyOverride(&root, assignment);
    }
  }
  // A line with --set values names a base scene that other lines share (the runner's lines).
  if (!options.overrides.empty() || !cache->seen.insert(std::hash<std::string>()(key)).second)
    cache->trees[key] = YAML::Clone(root);
  return root;
}

// The compiled model of the line (as loadScene builds it) and its damage thresholds.
Model lineModel(const BatchLine& line, const Options& options, SceneCache* cache,
                DamageThresholds* damage) {
  YAML::Node root = baseTree(line, options, cache);
  if (!root.IsMap())
    throw SceneError(options.scene_path + ": expected a mapping of sections at the top level");
  for (const std::string& assignment : options.overrides) applyOverride(&root, assignment);
  try {
    Model model = modelFromYaml(root, &cache->teeth);
    *damage = damageFromYaml(root);
    return model;
  } catch (const SceneError& e) {
    throw SceneError(options.scene_path + ": " + e.what());
  }
}

// Writes an output that the line's arguments sent to a file as well.
void writeFile(const std::string& path, const char* name, const std::string& text) {
  std::ofstream file(path);
  if (!file) throw OptionError(std::string("cannot open --") + name + " file '" + path + "'");
  file << text;
  file.close();
  if (file.fail())
    throw OptionError(std::string("error writing --") + name + " file '" + path + "'");
}

// Runs the line; fills the result's status and outputs. Throws on a bad line or scene.
void runLine(const BatchLine& line, SceneCache* cache, Result* result) {
  const Options options = lineOptions(line);
  DamageThresholds damage;
  const Model model = lineModel(line, options, cache, &damage);
  std::ostringstream streams[kNumOutputs];
  bool used[kNumOutputs];
  for (size_t k = 0; k < kNumOutputs; ++k)
    used[k] = line.returned[k] || !(options.*kOutputs[k].path).empty();
  auto stream = [&](size_t k) -> std::ostream* { return used[k] ? &streams[k] : nullptr; };
  std::string status;
  const int exit =
      runModel(model, damage, options,
               RunStreams{stream(0), stream(4), stream(2), stream(1), stream(3)}, &status);
  for (size_t k = 0; k < kNumOutputs; ++k) {
    if (!used[k]) continue;
    result->outputs[k] = streams[k].str();
    result->returned[k] = line.returned[k];
    const std::string& path = options.*kOutputs[k].path;
    if (!path.empty()) writeFile(path, kOutputs[k].name, result->outputs[k]);
  }
  result->exit = exit;
  result->status = exit == 0 ? "ok" : "failed";
  result->message = exit == 0 ? "" : status;
}

// ---------------------------------------------------------------------------------------------
// The batch.

double threadCpuSeconds() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

std::string resultLine(const Result& result, double cpu_s, double wall_s) {
  std::string out = "{\"id\": ";
  appendJsonString(result.id, &out);
  out += ", \"status\": ";
  appendJsonString(result.status, &out);
  out += ", \"exit\": " + std::to_string(result.exit) + ", \"message\": ";
  appendJsonString(result.message, &out);
  char times[96];
  std::snprintf(times, sizeof(times), ", \"cpu_s\": %.9g, \"wall_s\": %.9g", cpu_s, wall_s);
  out += times;
  for (size_t k = 0; k < kNumOutputs; ++k) {
    if (!result.returned[k]) continue;
    out += ", \"" + std::string(kOutputs[k].name) + "\": ";
    appendJsonString(result.outputs[k], &out);
  }
  return out + "}";
}

// The result of one input line: a run, or an error naming what was wrong with it.
Result processLine(const std::string& text, long number, SceneCache* cache) {
  Result result;
  BatchLine line;
  line.id = std::to_string(number);
  try {
    readLine(text, &line);
    runLine(line, cache, &result);
  } catch (const OptionError& e) {
    result.message = e.what();
  } catch (const SceneError& e) {
    result.message = e.what();
  } catch (const std::exception& e) {
    result.exit = 1;
    result.message = e.what();
  }
  result.id = line.id;
  return result;
}

}  // namespace

int runBatch(const std::string& path) {
  std::ifstream file;
  if (path != "-") {
    file.open(path);
    if (!file) throw OptionError("cannot open --batch file '" + path + "'");
  }
  std::istream& in = path == "-" ? std::cin : file;
  int status = 0;
  SceneCache cache;
  long number = 0;
  for (std::string text; std::getline(in, text);) {
    ++number;
    if (text.find_first_not_of(" \t\r") == std::string::npos) continue;
    const double cpu_started = threadCpuSeconds();
    const auto started = std::chrono::steady_clock::now();
    const Result result = processLine(text, number, &cache);
    const double wall_s =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
    std::cout << resultLine(result, threadCpuSeconds() - cpu_started, wall_s) << std::endl;
    status = std::max(status, result.exit);
  }
  return status;
}

}  // namespace app
}  // namespace threshing_sim
