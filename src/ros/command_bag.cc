// The ~command_bag reader (see command_bag.h).
#include "threshing_sim/ros/command_bag.h"

#include <rosbag/bag.h>
#include <rosbag/view.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>

#include "threshing_sim/ContactStateArray.h"
#include "threshing_sim/DrumSpeedCommand.h"

namespace threshing_sim {
namespace {

// "~command_bag (PATH): "
std::string where(const std::string& path) { return "~command_bag (" + path + "): "; }

// A stamp to the nanosecond, "0.000010500 s".
std::string stampText(std::uint64_t ns) {
  char text[48];
  std::snprintf(text, sizeof(text), "%llu.%09llu s",
                static_cast<unsigned long long>(ns / 1000000000ULL),
                static_cast<unsigned long long>(ns % 1000000000ULL));
  return text;
}

// The boundary index of a stamp; a stamp more than dt/1000 off the grid means another
// ~physics_dt (or wall clock mode).
long stepOf(const std::string& path, std::uint64_t ns, std::int64_t dt_ns) {
  const std::int64_t sns = static_cast<std::int64_t>(std::min<std::uint64_t>(ns, INT64_MAX / 2));
  const long k = static_cast<long>((sns + dt_ns / 2) / dt_ns);
  if (std::llabs(sns - k * dt_ns) * 1000 > dt_ns)
    throw std::invalid_argument(where(path) + "stamp " + stampText(ns) +
                                " is not on this node's step grid of " + stampText(dt_ns) +
                                " (recorded with another ~physics_dt or in wall clock mode?)");
  return k;
}

// The n-th message (0-based) on its topic as M, refusing a foreign definition or a short record.
template <class M>
boost::shared_ptr<M> instantiate(const std::string& path, const rosbag::MessageInstance& m,
                                 size_t n) {
  const std::string what =
      "message " + std::to_string(n) + " of type " + m.getDataType() + " on " + m.getTopic() + " ";
  if (m.getMD5Sum() != ros::message_traits::MD5Sum<M>::value())
    throw std::invalid_argument(where(path) + what + "has md5sum " + m.getMD5Sum() +
                                ", this build's is " + ros::message_traits::MD5Sum<M>::value() +
                                " (recorded with another message definition)");
  boost::shared_ptr<M> msg;
  try {
    msg = m.instantiate<M>();
  } catch (const ros::Exception& e) {
    throw std::invalid_argument(where(path) + what + "is malformed: " + e.what());
  }
  if (!msg)
    throw std::invalid_argument(where(path) + what + "cannot be read as " + m.getDataType());
  return msg;
}

}  // namespace

CommandBagContents readCommandBag(const std::string& path, std::int64_t dt_ns,
                                  double max_drum_speed_radps) {
  if (dt_ns <= 0) throw std::invalid_argument(where(path) + "the physics step must be > 0");
  CommandBagContents out;
  try {
    rosbag::Bag bag(path, rosbag::bagmode::Read);
    size_t n = 0;
    for (const rosbag::MessageInstance& m :
         rosbag::View(bag, rosbag::TypeQuery("threshing_sim/DrumSpeedCommand"))) {
      const auto c = instantiate<DrumSpeedCommand>(path, m, n);
      const long step = stepOf(path, c->header.stamp.toNSec(), dt_ns);
      // The live topic's test (onDrumSpeedCommand): finite and within ~max_drum_speed.
      if (!std::isfinite(c->speed) || std::abs(c->speed) > max_drum_speed_radps) {
        char text[160];
        std::snprintf(text, sizeof(text),
                      "command %zu at %s: speed %g rad/s is not finite or exceeds "
                      "~max_drum_speed = %g rad/s",
                      n, stampText(c->header.stamp.toNSec()).c_str(), c->speed,
                      max_drum_speed_radps);
        throw std::invalid_argument(where(path) + text);
      }
      out.commands.push_back({step, c->speed});
      ++n;
    }
    std::stable_sort(out.commands.begin(), out.commands.end(),
                     [](const BagCommand& a, const BagCommand& b) { return a.step < b.step; });
    n = 0;
    for (const rosbag::MessageInstance& m :
         rosbag::View(bag, rosbag::TypeQuery("threshing_sim/ContactStateArray"))) {
      const auto c = instantiate<ContactStateArray>(path, m, n++);
      out.last_contact_step =
          std::max(out.last_contact_step, stepOf(path, c->header.stamp.toNSec(), dt_ns));
    }
  } catch (const rosbag::BagException& e) {
    throw std::invalid_argument(where(path) + e.what());
  } catch (const ros::Exception& e) {
    throw std::invalid_argument(where(path) + "unreadable: " + e.what());
  } catch (const std::bad_alloc&) {
    throw std::invalid_argument(where(path) +
                                "unreadable: a record claims more memory than "
                                "there is (corrupt lengths)");
  }
  return out;
}

}  // namespace threshing_sim
