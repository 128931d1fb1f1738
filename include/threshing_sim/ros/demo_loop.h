// threshing_sim ROS layer, physics thread: the demo loop. Every ~loop_revolutions drum
// revolutions the kernels start over from their initial poses (the teeth and the commanded
// drum speed stay as they are), unless that would place bodies overlapping.
#pragma once

#include <string>

#include "threshing_sim/core/data.h"
#include "threshing_sim/core/model.h"
#include "threshing_sim/ros/pacer.h"

namespace threshing_sim {

class DemoLoop {
 public:
  // loop_revolutions <= 0: never. clock: the steady clock the overlap warnings are throttled on.
  DemoLoop(const Model& model, int loop_revolutions, const SteadyClock& clock);

  // The loop phase counts from the drum angle now.
  void start(const Data& data) { anchor_rad_ = data.theta_rad; }
  // Whether the drum passed the loop phase since the previous call.
  bool due(const Data& data);
  // Re-seeds the kernels of data (the drum target set again through setDrumTarget) unless the
  // kernels' initial poses overlap a body now; false (with a throttled warning) if they do.
  bool reseedIfClear(const Model& model, Data* data);
  long loops() const { return loops_; }  // re-seeds done [-]

 private:
  int revolutions_;
  const SteadyClock& clock_;
  double anchor_rad_ = 0;      // drum angle the loop phase counts from [rad]
  long index_ = 0;             // loop periods passed [-]
  long loops_ = 0;             // kernel re-seeds done [-]
  Data candidate_;             // the state a re-seed would give, for the overlap check
  double last_warn_s_ = -1e9;  // steady time of the last overlap warning [s]
};

}  // namespace threshing_sim
