// threshing_sim ROS layer: messages, markers and transforms built from a Snapshot.
//
// Pure conversions (no publishing), run by the node's output thread. Frames: `world`, `drum`,
// `tooth_<i>_root` (static in `drum`: x along the undeformed tooth), `tooth_<i>_tip`.
#pragma once

#include <geometry_msgs/TransformStamped.h>
#include <visualization_msgs/MarkerArray.h>

#include <cstdint>
#include <map>
#include <set>
#include <string>
#include <vector>

#include "threshing_sim/BeamShapeArray.h"
#include "threshing_sim/ContactStateArray.h"
#include "threshing_sim/DrumSpeedCommand.h"
#include "threshing_sim/DrumState.h"
#include "threshing_sim/FeedRateCommand.h"
#include "threshing_sim/FeedThroughput.h"
#include "threshing_sim/ImpactEvent.h"
#include "threshing_sim/KernelContactForces.h"
#include "threshing_sim/KernelStateArray.h"
#include "threshing_sim/StrikeHistory.h"
#include "threshing_sim/ros/live_view.h"
#include "threshing_sim/ros/node_shared.h"
#include "threshing_sim/ros/snapshot.h"
#include "threshing_sim/scene/outcomes.h"

namespace threshing_sim {

extern const char* const kWorldFrame;   // "world"
extern const char* const kDrumFrame;    // "drum"
std::string toothRootFrame(int tooth);  // "tooth_<i>_root"
std::string toothTipFrame(int tooth);   // "tooth_<i>_tip"

// Marker id of a contact pair, stable for the whole run: kind * 1e6 + a * 1e3 + b.
int pairMarkerId(const PairId& pair);

// Puts the snapshot's drum angle and positions into scratch, for the tooth shape functions
// (toothPointWorld and friends read nothing else).
void loadPose(const Snapshot& s, Data* scratch);

// contact_state. The core keeps running impulse sums per pair; this turns them into the
// impulse since the previous message.
class ContactStateBuilder {
 public:
  ContactStateArray build(const Snapshot& s);

 private:
  std::map<PairId, Vec2> last_sums_Ns_;  // (normal, tangential) sums at the previous message
};

ImpactEvent impactEventMsg(const ContactEvent& e, const ros::Time& stamp);
DrumSpeedCommand drumSpeedCommandMsg(const AppliedCommand& c);
FeedRateCommand feedRateCommandMsg(const AppliedFeedCommand& c);
FeedThroughput feedThroughputMsg(const FeedIntervalRecord& r);
// Parked pool slots of a feed (kernel_active 0) are left out.
KernelStateArray kernelStatesMsg(const Snapshot& s);
DrumState drumStateMsg(const Snapshot& s);
KernelContactForces kernelContactForcesMsg(const Snapshot& s);
StrikeHistory strikeHistoryMsg(const StrikeRecord& r, const ros::Time& stamp);
// scratch must hold the snapshot's pose (loadPose).
BeamShapeArray beamShapeMsg(const Snapshot& s, const Data& scratch, int points);

// world -> drum and tooth_<i>_root -> tooth_<i>_tip at the snapshot (scratch: loadPose).
std::vector<geometry_msgs::TransformStamped> movingTransforms(const Snapshot& s,
                                                              const Data& scratch);
// drum -> tooth_<i>_root, for the StaticTransformBroadcaster.
std::vector<geometry_msgs::TransformStamped> staticTransforms(const Model& model,
                                                              const ros::Time& stamp);

// The colour the overlay and the status markers take for a run status: OK running light grey,
// OK paused or finished sky blue, a warning (the pace not held...) amber, an error red.
std_msgs::ColorRGBA statusColor(const RunStatus& status);

// markers: one namespace per entity, stable ids. Static geometry (drum, obstacles) only when
// asked; DELETEALL first after a reset; arrows of pairs no longer in contact are deleted.
class MarkerBuilder {
 public:
  explicit MarkerBuilder(double force_arrow_scale_mpN, int beam_points)
      : scale_mpN_(force_arrow_scale_mpN), beam_points_(beam_points) {}
  visualization_msgs::MarkerArray build(const Snapshot& s, const Data& scratch, bool with_static);
  // Where the text overlay and the strike chart go, and the kernels' damage colours.
  void setView(const SceneExtent& extent, const DamageThresholds& damage) {
    extent_ = extent;
    damage_ = damage;
  }
  // A fed scene: its grate and mat are static geometry (feed: the scene's, or nullptr).
  void setFeed(const FeedSpec* feed) {
    has_feed_ = feed != nullptr;
    if (feed != nullptr) feed_ = *feed;
  }
  // Every finished strike goes through here (whichever stream its snapshot was due on).
  void noteStrikes(const std::vector<StrikeRecord>& strikes) {
    if (strikes.empty()) return;
    last_strike_ = strikes.back();
    have_strike_ = true;
  }
  // The run's state the overlay and the status markers show (the output thread sets it before
  // each build, from the same RunStatus as /diagnostics).
  void setStatus(const RunStatus& status) { status_ = status; }
  // The drum, the obstacles (and the chart's frame): the static geometry alone.
  visualization_msgs::MarkerArray staticGeometry(const Snapshot& s) const;

 private:
  void addOverlay(const Snapshot& s, visualization_msgs::MarkerArray* out) const;
  void addStrikeChart(const Snapshot& s, visualization_msgs::MarkerArray* out) const;
  void addStatus(const Snapshot& s, visualization_msgs::MarkerArray* out) const;
  void addFeedGeometry(const Snapshot& s, visualization_msgs::MarkerArray* out) const;

  SceneExtent extent_;                      // the scene's box in world [m]
  DamageThresholds damage_;                 // kernel colours: damaged at or above plastic_force [N]
  StrikeRecord last_strike_;                // the chart shows this one
  bool have_strike_ = false;                // a strike has finished since start
  double scale_mpN_;                        // force arrow length per newton [m/N]
  int beam_points_;                         // centreline samples per tooth [-]
  std::set<int> live_force_arrows_;         // ids of the contact_forces arrows now shown
  std::vector<std::uint8_t> kernel_drawn_;  // per kernel: its marker is shown (a feed's parked
                                            // slots are deleted once, when parked)
  RunStatus status_;                        // shown on the overlay and by the status markers
  FeedSpec feed_;                           // the scene's feed (has_feed_): its grate and mat drawn
  bool has_feed_ = false;
};

// The overlay's feed line: rate, fed, in the drum and the running fractions of the kernels
// retired so far (threshed, damaged, separated, carried over, out of bounds).
std::string feedOverlayLine(const SnapshotFeed& feed);

}  // namespace threshing_sim
