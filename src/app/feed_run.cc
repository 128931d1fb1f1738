// A scene with a continuous feed (core/feed.h) run to its duration: the feed updated every
// kFeedUpdateStep_s of simulated time (at the first step end at or past it: no step is cut for it),
// each retired kernel's outcome row, the time series per --feed-interval and the totals.
//
// Drum load: the drive's work over an interval (RunStats::drive_work_J, integrated by the
// integrator with the teeth's contact forces in it) over the interval's length is the mean
// power the drum delivers; over the drum angle turned, the mean load torque (core/feed.h
// FeedSeries: the node's feed_throughput computes the same).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <string>
#include <vector>

#include "app.h"
#include "threshing_sim/core/failure.h"
#include "threshing_sim/core/feed.h"
#include "threshing_sim/core/simulator.h"

namespace threshing_sim {
namespace app {
namespace {

void writeSeriesHeader(std::ostream& out) {
  out << "t_start_s,t_end_s,fed,threshed,damaged,separated,carried_over_detached,"
         "carried_over_unthreshed,out_of_bounds,in_drum,peak_force_mean_N,peak_force_p50_N,"
         "peak_force_p90_N,peak_force_max_N,drive_work_J,power_W,torque_Nm\n";
}

// The row of an interval (FeedSeries::close, the node's feed_throughput computes the same).
void writeSeriesRow(std::ostream& out, const FeedIntervalRow& r) {
  char row[512];
  std::snprintf(row, sizeof(row),
                "%.9g,%.9g,%ld,%ld,%ld,%ld,%ld,%ld,%ld,%ld,%.6g,%.6g,%.6g,%.6g,%.9g,%.6g,%.6g\n",
                r.t_start_s, r.t_end_s, r.fed, r.threshed, r.damaged, r.separated,
                r.carried_detached, r.carried_unthreshed, r.out_of_bounds, r.in_drum,
                r.peak_force_mean_N, r.peak_force_p50_N, r.peak_force_p90_N, r.peak_force_max_N,
                r.drive_work_J, r.power_W, r.torque_Nm);
  out << row;
}

void writeOutcomesHeader(std::ostream& out) {
  out << "id,slot,arrival_s,retired_s,fate,mass_kg,peak_tooth_normal_N,peak_tooth_tangential_N,"
         "peak_contact_N,impacts,detach_s,damage,exit_x_m,exit_y_m\n";
}

void writeOutcomeRow(std::ostream& out, const FeedRecord& r, const DamageThresholds& damage) {
  char row[512];
  std::snprintf(row, sizeof(row), "%ld,%d,%.9g,%.9g,%s,%.6g,%.6g,%.6g,%.6g,%ld,%.9g,%s,%.6g,%.6g\n",
                r.id, r.slot, r.arrival_s, r.retired_s, toString(r.fate), r.mass_kg,
                r.peak_normal_N, r.peak_tangential_N, r.peak_contact_N, r.impacts, r.detach_s,
                toString(classifyDamage(r.peak_contact_N, damage)), r.exit_position_m.x(),
                r.exit_position_m.y());
  out << row;
}

// Drains the kernels retired since the last update into the series and the outcome rows.
void drainRetired(const DamageThresholds& damage, std::ostream* outcomes, FeedState* state,
                  FeedSeries* series) {
  for (const FeedRecord& r : state->retired) {
    series->add(r, damage.plastic_force_N);
    if (outcomes != nullptr) writeOutcomeRow(*outcomes, r, damage);
  }
  state->retired.clear();
}

void openFile(const std::string& path, const char* option, std::ofstream* out) {
  if (path.empty()) return;
  out->open(path);
  if (!*out) throw OptionError(std::string("cannot open ") + option + " file '" + path + "'");
}

void closeFile(const std::string& path, const char* option, std::ofstream* out) {
  if (!out->is_open()) return;
  out->close();
  if (out->fail())
    throw OptionError(std::string("error writing ") + option + " file '" + path + "'");
}

// The summary as JSON (--summary) and as text (stdout).
void reportFeed(const Model& model, const FeedSpec& spec, const Data& d, const FeedState& state,
                const FeedTotals& totals, const std::string& status, double wall_s,
                std::ostream* json, bool quiet) {
  const FeedCounts& c = state.counts;
  const double rate_kgps = spec.rate_per_s * spec.kernel_mass_mean_kg();
  const double power_W = d.t_s > 0 ? d.stats.drive_work_J / d.t_s : 0.0;
  const double dtheta_rad = d.theta_rad - model.drum.initial_angle_rad;
  const double torque_Nm = dtheta_rad != 0 ? d.stats.drive_work_J / dtheta_rad : 0.0;
  const double peak_mean_N = totals.peakMean_N();
  char text[2048];
  std::snprintf(
      text, sizeof(text),
      "{\"status\": \"%s\", \"simulated_s\": %.9g, \"wall_time_s\": %.6g, \"steps\": %ld, "
      "\"impacts\": %ld, \"feed\": {\"rate_per_s\": %.9g, \"rate_kgps\": %.6g, "
      "\"mat_speed_mps\": %.9g, \"capacity\": %d, \"fed\": %ld, \"in_drum\": %ld, "
      "\"separated\": %ld, \"carried_over_detached\": %ld, \"carried_over_unthreshed\": %ld, "
      "\"out_of_bounds\": %ld, \"threshed\": %ld, \"damaged\": %ld, \"balanced\": %s, "
      "\"peak_force_mean_N\": %.6g, \"drive_work_J\": %.9g, \"power_W\": %.6g, "
      "\"torque_Nm\": %.6g}, \"peak_normal_force_N\": %.17g}\n",
      status.c_str(), d.t_s, wall_s, d.steps, d.stats.impacts, spec.rate_per_s, rate_kgps,
      spec.mat_speed_mps, spec.capacity, c.fed, c.in_drum, c.separated, c.carried_detached,
      c.carried_unthreshed, c.out_of_bounds, totals.threshed, totals.damaged,
      c.balanced() ? "true" : "false", peak_mean_N, d.stats.drive_work_J, power_W, torque_Nm,
      d.stats.peak_normal_force_N);
  if (json != nullptr) *json << text;
  if (quiet) return;
  std::printf(
      "Simulated %.6g s of a feed of %.6g kernels/s (%.3g kg/s) on a mat at %.3g m/s, pool of "
      "%d slots, in %.3g s of wall time: %s.\n"
      "Fed %ld: %ld in the drum, %ld separated, %ld carried over detached, %ld carried over "
      "unthreshed, %ld out of bounds; %ld threshed, %ld damaged. Mean peak tooth force %.3g N; "
      "drum load %.4g W, %.4g N m (drive work %.4g J).\n",
      d.t_s, spec.rate_per_s, rate_kgps, spec.mat_speed_mps, spec.capacity, wall_s, status.c_str(),
      c.fed, c.in_drum, c.separated, c.carried_detached, c.carried_unthreshed, c.out_of_bounds,
      totals.threshed, totals.damaged, peak_mean_N, power_W, torque_Nm, d.stats.drive_work_J);
}

}  // namespace

int runFeedToFiles(Model model, const FeedSpec& spec, const DamageThresholds& damage,
                   const Options& options) {
  std::ofstream summary, outcomes, series;
  openFile(options.summary_path, "--summary", &summary);
  openFile(options.outcomes_path, "--outcomes", &outcomes);
  openFile(options.feed_series_path, "--feed-series", &series);
  std::ostream* outcomes_out = outcomes.is_open() ? &outcomes : nullptr;
  std::ostream* series_out = series.is_open() ? &series : nullptr;
  if (outcomes_out != nullptr) writeOutcomesHeader(outcomes);
  if (series_out != nullptr) writeSeriesHeader(series);

  Data data;
  resetData(model, &data);
  FeedState state;
  startFeed(spec, model, &data, &state);
  FeedSeries feed_series;
  feed_series.start(data, state.counts, spec.capacity);
  std::string status = "ok";
  const auto started = std::chrono::steady_clock::now();
  const double t_end_s = model.duration_s;
  bool ok = updateFeed(spec, &model, &data, &state);
  double next_row_s = options.feed_interval_s;
  // Bounded: each pass advances time by at least one step (advancePast's guards fail a stall).
  while (ok && data.t_s < t_end_s) {
    const double t_next_s = std::min(t_end_s, nextFeedUpdate(data.t_s));
    if (advancePast(model, &data, t_next_s, t_end_s) == StepStatus::kFailed) {
      status = "failed: " + describe(data.stats.failure);
      break;
    }
    data.events.clear();
    ok = updateFeed(spec, &model, &data, &state);
    drainRetired(damage, outcomes_out, &state, &feed_series);
    if (data.t_s >= next_row_s - 1e-12 || data.t_s >= t_end_s) {
      const FeedIntervalRow row = feed_series.close(data, state.counts);
      if (series_out != nullptr) writeSeriesRow(*series_out, row);
      next_row_s =
          (std::floor(data.t_s / options.feed_interval_s + 1e-9) + 1) * options.feed_interval_s;
    }
  }
  if (!ok) status = "failed: " + state.error;
  if (!state.counts.balanced()) status = "failed: the feed's counts do not balance";
  const double wall_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
  reportFeed(model, spec, data, state, feed_series.totals(), status, wall_s,
             summary.is_open() ? &summary : nullptr, options.quiet);
  closeFile(options.summary_path, "--summary", &summary);
  closeFile(options.outcomes_path, "--outcomes", &outcomes);
  closeFile(options.feed_series_path, "--feed-series", &series);
  return status == "ok" ? 0 : 1;
}

}  // namespace app
}  // namespace threshing_sim
