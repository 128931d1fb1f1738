#include "threshing_sim/ros/node_shared.h"

#include <cstdio>
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
  char buf[160];
  if (busy_s > watchdog_timeout_s) {
    std::snprintf(buf, sizeof(buf), "watchdog: physics step running for %.1f s", busy_s);
    return {RunStatus::kError, "STALLED", buf};
  }
  if (flags.failed)
    return {RunStatus::kError, "FAILED", "integrator failed (" + failure + "): call ~reset"};
  const bool paused = flags.paused, finished = flags.finished;
  const double rtf = counters.measured_rtf, target = counters.target_rtf;
  const bool slow = !paused && !finished && target > 0 && rtf < kSlowFraction * target;
  RunStatus s;
  s.state = finished ? "FINISHED" : paused ? "PAUSED" : slow ? "SLOW" : "RUNNING";
  s.level = RunStatus::kWarn;
  if (counters.recoveries > 0) {
    s.message = "numerical recoveries";
  } else if (slow) {
    std::snprintf(buf, sizeof(buf),
                  "slower than the target real time: real-time factor %.3g, pace %.3g", rtf,
                  target);
    s.message = buf;
  } else if (counters.deflection_warning_s >= 0) {
    s.message = "tooth deflection outside the small-deflection range of the beam model";
  } else if (counters.resets_skipped > 0) {
    s.message = "resets skipped: the start poses overlapped a body";
  } else {
    s.level = RunStatus::kOk;
    s.message = finished ? "finished"
                : paused ? "paused (~pause or ~start_paused): call ~pause false to run"
                         : "running";
  }
  return s;
}

}  // namespace threshing_sim
