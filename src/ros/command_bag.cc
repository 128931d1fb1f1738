// The ~command_bag reader (see command_bag.h).
#include "threshing_sim/ros/command_bag.h"

#include <rosbag/bag.h>
#include <rosbag/view.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <functional>
#include <set>
#include <stdexcept>
#include <vector>

#include "threshing_sim/ContactStateArray.h"
#include "threshing_sim/DrumSpeedCommand.h"
#include "threshing_sim/FeedRateCommand.h"

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

std::uint32_t u32(const unsigned char* b) {
  return b[0] | (b[1] << 8) | (b[2] << 16) | (static_cast<std::uint32_t>(b[3]) << 24);
}

constexpr std::uint64_t kAbsent = ~std::uint64_t{0};

// The fields of a record header that matter here.
struct RecordHeader {
  int op = -1;                        // record type (0x03 bag header, 0x04 index data,
                                      // 0x05 chunk, 0x06 chunk info)
  std::uint64_t size = 0;             // chunk: uncompressed size [bytes]
  std::string compression;            // chunk: none, bz2, lz4
  std::uint64_t index_pos = kAbsent;  // bag header: offset of the first index record [bytes]
  std::uint64_t chunk_pos = kAbsent;  // chunk info: offset of its chunk [bytes]
  std::uint64_t count = kAbsent;      // index data: entries; chunk info: connections
  std::uint64_t ver = kAbsent;        // index data, chunk info: record version
  std::uint64_t conn = kAbsent;       // connection, index data, message: connection id
};

std::uint64_t u64(const char* b) {
  std::uint64_t v = 0;
  for (int i = 7; i >= 0; --i) v = (v << 8) | static_cast<unsigned char>(b[i]);
  return v;
}

// Parses "4-byte length, name=value" fields; false if a length runs past the header.
bool parseHeader(const std::string& header, RecordHeader* out) {
  for (size_t f = 0; f < header.size();) {
    if (header.size() - f < 4) return false;
    const std::uint32_t len = u32(reinterpret_cast<const unsigned char*>(&header[f]));
    if (len > header.size() - f - 4) return false;
    const std::string field = header.substr(f + 4, len);
    const size_t eq = field.find('=');
    if (eq == std::string::npos) return false;
    const std::string name = field.substr(0, eq), value = field.substr(eq + 1);
    if (name == "op" && value.size() == 1) out->op = static_cast<unsigned char>(value[0]);
    if (name == "size" && value.size() == 4)
      out->size = u32(reinterpret_cast<const unsigned char*>(value.data()));
    if (name == "compression") out->compression = value;
    if (name == "index_pos" && value.size() == 8) out->index_pos = u64(value.data());
    if (name == "chunk_pos" && value.size() == 8) out->chunk_pos = u64(value.data());
    if (name == "count" && value.size() == 4)
      out->count = u32(reinterpret_cast<const unsigned char*>(value.data()));
    if (name == "ver" && value.size() == 4)
      out->ver = u32(reinterpret_cast<const unsigned char*>(value.data()));
    if (name == "conn" && value.size() == 4)
      out->conn = u32(reinterpret_cast<const unsigned char*>(value.data()));
    f += 4 + len;
  }
  return true;
}

// The records inside an uncompressed chunk: every length and header field within the chunk
// (rosbag and ros::Header::parse read them without bounds checks).
void checkChunkRecords(const std::string& chunk,
                       const std::function<void(const std::string&)>& refuse,
                       std::set<std::uint64_t>* starts, std::set<std::uint64_t>* connections) {
  starts->clear();
  for (size_t pos = 0; pos < chunk.size();) {
    starts->insert(pos);
    if (chunk.size() - pos < 4) refuse("chunk record header length cut off");
    const std::uint64_t header_len = u32(reinterpret_cast<const unsigned char*>(&chunk[pos]));
    if (header_len + 8 > chunk.size() - pos) refuse("chunk record header beyond its chunk");
    RecordHeader h;
    if (!parseHeader(chunk.substr(pos + 4, header_len), &h))
      refuse("chunk record header field beyond its header");
    const std::uint64_t data_len =
        u32(reinterpret_cast<const unsigned char*>(&chunk[pos + 4 + header_len]));
    if (data_len > chunk.size() - pos - 8 - header_len)
      refuse("chunk record data beyond its chunk");
    // A connection record's data is itself a header (topic, type, md5sum, definition).
    RecordHeader connection;
    if (h.op == 0x07 && !parseHeader(chunk.substr(pos + 8 + header_len, data_len), &connection))
      refuse("connection header field beyond its record");
    if (h.op == 0x07) connections->insert(h.conn);
    pos += 8 + header_len + data_len;
  }
}

// What a pass over a bag's records found, for the checks across records.
struct BagScan {
  std::set<std::uint64_t> record_starts;        // byte offsets of the top-level records
  std::set<std::uint64_t> chunk_starts;         // offsets of the records in the last chunk
  std::set<std::uint64_t> connections;          // connection ids defined
  std::set<std::uint64_t> indexed_connections;  // connection ids named by index records
  std::vector<std::uint64_t> chunk_positions;   // chunk_pos of every chunk info
  std::uint64_t index_pos = kAbsent;            // the bag header's index_pos
};

// Reads n bytes of the stream into a string.
std::string readBytes(std::ifstream& in, std::uint64_t n) {
  std::string bytes(n, '\0');
  in.read(&bytes[0], static_cast<std::streamsize>(n));
  return bytes;
}

// The data of one top-level record (header h, data_len bytes, the stream at its data): a chunk
// uncompressed with its declared size and its records within it, a connection's header within
// its record, a chunk info's and an index record's counts equal to their data.
void checkRecordData(std::ifstream& in, const RecordHeader& h, std::uint64_t data_len,
                     const std::function<void(const std::string&)>& refuse, BagScan* scan) {
  if (h.op == 0x03) scan->index_pos = h.index_pos;
  if (h.op == 0x06) scan->chunk_positions.push_back(h.chunk_pos);
  if (h.op == 0x05) {
    if (h.compression != "none")
      refuse("compressed chunk (" + h.compression +
             ") not read; decompress the bag first (rosbag decompress)");
    if (h.size != data_len || h.size > kMaxChunkBytes)
      refuse("chunk declares " + std::to_string(h.size) + " bytes for " + std::to_string(data_len) +
             " bytes of data");
    checkChunkRecords(readBytes(in, data_len), refuse, &scan->chunk_starts, &scan->connections);
  } else if (h.op == 0x07) {
    // A connection record's data is itself a header (topic, type, md5sum, definition).
    if (data_len > (16u << 20)) refuse("connection record too large");
    RecordHeader connection;
    if (!parseHeader(readBytes(in, data_len), &connection))
      refuse("connection header field beyond its record");
    scan->connections.insert(h.conn);
  } else if (h.op == 0x06) {
    // Chunk info: `count` (connection id, message count) pairs, which rosbag reads as many.
    if (h.ver != 1 || h.count > (1u << 20) || h.count * 8 != data_len)
      refuse("chunk info declares " + std::to_string(h.count) + " connections for " +
             std::to_string(data_len) + " bytes of data");
  } else if (h.op == 0x04) {
    // Index data: `count` entries of (time 8 bytes, offset 4 bytes) into the chunk before it,
    // which rosbag reads as many (a larger count read offsets from beyond the record).
    if (data_len > (64u << 20)) refuse("index record too large");
    if (h.ver != 1 || h.count * 12 != data_len)
      refuse("index record declares " + std::to_string(h.count) + " entries for " +
             std::to_string(data_len) + " bytes of data");
    scan->indexed_connections.insert(h.conn);
    const std::string index = readBytes(in, data_len);
    for (size_t e = 0; e + 12 <= index.size(); e += 12)
      if (scan->chunk_starts.count(u32(reinterpret_cast<const unsigned char*>(&index[e + 8]))) == 0)
        refuse("index entry points between the records of its chunk");
  }
}

// rosbag seeks to the bag header's index_pos and to every chunk_pos and reads a record there:
// each must start one; every connection an index names must be defined.
void checkCrossReferences(const BagScan& scan,
                          const std::function<void(const std::string&)>& refuse) {
  if (scan.index_pos != kAbsent && scan.index_pos != 0 &&
      scan.record_starts.count(scan.index_pos) == 0)
    refuse("the bag header's index_pos " + std::to_string(scan.index_pos) + " starts no record");
  for (const std::uint64_t c : scan.chunk_positions)
    if (scan.record_starts.count(c) == 0)
      refuse("a chunk info's chunk_pos " + std::to_string(c) + " starts no record");
  for (const std::uint64_t c : scan.indexed_connections)
    if (scan.connections.count(c) == 0)
      refuse("an index record names connection " + std::to_string(c) +
             ", which no connection record defines");
}

// The record structure of a bag (format 2.0) before rosbag reads it: every header and data
// length within the file, every header field within its header, every chunk uncompressed with
// its declared size equal to its data (at most kMaxChunkBytes) and its records within it.
// rosbag allocates and copies by these numbers unchecked (out of memory, heap overflows on a
// corrupt bag, found by fuzz_command_bag). Bounded: each record advances by >= 8 bytes.
void checkBagLengths(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return;  // rosbag reports it
  in.seekg(0, std::ios::end);
  const std::uint64_t file_size = static_cast<std::uint64_t>(in.tellg());
  in.seekg(0);
  std::string magic(13, '\0');
  in.read(&magic[0], 13);
  // rosbag reads on after a damaged first line; only format 2.0 is read here.
  if (!in || magic != "#ROSBAG V2.0\n")
    throw std::invalid_argument(where(path) +
                                "not a ROS bag of format 2.0 (its first line is not "
                                "'#ROSBAG V2.0')");
  std::uint64_t pos = 13;
  const std::function<void(const std::string&)> refuse = [&](const std::string& what) {
    throw std::invalid_argument(where(path) + "corrupt record at byte " + std::to_string(pos) +
                                ": " + what);
  };
  unsigned char len4[4];
  BagScan scan;
  while (pos < file_size) {
    if (file_size - pos < 8) refuse("record cut off");
    in.read(reinterpret_cast<char*>(len4), 4);
    const std::uint64_t header_len = u32(len4);
    if (pos + 8 + header_len > file_size) refuse("header length beyond the end of the file");
    const std::string header = readBytes(in, header_len);
    in.read(reinterpret_cast<char*>(len4), 4);
    const std::uint64_t data_len = u32(len4);
    if (pos + 8 + header_len + data_len > file_size)
      refuse("data length beyond the end of the file");
    RecordHeader h;
    if (!parseHeader(header, &h)) refuse("header field beyond its header");
    scan.record_starts.insert(pos);
    checkRecordData(in, h, data_len, refuse, &scan);
    pos += 8 + header_len + data_len;
    in.seekg(static_cast<std::streamoff>(pos));
  }
  pos = 13;  // the cross-reference messages name the bag header's record
  checkCrossReferences(scan, refuse);
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
         rosbag::View(bag, rosbag::TypeQuery("threshing_sim/FeedRateCommand"))) {
      const auto c = instantiate<FeedRateCommand>(path, m, n);
      const long step = stepOf(path, c->header.stamp.toNSec(), dt_ns);
      // The live topic's first test (the pool's is the node's, at the boundary).
      if (!std::isfinite(c->rate_per_s) || c->rate_per_s < 0 || c->rate_per_s > 1e6) {
        char text[160];
        std::snprintf(text, sizeof(text),
                      "feed rate command %zu at %s: rate %g 1/s is not in [0, 1e6]", n,
                      stampText(c->header.stamp.toNSec()).c_str(), c->rate_per_s);
        throw std::invalid_argument(where(path) + text);
      }
      out.feed_commands.push_back({step, c->rate_per_s});
      ++n;
    }
    std::stable_sort(
        out.feed_commands.begin(), out.feed_commands.end(),
        [](const BagFeedCommand& a, const BagFeedCommand& b) { return a.step < b.step; });
    n = 0;
    for (const rosbag::MessageInstance& m :
         rosbag::View(bag, rosbag::TypeQuery("threshing_sim/ContactStateArray"))) {
      const auto c = instantiate<ContactStateArray>(path, m, n++);
      out.last_contact_step =
          std::max(out.last_contact_step, stepOf(path, c->header.stamp.toNSec(), dt_ns));
    }
  } catch (const std::invalid_argument&) {
    throw;  // this reader's own refusals, which name ~command_bag already
  } catch (const rosbag::BagException& e) {
    throw std::invalid_argument(where(path) + e.what());
  } catch (const ros::Exception& e) {
    throw std::invalid_argument(where(path) + "unreadable: " + e.what());
  } catch (const std::bad_alloc&) {
    throw std::invalid_argument(where(path) +
                                "unreadable: a record claims more memory than "
                                "there is (corrupt lengths)");
  } catch (const std::exception& e) {
    // rosbag lets other exceptions through, e.g. ros::normalizeSecNSec's std::runtime_error
    // ("Time is out of dual 32-bit range") on a corrupt index stamp (fuzz_command_bag).
    throw std::invalid_argument(where(path) + "unreadable: " + e.what());
  }
  return out;
}

}  // namespace threshing_sim
