// The ~command_bag reader (see command_bag.h).
#include "threshing_sim/ros/command_bag.h"

#include <rosbag/bag.h>
#include <rosbag/view.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
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

// Largest uncompressed chunk accepted [bytes]: rosbag allocates a chunk's declared size before
// reading it, so a corrupt size field would otherwise allocate gigabytes.
constexpr std::uint64_t kMaxChunkBytes = 256ull << 20;

std::uint32_t readU32(std::istream& in) {
  unsigned char b[4] = {0, 0, 0, 0};
  in.read(reinterpret_cast<char*>(b), 4);
  return b[0] | (b[1] << 8) | (b[2] << 16) | (static_cast<std::uint32_t>(b[3]) << 24);
}

// The top-level record structure of a bag (format 2.0) before rosbag reads it: every header
// and data length within the file, and every chunk's declared size within kMaxChunkBytes (and
// equal to its data for an uncompressed chunk). Bounded: each record advances by >= 8 bytes.
void checkBagLengths(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return;  // rosbag reports it
  in.seekg(0, std::ios::end);
  const std::uint64_t file_size = static_cast<std::uint64_t>(in.tellg());
  in.seekg(0);
  std::string magic(13, '\0');
  in.read(&magic[0], 13);
  if (!in || magic != "#ROSBAG V2.0\n") return;  // rosbag reports it
  std::uint64_t pos = 13;
  const auto refuse = [&](const std::string& what) {
    throw std::invalid_argument(where(path) + "corrupt record at byte " + std::to_string(pos) +
                                ": " + what);
  };
  while (pos + 4 <= file_size) {
    const std::uint64_t header_len = readU32(in);
    if (pos + 8 + header_len > file_size) refuse("header length beyond the end of the file");
    std::string header(header_len, '\0');
    in.read(&header[0], static_cast<std::streamsize>(header_len));
    const std::uint64_t data_len = readU32(in);
    if (pos + 8 + header_len + data_len > file_size)
      refuse("data length beyond the end of the file");
    // Fields: 4-byte length, then "name=value".
    int op = -1;
    std::uint64_t size = 0;
    std::string compression;
    for (size_t f = 0; f + 4 <= header.size();) {
      const std::uint32_t len =
          static_cast<unsigned char>(header[f]) | (static_cast<unsigned char>(header[f + 1]) << 8) |
          (static_cast<unsigned char>(header[f + 2]) << 16) |
          (static_cast<std::uint32_t>(static_cast<unsigned char>(header[f + 3])) << 24);
      if (len > header.size() - f - 4) refuse("header field length beyond its header");
      const std::string field = header.substr(f + 4, len);
      const size_t eq = field.find('=');
      const std::string name = field.substr(0, eq),
                        value = eq == std::string::npos ? "" : field.substr(eq + 1);
      if (name == "op" && value.size() == 1) op = static_cast<unsigned char>(value[0]);
      if (name == "size" && value.size() == 4)
        size = static_cast<unsigned char>(value[0]) | (static_cast<unsigned char>(value[1]) << 8) |
               (static_cast<unsigned char>(value[2]) << 16) |
               (static_cast<std::uint64_t>(static_cast<unsigned char>(value[3])) << 24);
      if (name == "compression") compression = value;
      f += 4 + len;
    }
    if (op == 0x05 && (size > kMaxChunkBytes || (compression == "none" && size != data_len)))
      refuse("chunk declares " + std::to_string(size) + " bytes for " + std::to_string(data_len) +
             " bytes of " + compression + " data");
    pos += 8 + header_len + data_len;
    in.seekg(static_cast<std::streamoff>(pos));
  }
}

}  // namespace

CommandBagContents readCommandBag(const std::string& path, std::int64_t dt_ns,
                                  double max_drum_speed_radps) {
  if (dt_ns <= 0) throw std::invalid_argument(where(path) + "the physics step must be > 0");
  CommandBagContents out;
  checkBagLengths(path);
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
