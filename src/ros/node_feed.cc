// The continuous feed in the node (node_feed.h).
#include "threshing_sim/ros/node_feed.h"

#include <utility>

namespace threshing_sim {

NodeFeed::NodeFeed(const FeedSpec& spec, double plastic_force_N, long interval_steps)
    : spec_(spec), plastic_force_N_(plastic_force_N), interval_steps_(interval_steps) {
  intervals_.reserve(16);
  commands_.reserve(16);
}

bool NodeFeed::start(std::shared_ptr<const Model>* model, Data* data) {
  startFeed(spec_, **model, data, &state_);
  // Later than t = 0 (a reset): kernels arrive from now on at the rate in force.
  if (data->t_s > 0) setFeedRate(spec_.rate_per_s, data->t_s, &spec_, &state_);
  series_.start(*data, state_.counts, spec_.capacity);
  next_update_s_ = nextFeedUpdate(data->t_s);
  return place(model, data);
}

std::string NodeFeed::setRate(double rate_per_s, const Data& data) {
  return setFeedRate(rate_per_s, data.t_s, &spec_, &state_);
}

bool NodeFeed::place(std::shared_ptr<const Model>* model, Data* data) {
  if (!feedKernelDue(spec_, state_, data->t_s)) return true;
  // The model changes: a copy unless only this feed and the loop hold it (a snapshot in the
  // queue or in the output thread keeps the one it was taken with). Only the physics thread
  // hands out references, so a count of 2 cannot grow meanwhile.
  if (owned_.get() != model->get() || owned_.use_count() > 2) {
    owned_ = std::make_shared<Model>(**model);
    *model = owned_;
  }
  return placeFeedKernels(spec_, owned_.get(), data, &state_);
}

void NodeFeed::drain() {
  for (const FeedRecord& r : state_.retired) series_.add(r, plastic_force_N_);
  state_.retired.clear();
}

bool NodeFeed::update(std::shared_ptr<const Model>* model, Data* data, long k, double t_k_s,
                      bool last, const ros::Time& stamp) {
  bool ok = true;
  // As simulate's loop: advancePast(nextFeedUpdate(t)) then the update (a boundary within a
  // picosecond of the multiple is on it: k * dt in floating point).
  if (last || t_k_s >= next_update_s_ - 1e-12) {
    retireFeedKernels(spec_, **model, data, &state_);
    ok = place(model, data);
    drain();
    next_update_s_ = nextFeedUpdate(data->t_s);
  }
  if (k > 0 && k % interval_steps_ == 0) {
    FeedIntervalRecord r;
    r.stamp = stamp;
    r.row = series_.close(*data, state_.counts);
    r.counts = state_.counts;
    r.totals = series_.totals();
    r.rate_per_s = spec_.rate_per_s;
    r.rate_kgps = spec_.rate_per_s * spec_.kernel_mass_mean_kg();
    intervals_.push_back(r);
  }
  return ok;
}

void NodeFeed::fillState(Snapshot* s) const {
  SnapshotFeed& f = s->feed;
  f.present = true;
  f.rate_per_s = spec_.rate_per_s;
  f.rate_kgps = spec_.rate_per_s * spec_.kernel_mass_mean_kg();
  f.counts = state_.counts;
  f.totals = series_.totals();
}

void NodeFeed::fill(Snapshot* s) {
  fillState(s);
  s->feed.intervals = std::exchange(intervals_, {});
  s->feed.commands = std::exchange(commands_, {});
  intervals_.reserve(16);
  commands_.reserve(16);
}

}  // namespace threshing_sim
