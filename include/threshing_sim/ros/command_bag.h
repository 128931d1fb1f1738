// threshing_sim ROS layer: the ~command_bag reader of a re-simulation.
//
// Reads the drum speed commands a run applied (threshing_sim/DrumSpeedCommand, any topic), the
// feed rate commands (threshing_sim/FeedRateCommand: NaN, inf, < 0 or > 1e6 1/s refused) and
// the last contact_state stamp (threshing_sim/ContactStateArray) from a bag. Every refusal is a
// std::invalid_argument naming ~command_bag and the path: a bag that cannot be opened, a
// message whose definition differs from this build's (md5sum), a record shorter than its
// message, a stamp off the node's step grid (printed to the nanosecond), and a speed the live
// drum_speed_cmd topic would reject (NaN, inf, |speed| > ~max_drum_speed).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace threshing_sim {

// One recorded command: applied at step boundary `step` (stamp / physics_dt).
struct BagCommand {
  long step = 0;           // boundary index [-]
  double speed_radps = 0;  // target drum speed [rad/s]
};

// One recorded feed rate command: applied at step boundary `step`.
struct BagFeedCommand {
  long step = 0;          // boundary index [-]
  double rate_per_s = 0;  // kernels fed per second [1/s]
};

struct CommandBagContents {
  std::vector<BagCommand> commands;           // in boundary order (stable for equal boundaries)
  std::vector<BagFeedCommand> feed_commands;  // likewise
  long last_contact_step = 0;                 // boundary of the last contact_state, 0 = none [-]
};

// Reads path with the node's physics step dt_ns [ns] and ~max_drum_speed [rad/s].
CommandBagContents readCommandBag(const std::string& path, std::int64_t dt_ns,
                                  double max_drum_speed_radps);

}  // namespace threshing_sim
