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
//
// Validated first, then run (scripts/sweep: a sweep is refused before any run starts, and each
// model is compiled once). Three control lines:
//   {"hold": true}          the run lines after it are read, loaded and compiled, and held
//                           (their models take at most 256 MB of heap, or {"hold": MB}; a
//                           model beyond it is compiled again to run);
//   {"barrier": 60}         answers {"barrier": true, "lines": N, "invalid": [{"id", "message"}]}
//                           for the held lines, then waits at most 60 s for the next line:
//   {"go": true}            runs the held lines (their compiled models), then reads on;
//   {"go": false}           (or the end of the input, or no go in time) exits 2, nothing run;
//   {"run": ["id", ...]}    (instead of the go) runs those held lines, in that order; more run
//                           lines and other lines may follow (the runner shares the runs out as
//                           workers free up); held lines not run by the end are dropped.
// A held run's cpu_s and wall_s include its validation (parse, load, compile). "scene_name" in
// a run line names its scene_yaml in messages (default "(scene_yaml)").
#include <malloc.h>
#include <time.h>

#include <algorithm>
#include <chrono>
#include <condition_variable>
#include <cstdio>
#include <cstdlib>
#include <deque>
#include <fstream>
#include <iostream>
#include <mutex>
#include <sstream>
#include <string>
#include <thread>
#include <unordered_map>
#include <unordered_set>
#include <vector>

#include "app.h"
#include "batch_line.h"
#include "json.h"
#include "threshing_sim/scene/scene_loader.h"

namespace threshing_sim {
namespace app {
namespace {

using Kind = JsonValue::Kind;

// A run's result line, before it is written.
struct Result {
  std::string id;
  std::string status = "error";
  int exit = 2;
  std::string message;
  std::string outputs[kNumOutputs];
  bool returned[kNumOutputs] = {};
};

// Writes an output that the line's arguments sent to a file as well.
void writeFile(const std::string& path, const char* name, const std::string& text) {
  std::ofstream file(path);
  if (!file) throw OptionError(std::string("cannot open --") + name + " file '" + path + "'");
  file << text;
  file.close();
  if (file.fail())
    throw OptionError(std::string("error writing --") + name + " file '" + path + "'");
}

// A run line read, loaded and compiled: what its run needs.
struct PreparedRun {
  BatchLine line;
  Options options;
  Model model;
  DamageThresholds damage;
};

// Reads the line's keys and options, loads its scene and compiles its model. Throws on a bad
// line or scene.
void prepareLine(const JsonValue& object, SceneCache* cache, PreparedRun* run) {
  readLine(object, &run->line);
  run->options = lineOptions(run->line);
  run->model = lineModel(run->line, run->options, cache, &run->damage);
}

// Runs the prepared line; fills the result's status and outputs. Throws on a bad output file.
void runPrepared(const PreparedRun& run, Result* result) {
  const Options& options = run.options;
  std::ostringstream streams[kNumOutputs];
  bool used[kNumOutputs];
  for (size_t k = 0; k < kNumOutputs; ++k)
    used[k] = run.line.returned[k] || !(options.*kOutputs[k].path).empty();
  auto stream = [&](size_t k) -> std::ostream* { return used[k] ? &streams[k] : nullptr; };
  std::string status;
  const int exit =
      runModel(run.model, run.damage, options,
               RunStreams{stream(0), stream(4), stream(2), stream(1), stream(3)}, &status);
  for (size_t k = 0; k < kNumOutputs; ++k) {
    if (!used[k]) continue;
    result->outputs[k] = streams[k].str();
    result->returned[k] = run.line.returned[k];
    const std::string& path = options.*kOutputs[k].path;
    if (!path.empty()) writeFile(path, kOutputs[k].name, result->outputs[k]);
  }
  result->exit = exit;
  result->status = exit == 0 ? "ok" : "failed";
  result->message = exit == 0 ? "" : status;
}

// Calls f; an exception becomes the result's error (exit 2 for a bad line, option or scene,
// else 1). Returns whether f returned.
template <typename F>
bool guarded(Result* result, F&& f) {
  try {
    f();
    return true;
  } catch (const OptionError& e) {
    result->message = e.what();
  } catch (const SceneError& e) {
    result->message = e.what();
  } catch (const std::exception& e) {
    result->exit = 1;
    result->message = e.what();
  }
  return false;
}

// ---------------------------------------------------------------------------------------------
// The batch.

double threadCpuSeconds() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

// This thread's CPU time and the wall time since it was made [s].
class Stopwatch {
 public:
  double cpuSeconds() const { return threadCpuSeconds() - cpu_started_s_; }
  double wallSeconds() const {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - wall_started_).count();
  }

 private:
  double cpu_started_s_ = threadCpuSeconds();
  std::chrono::steady_clock::time_point wall_started_ = std::chrono::steady_clock::now();
};

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

// What a line is: a run, or one of the control lines of validation first.
enum class LineKind { kRun, kHold, kBarrier, kGo, kRunHeld };

// Heap that the compiled models of held runs may take, by default and at most [MB]; a line
// validated beyond it drops its model and compiles it again when it runs (its cpu_s holds both
// compilations). The single strike's model takes about 0.45 MB.
constexpr double kDefaultHeldMegabytes = 256.0;
constexpr double kMaxHeldMegabytes = 65536.0;

// Longest wait for the go after a barrier that a line may ask for [s].
constexpr double kMaxBarrierTimeoutS = 86400.0;

// The kind of a line; *number gets a barrier's timeout [s] or a hold's heap [MB], *flag a go's
// value, *ids a run line's ids. Throws OptionError for a malformed control line.
LineKind lineKind(const JsonValue& object, double* number, bool* flag,
                  std::vector<std::string>* ids) {
  static const char* const kControls[] = {"hold", "barrier", "go", "run"};
  for (const auto& [key, value] : object.members) {
    const std::string& name_of_key = key;  // (a lambda may not capture a structured binding)
    const auto control = std::find_if(std::begin(kControls), std::end(kControls),
                                      [&](const char* name) { return name_of_key == name; });
    if (control == std::end(kControls)) continue;
    if (object.members.size() != 1)
      throw OptionError("a control line holds only its key ('" + key + "'; got " +
                        showJson(object) + ")");
    if (key == "barrier") {
      *number = value.kind == Kind::kNumber ? std::strtod(value.text.c_str(), nullptr) : 0.0;
      if (value.kind != Kind::kNumber || !(*number > 0.0 && *number <= kMaxBarrierTimeoutS))
        throw OptionError("barrier: expected the go's timeout in s, in (0, 86400] (got " +
                          showJson(value) + ")");
      return LineKind::kBarrier;
    }
    if (key == "run") {
      *ids = stringList(value, "run");
      return LineKind::kRunHeld;
    }
    if (key == "hold" && value.kind == Kind::kNumber) {
      *number = std::strtod(value.text.c_str(), nullptr);
      if (!(*number >= 0.0 && *number <= kMaxHeldMegabytes))
        throw OptionError(
            "hold: expected true or the held models' heap in MB, in [0, 65536] "
            "(got " +
            showJson(value) + ")");
      *flag = true;
      return LineKind::kHold;
    }
    if (value.kind != Kind::kBool || (key == "hold" && !value.flag))
      throw OptionError(key + ": expected " +
                        (key == "hold" ? "true or a number of MB" : "true or false") + " (got " +
                        showJson(value) + ")");
    if (key == "hold") *number = kDefaultHeldMegabytes;
    *flag = value.flag;
    return key == "hold" ? LineKind::kHold : LineKind::kGo;
  }
  return LineKind::kRun;
}

// Ends the process (exit 2, the message on stderr) unless it is destroyed within timeout_s.
class Watchdog {
 public:
  Watchdog(double timeout_s, std::string message)
      : thread_([this, timeout_s, message] {
          std::unique_lock<std::mutex> lock(mutex_);
          if (!cv_.wait_for(lock, std::chrono::duration<double>(timeout_s),
                            [this] { return done_; })) {
            std::cerr << message << std::flush;
            std::_Exit(2);
          }
        }) {}
  ~Watchdog() {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      done_ = true;
    }
    cv_.notify_all();
    thread_.join();
  }
  Watchdog(const Watchdog&) = delete;
  Watchdog& operator=(const Watchdog&) = delete;

 private:
  std::mutex mutex_;
  std::condition_variable cv_;
  bool done_ = false;
  std::thread thread_;  // last: it uses the members above
};

// Bytes of heap in use (malloc's arenas and mmapped blocks).
size_t heapBytes() {
  const struct mallinfo2 info = mallinfo2();
  return info.uordblks + info.hblkhd;
}

// A run line validated and held until the go: its compiled model, or its error.
struct HeldRun {
  PreparedRun run;
  Result result;  // its id; its error when it is not valid
  bool valid = false;
  bool compiled = false;  // the model is kept (else compiled again to run)
  bool done = false;      // run (its result written)
  double cpu_s = 0.0;     // this thread's CPU time for its validation [s]
  double wall_s = 0.0;    // the validation's wall time [s]
};

// The state of a batch between its lines.
class Batch {
 public:
  explicit Batch(std::istream* in) : in_(in) {}

  // Handles the next input line (its number names it when it has no id; blank lines are
  // skipped). Returns false when the batch must end (no go after a barrier).
  bool line(const std::string& text) {
    const long number = ++number_;
    if (text.find_first_not_of(" \t\r") == std::string::npos) return true;
    const Stopwatch watch;
    Result result;
    result.id = std::to_string(number);
    JsonValue object;
    LineKind kind = LineKind::kRun;
    double number_value = 0.0;
    bool flag = false;
    std::vector<std::string> ids;
    const bool read = guarded(&result, [&] {
      object = parseLine(text);
      kind = lineKind(object, &number_value, &flag, &ids);
    });
    if (read && kind == LineKind::kHold) {
      holding_ = true;
      max_held_bytes_ = static_cast<size_t>(number_value * 1048576.0);
      return true;
    }
    if (read && kind == LineKind::kBarrier) return barrier(number_value);
    if (read && (kind == LineKind::kGo || kind == LineKind::kRunHeld)) {
      if (answered_) return decide(kind, flag, ids);
      result.message = "a go or run line without a barrier before it";
    }
    if (holding_) {
      hold(read && kind == LineKind::kRun ? &object : nullptr, std::move(result), watch);
      held_index_.emplace(held_.back().result.id, held_.size() - 1);
      return true;
    }
    PreparedRun run;
    run.line.id = result.id;
    if (read && kind == LineKind::kRun) {
      guarded(&result, [&] {
        prepareLine(object, &cache_, &run);
        runPrepared(run, &result);
      });
    }
    result.id = run.line.id;
    emit(result, watch.cpuSeconds(), watch.wallSeconds());
    return true;
  }

  int status() const { return status_; }

 private:
  // Validates the run line (its object, or null when it could not be read: then the result
  // holds its error) and holds it.
  void hold(const JsonValue* object, Result result, const Stopwatch& watch) {
    held_.emplace_back();
    HeldRun& held = held_.back();
    held.run.line.id = result.id;
    held.result = std::move(result);
    const size_t heap_before = heapBytes();
    if (object != nullptr)
      held.valid = guarded(&held.result, [&] { prepareLine(*object, &cache_, &held.run); });
    const size_t heap_after = heapBytes();
    const size_t bytes = heap_after > heap_before ? heap_after - heap_before : 0;
    held.compiled = held.valid && held_bytes_ + bytes <= max_held_bytes_;
    if (held.compiled) held_bytes_ += bytes;
    if (held.valid && !held.compiled) held.run.model = Model();
    held.result.id = held.run.line.id;
    held.cpu_s = watch.cpuSeconds();
    held.wall_s = watch.wallSeconds();
  }

  // Answers the barrier, waits for the go (at most timeout_s) and runs the held lines.
  bool barrier(double timeout_s) {
    std::string answer =
        "{\"barrier\": true, \"lines\": " + std::to_string(held_.size()) + ", \"invalid\": [";
    bool first = true;
    for (const HeldRun& held : held_) {
      if (held.valid) continue;
      answer += first ? "{\"id\": " : ", {\"id\": ";
      first = false;
      appendJsonString(held.result.id, &answer);
      answer += ", \"message\": ";
      appendJsonString(held.result.message, &answer);
      answer += "}";
    }
    std::cout << answer << "]}" << std::endl;
    std::string text;
    bool got = false;
    {
      const Watchdog watchdog(timeout_s, "simulate: error: --batch: no go within " +
                                             showNumber(timeout_s) + " s of the barrier; " +
                                             std::to_string(held_.size()) + " held runs not run\n");
      got = static_cast<bool>(std::getline(*in_, text));
    }
    number_ += got;
    Result ignored;
    double unused = 0.0;
    bool go = false;
    std::vector<std::string> ids;
    LineKind kind = LineKind::kRun;
    const bool read = got && guarded(&ignored, [&] {
                        kind = lineKind(parseLine(text), &unused, &go, &ids);
                        if (kind != LineKind::kGo && kind != LineKind::kRunHeld)
                          throw OptionError("not a go line");
                      });
    if (!read) {
      std::cerr << "simulate: error: --batch: "
                << (!got ? std::string("the input ended at the barrier")
                         : "expected {\"go\": true}, {\"go\": false} or {\"run\": [ids]} after "
                           "the barrier (got " +
                               text.substr(0, 200) + ")")
                << "; " << held_.size() << " held runs not run\n";
      status_ = 2;
      return false;
    }
    answered_ = true;
    holding_ = false;
    return decide(kind, go, ids);
  }

  // After the barrier: {"go": true} runs every held line not run yet (in order), {"go": false}
  // ends the batch (exit 2) without them, {"run": [ids]} runs those held lines in that order.
  bool decide(LineKind kind, bool go, const std::vector<std::string>& ids) {
    if (kind == LineKind::kGo && !go) {
      std::cerr << "simulate: error: --batch: no go after the barrier; " << held_.size()
                << " held runs not run\n";
      status_ = 2;
      return false;
    }
    if (kind == LineKind::kGo) {
      for (HeldRun& held : held_) {
        if (!held.done) runHeld(&held);
      }
      held_.clear();
      held_index_.clear();
      held_bytes_ = 0;
      answered_ = false;
      return true;
    }
    for (const std::string& id : ids) {
      auto [begin, end] = held_index_.equal_range(id);
      while (begin != end && held_[begin->second].done) ++begin;
      if (begin != end) {
        runHeld(&held_[begin->second]);
        continue;
      }
      Result result;
      result.id = id;
      result.message = "run: no held line '" + id + "' left to run";
      emit(result, 0.0, 0.0);
    }
    return true;
  }

  // Runs a held line (compiling its model again when it was not kept) and writes its result;
  // its cpu_s and wall_s include its validation.
  void runHeld(HeldRun* held) {
    const Stopwatch watch;
    if (held->valid) {
      guarded(&held->result, [&] {
        if (!held->compiled)
          held->run.model =
              lineModel(held->run.line, held->run.options, &cache_, &held->run.damage);
        runPrepared(held->run, &held->result);
      });
    }
    emit(held->result, held->cpu_s + watch.cpuSeconds(), held->wall_s + watch.wallSeconds());
    held->run.model = Model();  // its tables freed as it ends
    held->done = true;
  }

  void emit(const Result& result, double cpu_s, double wall_s) {
    std::cout << resultLine(result, cpu_s, wall_s) << std::endl;
    status_ = std::max(status_, result.exit);
  }

  static std::string showNumber(double value) {
    std::ostringstream text;
    text << value;
    return text.str();
  }

  std::istream* in_;
  long number_ = 0;  // lines read
  SceneCache cache_;
  bool holding_ = false;   // run lines are held (after a hold, until the barrier)
  bool answered_ = false;  // the barrier was answered: go and run lines decide on held_
  std::deque<HeldRun> held_;
  std::unordered_multimap<std::string, size_t> held_index_;  // held_ by id
  size_t held_bytes_ = 0;      // heap held by the held runs' models [bytes]
  size_t max_held_bytes_ = 0;  // the hold's budget for them [bytes]
  int status_ = 0;
};

}  // namespace

int runBatch(const std::string& path) {
  std::ifstream file;
  if (path != "-") {
    file.open(path);
    if (!file) throw OptionError("cannot open --batch file '" + path + "'");
  }
  std::istream& in = path == "-" ? std::cin : file;
  Batch batch(&in);
  for (std::string text; std::getline(in, text);) {
    if (!batch.line(text)) break;
  }
  return batch.status();
}

}  // namespace app
}  // namespace threshing_sim
