// threshing_sim ROS layer, physics thread: the continuous feed of a scene with a `feed` section
// (core/feed.h) run in the node.
//
// The feed is updated as `simulate` updates it (kernels that left retired, kernels due placed):
// after the advance, at the first step boundary at or past the next multiple of
// kFeedUpdateStep_s after the last update (the boundary's state is the step end at or past it,
// the step end `simulate` updates at when the physics step divides kFeedUpdateStep_s: both then
// take the same steps), and at a bounded run's last boundary; feed rate commands are applied at
// step boundaries (core setFeedRate: deterministic, the seeded scatter continues), and the
// throughput series (core FeedSeries, as `simulate --feed-series` computes it) closes an interval
// every ~feed_interval of simulated time, on the step grid. Placing a kernel writes its values into
// its pool slot of the Model: the node's model is shared with the snapshots the output thread
// reads, so a model still shared is copied first (copy on write) and the loop's pointer swapped for
// the copy.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "threshing_sim/core/data.h"
#include "threshing_sim/core/feed.h"
#include "threshing_sim/core/model.h"
#include "threshing_sim/ros/snapshot.h"

namespace threshing_sim {

class NodeFeed {
 public:
  // spec: the scene's feed; plastic_force_N: the damage threshold [N]; interval_steps: step
  // boundaries per throughput interval [-].
  NodeFeed(const FeedSpec& spec, double plastic_force_N, long interval_steps);

  // Parks the pool and starts the feed at data's time (a run's start: kernels arrive from
  // feed.start; a reset: from now on, at the rate in force), the counts and the series from
  // zero, then places the kernels due now (the model may be swapped: copy on write).
  bool start(std::shared_ptr<const Model>* model, Data* data);
  // A feed rate command at the boundary at data's time: "" or why it was refused (naming the
  // value; nothing changes then).
  std::string setRate(double rate_per_s, const Data& data);
  // At boundary k (time t_k_s; last: a bounded run's last), after the advance: retires and
  // places kernels when an update is due, and closes the throughput interval when k is a
  // multiple of interval_steps (kept until the next snapshot). False when the pool has no slot
  // for a kernel due or a kernel cannot be placed (error()).
  bool update(std::shared_ptr<const Model>* model, Data* data, long k, double t_k_s, bool last,
              const ros::Time& stamp);
  // Moves into s the feed's state now, the intervals closed and commands applied since the
  // previous snapshot.
  void fill(Snapshot* s);
  // For a frame (StrikeFrames): the state now only.
  void fillState(Snapshot* s) const;
  void noteCommand(const AppliedFeedCommand& c) { commands_.push_back(c); }
  const std::string& error() const { return state_.error; }
  const FeedSpec& spec() const { return spec_; }
  const FeedCounts& counts() const { return state_.counts; }
  const FeedTotals& totals() const { return series_.totals(); }

 private:
  bool place(std::shared_ptr<const Model>* model, Data* data);
  void drain();

  FeedSpec spec_;                 // the scene's, with the rate in force
  double plastic_force_N_;        // damage threshold [N]
  long interval_steps_;           // boundaries per throughput interval [-]
  double next_update_s_ = 0;      // the next update at the first boundary at or past it [s]
  FeedState state_;               // the pool, the counts, the scatter
  FeedSeries series_;             // the interval being accumulated, the totals
  std::shared_ptr<Model> owned_;  // the model this feed changes (the loop's, unless swapped)
  std::vector<FeedIntervalRecord> intervals_;  // closed since the previous snapshot
  std::vector<AppliedFeedCommand> commands_;   // applied since the previous snapshot
};

}  // namespace threshing_sim
