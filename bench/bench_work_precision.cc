// bench_work_precision: one point of the work-precision benchmark (scripts/bench.py drives it).
//
// Loads a scene with overrides (as simulate does), then
//   1. times R repetitions of the bare run (resetData + advanceTo(duration), nothing sampled),
//      all in this one process, optionally pinned to one CPU, and keeps the median wall time;
//   2. takes the run's metrics from the last timed repetition (final kernel states and the
//      core's RunStats, which the integrator keeps anyway) and checks that every repetition
//      ended in the bit-identical state;
//   3. runs once more with the tooth tip deflection sampled at fixed times (this run lands on
//      the sample times, which changes the event-driven step sequence, so it is not timed).
// Writes everything as one JSON object. Exit status: 0 ok, 1 integrator failure, 2 bad input.
#include <sched.h>

#include <algorithm>
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
#include "threshing_sim/scene/number_text.h"
#include "threshing_sim/scene/report.h"
#include "threshing_sim/scene/scene_loader.h"

namespace threshing_sim {
namespace {

const char kUsage[] =
    "usage: bench_work_precision SCENE.yaml [--set-file FILE.yaml]... [--set key.path=value]... "
    "[--reps R] [--budget S] [--time-limit S] [--samples N] [--cpu K] [--out FILE.json]";

struct Options {
  std::string scene_path;
  std::vector<std::string> overrides;  // override files expanded in place, in command order
  int reps = 5;                        // timed repetitions [-]
  double budget_s = 1e30;              // stop repeating once this much wall time is spent [s]
  double time_limit_s = 0;             // > 0: a timed run stops after this wall time, advancing
                                       // in 50 chunks (cost only: chunks change the steps) [s]
  int samples = 200;                   // tip deflection samples over the run; 0 = no such run [-]
  int cpu = -1;                        // CPU to pin to; < 0 = leave the affinity alone
  std::string out_path;                // JSON output; empty = stdout
};

// A bad command line (exit 2).
class UsageError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

int parseInt(const std::string& option, const std::string& text, int lo) {
  const std::optional<int> value = intFromText(text);
  if (!value || *value < lo) {
    throw UsageError(option + " expects an integer >= " + std::to_string(lo) + " (got '" + text +
                     "')");
  }
  return *value;
}

double parseSeconds(const std::string& option, const std::string& text) {
  const std::optional<double> value = doubleFromText(text);
  if (!value || !(*value > 0)) {
    throw UsageError(option + " expects a number > 0 in seconds (got '" + text + "')");
  }
  return *value;
}

Options parseOptions(int argc, char** argv) {
  Options options;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    const auto value = [&]() -> std::string {
      if (i + 1 >= argc) throw UsageError("option " + arg + " needs a value");
      return argv[++i];
    };
    if (arg == "--set") {
      options.overrides.push_back(value());
    } else if (arg == "--set-file") {
      const std::vector<std::string> from_file = overridesFromFile(value());
      options.overrides.insert(options.overrides.end(), from_file.begin(), from_file.end());
    } else if (arg == "--reps") {
      options.reps = parseInt(arg, value(), 1);
    } else if (arg == "--samples") {
      options.samples = parseInt(arg, value(), 0);
    } else if (arg == "--cpu") {
      options.cpu = parseInt(arg, value(), 0);
    } else if (arg == "--budget") {
      options.budget_s = parseSeconds(arg, value());
    } else if (arg == "--time-limit") {
      options.time_limit_s = parseSeconds(arg, value());
    } else if (arg == "--out") {
      options.out_path = value();
    } else if (arg.rfind("-", 0) == 0) {
      throw UsageError("unknown option '" + arg + "'");
    } else if (options.scene_path.empty()) {
      options.scene_path = arg;
    } else {
      throw UsageError("more than one scene file");
    }
  }
  if (options.scene_path.empty()) throw UsageError("no scene file given");
  return options;
}

// ---------------------------------------------------------------------------------------------
// JSON output helpers (17 significant digits, so that values compare bit for bit).

std::string num(double x) {
  if (!std::isfinite(x)) return "null";
  char text[40];
  std::snprintf(text, sizeof(text), "%.17g", x);
  return text;
}

std::string numList(const std::vector<double>& xs) {
  std::string text = "[";
  for (size_t i = 0; i < xs.size(); ++i) text += (i ? ", " : "") + num(xs[i]);
  return text + "]";
}

std::string quoted(const std::string& s) {
  std::string text = "\"";
  for (const char c : s) {
    if (c == '"' || c == '\\') text += '\\';
    text += c;
  }
  return text + "\"";
}

// ---------------------------------------------------------------------------------------------
// The runs.

// Outcome of one timed repetition.
struct TimedRun {
  double wall_s = 0;  // wall time inside advanceTo [s]
  StepStatus status = StepStatus::kOk;
  bool completed = true;  // false when the time limit stopped it before the duration
};

// Without a time limit: one advanceTo to the duration. With one: 50 chunks, stopping after the
// chunk that crosses the limit (data->t_s then tells how far the run got).
TimedRun timedRun(const Model& model, double time_limit_s, Data* data) {
  resetData(model, data);
  TimedRun run;
  const auto started = std::chrono::steady_clock::now();
  const auto elapsed = [&started]() {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
  };
  if (time_limit_s <= 0) {
    run.status = advanceTo(model, data, model.duration_s);
  } else {
    constexpr int kChunks = 50;
    int c = 1;
    for (; c <= kChunks && elapsed() < time_limit_s; ++c) {
      const double t_s = c == kChunks ? model.duration_s : model.duration_s * c / kChunks;
      run.status = std::max(run.status, advanceTo(model, data, t_s));
      if (run.status == StepStatus::kFailed) break;
    }
    run.completed = c > kChunks;
  }
  run.wall_s = elapsed();
  return run;
}

// Tip deflection of every tooth at `samples` equally spaced times (the first after one
// interval, the last at the duration): deflection_m[tooth][sample] [m]. Returns the run's status.
StepStatus sampledRun(const Model& model, int samples, std::vector<double>* times_s,
                      std::vector<std::vector<double>>* deflection_m) {
  Data data;
  resetData(model, &data);
  deflection_m->assign(model.teeth.size(), {});
  times_s->clear();
  StepStatus worst = StepStatus::kOk;
  for (int i = 1; i <= samples; ++i) {
    const double t_s = i == samples ? model.duration_s : model.duration_s * i / samples;
    const StepStatus status = advanceTo(model, &data, t_s);
    worst = std::max(worst, status);
    if (status == StepStatus::kFailed) break;
    times_s->push_back(t_s);
    for (size_t k = 0; k < model.teeth.size(); ++k) {
      (*deflection_m)[k].push_back(
          toothDeflection(model, data, static_cast<int>(k), model.teeth[k].length_m));
    }
  }
  return worst;
}

const char* statusName(StepStatus status) {
  switch (status) {
    case StepStatus::kOk:
      return "ok";
    case StepStatus::kRecovered:
      return "recovered";
    case StepStatus::kFailed:
      return "failed";
  }
  return "?";
}

int run(const Options& options) {
  // Pin first, so that every repetition runs on the same core.
  if (options.cpu >= 0) {
    cpu_set_t set;
    CPU_ZERO(&set);
    CPU_SET(options.cpu, &set);
    if (sched_setaffinity(0, sizeof(set), &set) != 0) {
      throw UsageError("cannot pin to CPU " + std::to_string(options.cpu));
    }
  }
  const Model model = loadScene(options.scene_path, options.overrides);

  // Timed repetitions; every one must end in the state of the first (determinism).
  std::vector<double> walls_s;
  Data data;
  VecX z_first, u_first;
  bool identical = true;
  bool completed = true;
  StepStatus worst = StepStatus::kOk;
  double spent_s = 0;
  for (int r = 0; r < options.reps; ++r) {
    const TimedRun timed = timedRun(model, options.time_limit_s, &data);
    walls_s.push_back(timed.wall_s);
    spent_s += timed.wall_s;
    worst = std::max(worst, timed.status);
    if (r == 0) {
      z_first = data.z;
      u_first = data.u;
    } else {
      identical = identical && data.z.size() == z_first.size() &&
                  std::equal(data.z.data(), data.z.data() + data.z.size(), z_first.data()) &&
                  std::equal(data.u.data(), data.u.data() + data.u.size(), u_first.data());
    }
    completed = timed.completed;
    if (timed.status == StepStatus::kFailed || !completed || spent_s >= options.budget_s) break;
  }
  std::vector<double> sorted = walls_s;
  std::sort(sorted.begin(), sorted.end());
  const size_t n = sorted.size();
  const double median_s = n % 2 ? sorted[n / 2] : 0.5 * (sorted[n / 2 - 1] + sorted[n / 2]);

  // The deflection history, from a separate (untimed) run.
  std::vector<double> sample_times_s;
  std::vector<std::vector<double>> deflection_m;
  const StepStatus sampled_status =
      options.samples > 0 ? sampledRun(model, options.samples, &sample_times_s, &deflection_m)
                          : StepStatus::kOk;

  // JSON: settings, timing, the core's statistics and the final kernel states.
  std::string json = "{\n";
  const auto field = [&json](const std::string& key, const std::string& value) {
    json += "  " + quoted(key) + ": " + value + ",\n";
  };
  field("scene", quoted(options.scene_path));
  std::string overrides = "[";
  for (size_t i = 0; i < options.overrides.size(); ++i) {
    overrides += (i ? ", " : "") + quoted(options.overrides[i]);
  }
  field("overrides", overrides + "]");
  const bool event_driven = model.integrator.type == IntegratorType::kEventDriven;
  field("integrator", quoted(event_driven ? "event_driven" : "time_stepping"));
  field("tolerance", num(model.integrator.tolerance));
  field("dt_s", num(model.integrator.dt_s));
  field("status", quoted(statusName(worst)));
  field("sampled_run_status", quoted(statusName(sampled_status)));
  field("deterministic", identical ? "true" : "false");
  field("sim_time_s", num(data.t_s));
  field("wall_times_s", numList(walls_s));
  field("median_wall_s", num(median_s));
  field("duration_s", num(model.duration_s));
  field("completed", completed ? "true" : "false");
  field("wall_per_sim_s", num(median_s / data.t_s));
  field("steps", std::to_string(data.steps));
  field("rejected_steps", std::to_string(data.stats.rejected_steps));
  field("numerical_recoveries", std::to_string(data.stats.numerical_recoveries));
  field("islands", model.integrator.islands ? "true" : "false");
  field("scheduler", schedulerJson(data.stats.scheduler));
  field("impacts", std::to_string(data.stats.impacts));
  field("contact_episodes", std::to_string(data.stats.contact_episodes));
  field("peak_normal_force_N", num(data.stats.peak_normal_force_N));
  field("peak_tangential_force_N", num(data.stats.peak_tangential_force_N));
  field("total_normal_impulse_Ns", num(data.stats.total_normal_impulse_Ns));
  field("n_teeth", std::to_string(model.teeth.size()));
  std::vector<double> modes;
  for (const ToothModel& tooth : model.teeth) modes.push_back(tooth.n_modes);
  field("tooth_modes", numList(modes));
  field("sample_times_s", numList(sample_times_s));
  std::string tips = "[";
  for (size_t k = 0; k < deflection_m.size(); ++k)
    tips += (k ? ", " : "") + numList(deflection_m[k]);
  field("tip_deflection_m", tips + "]");
  // Per kernel: initial and final pose, final velocity, semi-axis a (scales the angle error).
  std::string kernels;
  for (size_t i = 0; i < model.kernels.size(); ++i) {
    const KernelModel& k = model.kernels[i];
    const int o = k.dof_offset;
    kernels +=
        std::string(i ? ",\n    " : "\n    ") + "{\"initial_position_m\": " +
        numList({k.initial_position_m.x(), k.initial_position_m.y()}) +
        ", \"initial_angle_rad\": " + num(k.initial_angle_rad) +
        ", \"semi_axis_a_m\": " + num(k.semi_axis_a_m) +
        ", \"position_m\": " + numList({data.z[o], data.z[o + 1]}) +
        ", \"angle_rad\": " + num(data.z[o + 2]) +
        ", \"velocity_mps\": " + numList({data.u[o], data.u[o + 1]}) +
        ", \"angular_velocity_radps\": " + num(data.u[o + 2]) + ", \"impacts\": " +
        std::to_string(i < data.stats.kernel_impacts.size() ? data.stats.kernel_impacts[i] : 0) +
        ", \"attached\": " + (data.kernel_attached[i] ? "true" : "false") + "}";
  }
  json += "  \"kernels\": [" + kernels + "\n  ]\n}\n";

  if (options.out_path.empty()) {
    std::cout << json;
  } else {
    std::ofstream out(options.out_path);
    out << json;
    out.close();
    if (out.fail()) throw std::runtime_error("error writing '" + options.out_path + "'");
  }
  return worst == StepStatus::kFailed ? 1 : 0;
}

}  // namespace
}  // namespace threshing_sim

int main(int argc, char** argv) {
  using namespace threshing_sim;
  try {
    return run(parseOptions(argc, argv));
  } catch (const UsageError& e) {
    std::cerr << "bench_work_precision: error: " << e.what() << "\n" << kUsage << "\n";
    return 2;
  } catch (const SceneError& e) {
    std::cerr << "bench_work_precision: error: " << e.what() << "\n";
    return 2;
  } catch (const std::exception& e) {
    std::cerr << "bench_work_precision: error: " << e.what() << "\n";
    return 1;
  }
}
