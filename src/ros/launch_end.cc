#include "threshing_sim/ros/launch_end.h"

#include <signal.h>
#include <unistd.h>

#include <fstream>
#include <iterator>

namespace threshing_sim {

bool isRoslaunchCommandLine(const std::string& cmdline) {
  size_t begin = 0;
  while (begin < cmdline.size()) {
    size_t end = cmdline.find('\0', begin);
    if (end == std::string::npos) end = cmdline.size();
    const std::string arg = cmdline.substr(begin, end - begin);
    const size_t slash = arg.rfind('/');
    if (arg.substr(slash == std::string::npos ? 0 : slash + 1) == "roslaunch") return true;
    begin = end + 1;
  }
  return false;
}

bool requestLaunchShutdown() {
  const pid_t parent = getppid();
  if (parent <= 1) return false;
  std::ifstream in("/proc/" + std::to_string(parent) + "/cmdline", std::ios::binary);
  const std::string cmdline((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (!isRoslaunchCommandLine(cmdline)) return false;
  return kill(parent, SIGINT) == 0;
}

}  // namespace threshing_sim
