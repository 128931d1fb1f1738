// The ~command_bag reader (issue 14, defects 2 and 3, and the off-grid stamp of defect 7): real
// bags written with rosbag, good and hostile. Every refusal is a std::invalid_argument naming
// ~command_bag; before, a foreign definition dereferenced a null message (SIGSEGV), a short
// record threw StreamOverrunException out of the node (abort), and NaN, inf and too-fast speeds
// were applied silently.
#include <gtest/gtest.h>
#include <ros/serialization.h>
#include <rosbag/bag.h>
#include <topic_tools/shape_shifter.h>

#include <cmath>
#include <filesystem>
#include <limits>
#include <string>
#include <vector>

#include "threshing_sim/ContactStateArray.h"
#include "threshing_sim/DrumSpeedCommand.h"
#include "threshing_sim/ros/command_bag.h"

namespace threshing_sim {
namespace {

constexpr std::int64_t kDtNs = 10000;  // physics step 1e-5 s
constexpr double kMaxSpeed = 400.0;    // ~max_drum_speed default [rad/s]

std::string bagPath(const std::string& name) {
  return (std::filesystem::temp_directory_path() / ("command_bag_" + name + ".bag")).string();
}

DrumSpeedCommand command(std::uint64_t stamp_ns, double speed) {
  DrumSpeedCommand c;
  c.header.stamp.fromNSec(stamp_ns);
  c.speed = speed;
  return c;
}

ContactStateArray contactState(std::uint64_t stamp_ns) {
  ContactStateArray c;
  c.header.stamp.fromNSec(stamp_ns);
  return c;
}

template <class M>
std::vector<std::uint8_t> bytesOf(const M& msg) {
  std::vector<std::uint8_t> buf(ros::serialization::serializationLength(msg));
  ros::serialization::OStream out(buf.data(), static_cast<std::uint32_t>(buf.size()));
  ros::serialization::serialize(out, msg);
  return buf;
}

// A raw record of type datatype with the given md5sum and bytes.
topic_tools::ShapeShifter raw(const std::string& datatype, const std::string& md5,
                              const std::string& definition, std::vector<std::uint8_t> bytes) {
  topic_tools::ShapeShifter s;
  s.morph(md5, datatype, definition, "");
  ros::serialization::IStream in(bytes.data(), static_cast<std::uint32_t>(bytes.size()));
  s.read(in);
  return s;
}

// The refusal message of reading path ("" if it reads).
std::string refusal(const std::string& path) {
  try {
    readCommandBag(path, kDtNs, kMaxSpeed);
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "";
}

TEST(CommandBag, ReadsCommandsInBoundaryOrderAndTheLastContactState) {
  const std::string path = bagPath("good");
  {
    rosbag::Bag bag(path, rosbag::bagmode::Write);
    bag.write("drum_speed_cmd_applied", ros::Time(1), command(50000, 120.0));
    bag.write("drum_speed_cmd_applied", ros::Time(1), command(20000, -90.0));
    bag.write("contact_state", ros::Time(1), contactState(70000));
  }
  const CommandBagContents c = readCommandBag(path, kDtNs, kMaxSpeed);
  ASSERT_EQ(c.commands.size(), 2u);
  EXPECT_EQ(c.commands[0].step, 2);
  EXPECT_EQ(c.commands[0].speed_radps, -90.0);
  EXPECT_EQ(c.commands[1].step, 5);
  EXPECT_EQ(c.last_contact_step, 7);
}

TEST(CommandBag, ForeignDefinitionIsRefusedNotDereferenced) {
  const std::string path = bagPath("foreign");
  {
    rosbag::Bag bag(path, rosbag::bagmode::Write);
    bag.write("drum_speed_cmd_applied", ros::Time(1),
              raw("threshing_sim/DrumSpeedCommand", "0123456789abcdef0123456789abcdef",
                  "float64 speed\n", bytesOf(command(10000, 1.0))));
  }
  const std::string message = refusal(path);
  EXPECT_NE(message.find("~command_bag (" + path + ")"), std::string::npos) << message;
  EXPECT_NE(message.find("md5sum 0123456789abcdef0123456789abcdef"), std::string::npos) << message;
}

TEST(CommandBag, ShortRecordsAreRefusedNotThrownOut) {
  const auto md5 = [](auto* msg) { return std::string(ros::message_traits::md5sum(*msg)); };
  DrumSpeedCommand cmd = command(10000, 1.0);
  ContactStateArray cs = contactState(10000);
  for (const bool contact : {false, true}) {
    const std::string path = bagPath(contact ? "short_contact" : "short_command");
    {
      rosbag::Bag bag(path, rosbag::bagmode::Write);
      if (contact) {
        bag.write("drum_speed_cmd_applied", ros::Time(1), cmd);
        bag.write("contact_state", ros::Time(1),
                  raw("threshing_sim/ContactStateArray", md5(&cs),
                      ros::message_traits::definition(cs), {1, 2, 3, 4, 5}));
      } else {
        bag.write("drum_speed_cmd_applied", ros::Time(1),
                  raw("threshing_sim/DrumSpeedCommand", md5(&cmd),
                      ros::message_traits::definition(cmd), {1, 2, 3}));
      }
    }
    const std::string message = refusal(path);
    EXPECT_NE(message.find("~command_bag (" + path + ")"), std::string::npos) << message;
    EXPECT_NE(message.find("malformed"), std::string::npos) << message;
  }
}

TEST(CommandBag, SpeedsAreValidatedLikeTheLiveTopic) {
  const double kInf = std::numeric_limits<double>::infinity();
  for (const double speed : {std::nan(""), kInf, -kInf, 1e308, 1e4, -400.5}) {
    const std::string path = bagPath("speed");
    {
      rosbag::Bag bag(path, rosbag::bagmode::Write);
      bag.write("drum_speed_cmd_applied", ros::Time(1), command(10000, speed));
    }
    const std::string message = refusal(path);
    EXPECT_NE(message.find("~max_drum_speed = 400"), std::string::npos) << speed << ": " << message;
  }
  // The limit itself is accepted, as on the topic.
  const std::string path = bagPath("speed_ok");
  {
    rosbag::Bag bag(path, rosbag::bagmode::Write);
    bag.write("drum_speed_cmd_applied", ros::Time(1), command(10000, -400.0));
    bag.write("contact_state", ros::Time(1), contactState(10000));
  }
  EXPECT_EQ(refusal(path), "");
}

// An off-grid stamp is printed to the nanosecond (it looked on the grid at 6 decimals).
TEST(CommandBag, OffGridStampIsPrintedExactly) {
  const std::string path = bagPath("offgrid");
  {
    rosbag::Bag bag(path, rosbag::bagmode::Write);
    bag.write("drum_speed_cmd_applied", ros::Time(1), command(10500, 1.0));
  }
  const std::string message = refusal(path);
  EXPECT_NE(message.find("stamp 0.000010500 s is not on this node's step grid of 0.000010000 s"),
            std::string::npos)
      << message;
}

// Found by fuzz_command_bag: a record whose chunk declares 2.3 GB made rosbag allocate it
// (out of memory under the fuzzer, bad_alloc or swapping without). Refused before rosbag reads.
TEST(CommandBag, CorruptChunkSizeIsRefusedBeforeRosbagAllocatesIt) {
  const std::string path = std::string(THRESHING_SIM_SOURCE_DIR) +
                           "/test/fuzz/corpus/fuzz_command_bag/oom_chunk_size.bag";
  const std::string message = refusal(path);
  EXPECT_NE(message.find("~command_bag (" + path + "): corrupt record"), std::string::npos)
      << message;
}

// Found by fuzz_command_bag: a message record inside a chunk whose header field length runs past
// its buffer made ros::Header::parse copy past the heap block (ASan heap-buffer-overflow).
TEST(CommandBag, CorruptRecordInsideAChunkIsRefused) {
  const std::string path = std::string(THRESHING_SIM_SOURCE_DIR) +
                           "/test/fuzz/corpus/fuzz_command_bag/overflow_chunk_record.bag";
  const std::string message = refusal(path);
  EXPECT_NE(message.find("~command_bag (" + path + "): corrupt record"), std::string::npos)
      << message;
}

// Found by fuzz_command_bag: rosbag reads a bag whose first line is damaged ("#ROSBA  V2.0"),
// then takes a run of padding spaces for a 0.5-2.3 GB header length and allocates it.
TEST(CommandBag, DamagedFirstLineIsRefused) {
  const std::string path = std::string(THRESHING_SIM_SOURCE_DIR) +
                           "/test/fuzz/corpus/fuzz_command_bag/oom_damaged_first_line.bag";
  const std::string message = refusal(path);
  EXPECT_NE(message.find("~command_bag (" + path + "): not a ROS bag of format 2.0"),
            std::string::npos)
      << message;
}

// Found by fuzz_command_bag: a connection record whose data (itself a header) has a field length
// past its end made ros::Header::parse copy past the heap block.
TEST(CommandBag, CorruptConnectionHeaderIsRefused) {
  const std::string path = std::string(THRESHING_SIM_SOURCE_DIR) +
                           "/test/fuzz/corpus/fuzz_command_bag/overflow_connection_header.bag";
  const std::string message = refusal(path);
  EXPECT_NE(message.find("~command_bag (" + path + "): corrupt record"), std::string::npos)
      << message;
}

// Found by fuzz_command_bag (the 1e6-input run): an index record declaring 47 entries with the
// data of one made rosbag read 46 offsets from beyond the record, then a message header at one
// of them (SEGV in rosbag::Bag::readHeaderFromBuffer). Every index record's and chunk info's
// count must now match its data, and every indexed connection must be defined.
TEST(CommandBag, IndexCountBeyondItsDataIsRefused) {
  const std::string path = std::string(THRESHING_SIM_SOURCE_DIR) +
                           "/test/fuzz/corpus/fuzz_command_bag/overread_index_count.bag";
  const std::string message = refusal(path);
  EXPECT_NE(message.find("~command_bag (" + path +
                         "): corrupt record at byte 9206: index "
                         "record declares 47 entries for 12 bytes of data"),
            std::string::npos)
      << message;
}

// Found by fuzz_command_bag: an index entry's stamp beyond 32-bit seconds made rosbag throw
// std::runtime_error ("Time is out of dual 32-bit range"), which nothing caught: abort.
TEST(CommandBag, StampOutOfRangeIsRefusedNotThrownOut) {
  const std::string path = std::string(THRESHING_SIM_SOURCE_DIR) +
                           "/test/fuzz/corpus/fuzz_command_bag/throw_index_stamp.bag";
  const std::string message = refusal(path);
  EXPECT_NE(message.find("~command_bag (" + path + "): unreadable: Time is out of dual 32-bit"),
            std::string::npos)
      << message;
}

// Found by fuzz_command_bag (scripts/test.sh's 30 s run): an index record whose stamp's
// nanoseconds overflow made ros::Time throw a plain std::runtime_error from rosbag::Bag::open,
// which ended the process (std::terminate). It is now a refusal naming the bag.
TEST(CommandBag, IndexStampOutOfRangeIsRefused) {
  const std::string path = std::string(THRESHING_SIM_SOURCE_DIR) +
                           "/test/fuzz/corpus/fuzz_command_bag/time_out_of_range_index.bag";
  const std::string message = refusal(path);
  EXPECT_NE(
      message.find("~command_bag (" + path + "): unreadable: Time is out of dual 32-bit range"),
      std::string::npos)
      << message;
}

TEST(CommandBag, MissingAndNonBagFilesAreRefused) {
  EXPECT_NE(refusal("/nonexistent/x.bag").find("~command_bag (/nonexistent/x.bag)"),
            std::string::npos);
  EXPECT_NE(refusal(std::filesystem::temp_directory_path().string()).find("~command_bag"),
            std::string::npos);
}

}  // namespace
}  // namespace threshing_sim
