#include "threshing_sim/ros/node_shared.h"

#include <utility>

namespace threshing_sim {

void SnapshotQueue::push(Snapshot s, const std::atomic<bool>& stop) {
  std::unique_lock<std::mutex> lock(mutex_);
  cv_.wait(lock, [&] { return queue_.size() < kMaxQueued || stop; });
  queue_.push_back(std::move(s));
  cv_.notify_all();
}

std::deque<Snapshot> SnapshotQueue::takeAll(double timeout_s, const std::atomic<bool>& stop) {
  std::deque<Snapshot> batch;
  {
    std::unique_lock<std::mutex> lock(mutex_);
    cv_.wait_for(lock, seconds(timeout_s), [&] { return !queue_.empty() || stop; });
    batch.swap(queue_);
  }
  cv_.notify_all();  // a producer waiting for room
  return batch;
}

bool SnapshotQueue::empty() {
  std::lock_guard<std::mutex> lock(mutex_);
  return queue_.empty();
}

RunStatus runStatus(const RunFlags& flags, const RunCounters& counters, const std::string& failure,
                    double busy_s, double watchdog_timeout_s) {
  RunStatus s;
  const double rtf = counters.measured_rtf, target = counters.target_rtf;
  if (busy_s > watchdog_timeout_s) {
    s = {RunStatus::kError, "STALLED",
         "watchdog: physics step running for " + std::to_string(busy_s) + " s"};
  } else if (flags.failed) {
    s = {RunStatus::kError, "FAILED", "integrator failed (" + failure + "): call ~reset"};
  } else if (counters.recoveries > 0) {
    s = {RunStatus::kWarn, "running", "numerical recoveries"};
  } else if (!flags.paused && !flags.finished && target > 0 && rtf < kSlowFraction * target) {
    s = {RunStatus::kWarn, "SLOW", "slower than the target real time"};
  } else if (counters.deflection_warning_s >= 0) {
    s = {RunStatus::kWarn, "running",
         "tooth deflection outside the small-deflection range of the beam model"};
  } else if (counters.resets_skipped > 0) {
    s = {RunStatus::kWarn, "running", "resets skipped: the start poses overlapped a body"};
  } else {
    const char* state = flags.finished ? "finished" : flags.paused ? "paused" : "running";
    s = {RunStatus::kOk, state, state};
  }
  return s;
}

}  // namespace threshing_sim
