// drum_cmd_flood: publishes std_msgs/Float64 drum speed commands at a fixed rate for a fixed
// wall time, half of them NaN, inf or too fast (1e4 rad/s), and prints what it sent. The
// soak script (scripts/soak.sh) floods a running node with it and compares the node's count of
// rejected commands with the invalid ones sent. Python's publisher cannot reach 10 kHz on a
// loaded machine; this one sends in bursts of 1 ms, each burst its share of the rate.
//   drum_cmd_flood [RATE_HZ=10000] [SECONDS=3] [TOPIC=/drum_speed_cmd]
#include <ros/ros.h>
#include <std_msgs/Float64.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <string>

namespace {

// Reads argv[i] as a number in [lo, hi], or exits 2 naming it.
double argument(int argc, char** argv, int i, double fallback, double lo, double hi,
                const char* name) {
  if (argc <= i) return fallback;
  char* end = nullptr;
  const double v = std::strtod(argv[i], &end);
  if (end == argv[i] || *end != '\0' || !(v >= lo && v <= hi)) {
    std::fprintf(stderr, "drum_cmd_flood: %s must be a number in [%g, %g] (got '%s')\n", name, lo,
                 hi, argv[i]);
    std::exit(2);
  }
  return v;
}

}  // namespace

int main(int argc, char** argv) {
  ros::init(argc, argv, "drum_cmd_flood", ros::init_options::AnonymousName);
  const double rate_hz = argument(argc, argv, 1, 1e4, 1.0, 1e6, "RATE_HZ");
  const double duration_s = argument(argc, argv, 2, 3.0, 0.01, 3600.0, "SECONDS");
  const std::string topic = argc > 3 ? argv[3] : "/drum_speed_cmd";
  ros::NodeHandle nh;
  ros::Publisher pub = nh.advertise<std_msgs::Float64>(topic, 10000);
  // Wait (bounded) for the node to connect, so that the first commands are not lost.
  const ros::WallTime connect_end = ros::WallTime::now() + ros::WallDuration(10.0);
  while (pub.getNumSubscribers() == 0 && ros::WallTime::now() < connect_end)
    ros::WallDuration(0.01).sleep();
  if (pub.getNumSubscribers() == 0) {
    std::fprintf(stderr, "drum_cmd_flood: nobody subscribes to %s after 10 s\n", topic.c_str());
    return 1;
  }
  const double values[6] = {80.0, std::numeric_limits<double>::quiet_NaN(),
                            90.0, std::numeric_limits<double>::infinity(),
                            1e4,  85.0};
  const ros::WallDuration burst(1e-3);
  const ros::WallTime start = ros::WallTime::now();
  ros::WallTime next = start;
  long sent = 0, invalid = 0;
  const long total = std::lround(rate_hz * duration_s);
  while (sent < total) {
    // This burst brings the count up to the rate times the time elapsed since the start.
    const double elapsed_s = (next - start).toSec() + burst.toSec();
    const long due = std::min(total, static_cast<long>(rate_hz * elapsed_s));
    for (; sent < due; ++sent) {
      std_msgs::Float64 msg;
      msg.data = values[sent % 6];
      if (!std::isfinite(msg.data) || std::abs(msg.data) > 400.0) ++invalid;
      pub.publish(msg);
    }
    next += burst;
    const ros::WallDuration wait = next - ros::WallTime::now();
    if (wait > ros::WallDuration(0)) wait.sleep();
  }
  const double wall_s = (ros::WallTime::now() - start).toSec();
  ros::WallDuration(0.5).sleep();  // let the transport flush
  std::printf("flood: %ld commands in %.3f s (%.0f Hz), %ld invalid (NaN, inf or 1e4 rad/s)\n",
              sent, wall_s, sent / wall_s, invalid);
  return 0;
}
