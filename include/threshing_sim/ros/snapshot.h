// threshing_sim ROS layer: what the output thread needs of one instant of the simulation.
//
// The physics thread copies a Snapshot at a step boundary (cheap: a few vectors); the output
// thread turns it into messages. Nothing ROS-specific is computed in the stepping loop.
#pragma once

#include <ros/time.h>

#include <cstdint>
#include <memory>
#include <vector>

#include "threshing_sim/core/data.h"
#include "threshing_sim/core/feed.h"
#include "threshing_sim/core/model.h"
#include "threshing_sim/ros/live_view.h"

namespace threshing_sim {

// Output streams, as a bit mask: which topics a snapshot is due on.
enum Stream : unsigned {
  kContactStream = 1u,  // contact_state
  kStateStream = 2u,    // kernel_states, beam_shape, tf world->drum and tooth tips
  kMarkerStream = 4u,   // markers
  kAllStreams = 7u,
};

// The largest normal force of the latest contact episode of one pair (drawn as the
// "last_contact" arrow once the episode is over, so that a 40 us contact stays visible at any
// real-time factor).
struct PeakContact {
  PairId pair;
  ContactState state = ContactState::kSeparated;  // state at the peak
  Vec2 p_W = Vec2::Zero();                        // contact point, world [m]
  Vec2 f_W = Vec2::Zero();                        // force on body b at the peak, world [N]
  double normal_force_N = 0;                      // normal force at the peak [N]
  long last_closed_step = -1;                     // last boundary the pair was closed at
};

// A drum speed command as applied at a step boundary.
struct AppliedCommand {
  ros::Time stamp;     // the boundary (simulation time in sim clock mode)
  double speed_radps;  // target drum speed [rad/s]
};

// A feed rate command as applied at a step boundary.
struct AppliedFeedCommand {
  ros::Time stamp;        // the boundary (simulation time in sim clock mode)
  double rate_per_s = 0;  // kernels fed per second [1/s]
};

// One closed interval of the feed's throughput series (a feed_throughput message).
struct FeedIntervalRecord {
  ros::Time stamp;        // the boundary that closed it
  FeedIntervalRow row;    // the interval's figures (core FeedSeries)
  FeedCounts counts;      // the feed's counts at its end
  FeedTotals totals;      // threshed, damaged and peak forces since the start
  double rate_per_s = 0;  // feed rate in force [1/s]
  double rate_kgps = 0;   // the same at the feed's mean kernel mass [kg/s]
};

// The continuous feed at a snapshot (a scene with a `feed` section; else present is false).
struct SnapshotFeed {
  bool present = false;
  double rate_per_s = 0;                      // feed rate in force [1/s]
  double rate_kgps = 0;                       // the same at the mean kernel mass [kg/s]
  FeedCounts counts;                          // fed, in drum, retired by fate, now [-]
  FeedTotals totals;                          // threshed, damaged, peak forces so far
  std::vector<FeedIntervalRecord> intervals;  // closed since the previous snapshot
  std::vector<AppliedFeedCommand> commands;   // applied since the previous snapshot
};

struct Snapshot {
  std::shared_ptr<const Model> model;  // the model in effect (contact values may change live)
  long step = 0;                       // boundary index k: t = k * physics_dt
  double t_s = 0;                      // simulation time [s] (after a failure: of the state kept)
  ros::Time stamp;                     // stamp of every message built from this snapshot
  double theta_rad = 0;                // drum angle [rad]
  double omega_radps = 0;              // drum speed [rad/s]
  double omega_target_radps = 0;       // commanded drum speed [rad/s]
  double alpha_radps2 = 0;             // drum acceleration [rad/s^2]
  long loops = 0;                      // demo-loop kernel re-seeds so far [-]
  double target_rtf = 0;               // real-time factor the pacer aims at now [-]
  double requested_rtf = 0;            // ~real_time_factor as asked for (reconfigurable) [-]
  double measured_rtf = 0;             // measured real-time factor [-]
  Vec2 strike_focus_W = Vec2::Zero();  // tf frame `strike`: the tooth-kernel contact point, else
                                       // the kernel a tooth reaches first, world [m]
  VecX z;                              // generalised positions (see core/data.h)
  VecX u;                              // generalised velocities
  std::vector<std::uint8_t> kernel_attached;
  std::vector<std::uint8_t> kernel_active;  // 0: a parked pool slot of the feed, not drawn
  std::vector<ContactInfo> contacts;        // pairs examined in the last step
  std::vector<double> kernel_peak_force_N;  // per kernel, so far [N]
  std::vector<long> kernel_impacts;         // per kernel, so far
  std::vector<ContactEvent> impacts;        // impacts completed since the previous snapshot
  std::vector<AppliedCommand> commands;     // commands applied since the previous snapshot
  std::vector<PeakContact> peaks;           // latest episode of every pair that touched
  std::vector<KernelForces> kernel_forces;  // per kernel: forces now, impulse sums
  std::vector<StrikeRecord> strikes;        // strikes finished since the previous snapshot
  SnapshotFeed feed;                        // the continuous feed, if the scene has one
  unsigned streams = 0;                     // Stream bits due
  bool reset = false;                       // bodies were reset: markers start with DELETEALL
  bool frame = false;  // a strike's frame (StrikeFrames): markers of the bodies, contacts and
                       // overlay only; rviz keeps the strike chart and status drawn last
  // The strike's frames since the previous snapshot, oldest first: their markers go out in
  // this snapshot's `markers` message, before its own, each marker stamped with its frame's
  // time (scripts/play_bag splits them again), so that a burst of frames is one message.
  std::vector<Snapshot> frames;
};

}  // namespace threshing_sim
