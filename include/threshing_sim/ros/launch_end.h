// threshing_sim ROS layer: the quiet end of a launch. A bounded run (~end_time) ends the whole
// launch; when the node simply exits, roslaunch reports its `required` node with a red
// "REQUIRED process [...] has died!" although nothing went wrong. Instead the node asks the
// roslaunch that started it to shut down, as Ctrl-C would, and exits when roslaunch stops it.
#pragma once

#include <string>

namespace threshing_sim {

// Whether a NUL-separated command line (/proc/<pid>/cmdline) runs roslaunch (an argument whose
// base name is "roslaunch"; rostest, which runs its launch in-process, is not one).
bool isRoslaunchCommandLine(const std::string& cmdline);

// Sends SIGINT to the parent process when it is roslaunch; returns whether it did.
bool requestLaunchShutdown();

}  // namespace threshing_sim
