// libFuzzer target: the ~command_bag reader. The input is written to a file and read as a bag
// with a 1e-5 s step and ~max_drum_speed 400 rad/s; refusals (std::invalid_argument naming
// ~command_bag) are expected; a crash, another exception or a sanitizer report is a finding.
#include <rosbag/encryptor.h>
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <pluginlib/class_loader.hpp>
#include <stdexcept>
#include <string>

#include "threshing_sim/ros/command_bag.h"

namespace {
// Every rosbag::Bag loads rosbag's NoEncryptor plugin library, and unloads it when destroyed
// (dlopen, dlclose and their finalizers: 90 % of this target's time). One instance held for the
// whole run keeps the library loaded, so each input pays only the lookup; the reader itself
// still opens every input with a fresh rosbag::Bag, as the node does.
struct KeepEncryptorLoaded {
  pluginlib::ClassLoader<rosbag::EncryptorBase> loader{"rosbag_storage", "rosbag::EncryptorBase"};
  boost::shared_ptr<rosbag::EncryptorBase> instance = loader.createInstance("rosbag/NoEncryptor");
};
}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  // In memory (/dev/shm) where there is one: a disk file's write-back cost a fifth of the time.
  static const std::string dir = access("/dev/shm", W_OK) == 0 ? "/dev/shm" : "/tmp";
  static const std::string path = dir + "/fuzz_command_bag." + std::to_string(getpid()) + ".bag";
  std::FILE* f = std::fopen(path.c_str(), "wb");
  if (f == nullptr) return 0;
  std::fwrite(data, 1, size, f);
  std::fclose(f);
  static KeepEncryptorLoaded keep;
  try {
    threshing_sim::readCommandBag(path, 10000, 400.0);
  } catch (const std::invalid_argument&) {
  }
  return 0;
}
