// threshing_sim core: the feed's time series (core/feed.h FeedSeries): what `simulate
// --feed-series` writes per interval and the node publishes on feed_throughput.
#include <algorithm>
#include <cmath>
#include <vector>

#include "threshing_sim/core/feed.h"

namespace threshing_sim {

double feedPercentile(const std::vector<double>& sorted, double p) {
  if (sorted.empty()) return 0.0;
  const size_t rank = static_cast<size_t>(std::ceil(p * sorted.size()));
  return sorted[std::min(sorted.size() - 1, rank == 0 ? 0 : rank - 1)];
}

void FeedSeries::start(const Data& d, const FeedCounts& c, int capacity) {
  peaks_N_.reserve(static_cast<size_t>(std::max(capacity, 0)));
  totals_ = FeedTotals();
  close(d, c);
}

void FeedSeries::add(const FeedRecord& r, double plastic_force_N) {
  const bool threshed = r.detach_s >= 0;
  const bool damaged = r.peak_contact_N >= plastic_force_N;
  threshed_ += threshed;
  damaged_ += damaged;
  totals_.threshed += threshed;
  totals_.damaged += damaged;
  peaks_N_.push_back(r.peak_normal_N);
  totals_.peak_sum_N += r.peak_normal_N;
  ++totals_.peak_count;
}

FeedIntervalRow FeedSeries::close(const Data& d, const FeedCounts& c) {
  std::sort(peaks_N_.begin(), peaks_N_.end());
  FeedIntervalRow row;
  row.t_start_s = t_start_s_;
  row.t_end_s = d.t_s;
  row.fed = c.fed - at_start_.fed;
  row.threshed = threshed_;
  row.damaged = damaged_;
  row.separated = c.separated - at_start_.separated;
  row.carried_detached = c.carried_detached - at_start_.carried_detached;
  row.carried_unthreshed = c.carried_unthreshed - at_start_.carried_unthreshed;
  row.out_of_bounds = c.out_of_bounds - at_start_.out_of_bounds;
  row.in_drum = c.in_drum;
  for (double f : peaks_N_) row.peak_force_mean_N += f;
  if (!peaks_N_.empty()) row.peak_force_mean_N /= static_cast<double>(peaks_N_.size());
  row.peak_force_p50_N = feedPercentile(peaks_N_, 0.5);
  row.peak_force_p90_N = feedPercentile(peaks_N_, 0.9);
  row.peak_force_max_N = peaks_N_.empty() ? 0.0 : peaks_N_.back();
  const double dt_s = d.t_s - t_start_s_;
  row.drive_work_J = d.stats.drive_work_J - drive_work_start_J_;
  row.power_W = dt_s > 0 ? row.drive_work_J / dt_s : 0.0;
  const double dtheta_rad = d.theta_rad - theta_start_rad_;
  row.torque_Nm = dtheta_rad != 0 ? row.drive_work_J / dtheta_rad : 0.0;
  // The next interval.
  t_start_s_ = d.t_s;
  at_start_ = c;
  threshed_ = damaged_ = 0;
  peaks_N_.clear();
  drive_work_start_J_ = d.stats.drive_work_J;
  theta_start_rad_ = d.theta_rad;
  return row;
}

}  // namespace threshing_sim
