// Helpers shared by the rostests: a node's process id, whether a process has ended, a shell
// command's exit status and output, subscriptions whose callbacks run under a test's lock, a
// bounded wait for a condition under that lock, and a roslaunch in the background.
#pragma once

#include <ros/master.h>
#include <ros/network.h>
#include <ros/ros.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>
#include <xmlrpcpp/XmlRpc.h>

#include <array>
#include <cstdint>
#include <cstdio>
#include <fstream>
#include <functional>
#include <mutex>
#include <string>

namespace threshing_sim {
namespace test {

// The process id of a ROS node, asked over its XML-RPC API (getPid); -1 if it does not answer.
inline int pidOf(const std::string& node) {
  XmlRpc::XmlRpcValue args, result, payload;
  args[0] = ros::this_node::getName();
  args[1] = node;
  if (!ros::master::execute("lookupNode", args, result, payload, false)) return -1;
  std::string host;
  std::uint32_t port = 0;
  if (!ros::network::splitURI(static_cast<std::string>(payload), host, port)) return -1;
  XmlRpc::XmlRpcClient client(host.c_str(), static_cast<int>(port), "/");
  XmlRpc::XmlRpcValue pid_args, pid_result;
  pid_args[0] = ros::this_node::getName();
  if (!client.execute("getPid", pid_args, pid_result) || pid_result.size() < 3) return -1;
  return static_cast<int>(pid_result[2]);
}

// A process gone (or a zombie waiting for its parent to reap it).
inline bool processEnded(int pid) {
  std::ifstream stat("/proc/" + std::to_string(pid) + "/stat");
  std::string pid_field, comm, state;
  if (!(stat >> pid_field >> comm >> state)) return true;
  return state == "Z" || state == "X";
}

// Runs a shell command; its exit status, and its merged stdout and stderr in *output.
inline int run(const std::string& cmd, std::string* output) {
  FILE* pipe = popen((cmd + " 2>&1").c_str(), "r");
  if (!pipe) return -1;
  std::array<char, 4096> buf;
  size_t n;
  while ((n = fread(buf.data(), 1, buf.size(), pipe)) > 0) output->append(buf.data(), n);
  const int status = pclose(pipe);
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

// Waits (wall time) until pred() holds under mutex, looking every poll_s, or until timeout_s
// passes; whether it held.
inline bool waitUnder(std::mutex& mutex, const std::function<bool()>& pred, double timeout_s,
                      double poll_s) {
  const ros::WallTime end = ros::WallTime::now() + ros::WallDuration(timeout_s);
  while (ros::WallTime::now() < end) {
    {
      std::lock_guard<std::mutex> lock(mutex);
      if (pred()) return true;
    }
    ros::WallDuration(poll_s).sleep();
  }
  return false;
}

// Subscribes f to topic (queue messages deep); f runs under mutex.
template <typename M>
ros::Subscriber listenUnder(ros::NodeHandle* nh, std::mutex& mutex, const std::string& topic,
                            std::uint32_t queue, const std::function<void(const M&)>& f) {
  return nh->subscribe<M>(topic, queue,
                          boost::function<void(const typename M::ConstPtr&)>(
                              [f, &mutex](const typename M::ConstPtr& m) {
                                std::lock_guard<std::mutex> lock(mutex);
                                f(*m);
                              }));
}

// A roslaunch in the background (its output to log_path), in its own process group; one still
// running when the test ends (a failed assertion) is interrupted.
class Launch {
 public:
  Launch(const std::string& log_path, const std::string& args) {
    pid_ = fork();
    if (pid_ == 0) {
      setpgid(0, 0);
      const std::string cmd = "exec roslaunch " + args + " > " + log_path + " 2>&1";
      execl("/bin/sh", "sh", "-c", cmd.c_str(), static_cast<char*>(nullptr));
      _exit(127);
    }
  }
  ~Launch() {
    if (running()) stop();
  }
  Launch(const Launch&) = delete;
  Launch& operator=(const Launch&) = delete;
  bool running() {
    if (exited_) return false;
    int status = 0;
    if (waitpid(pid_, &status, WNOHANG) == 0) return true;
    exited_ = true;
    exit_status_ = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
    return false;
  }
  // Exit status, or -1 if it had to be interrupted after timeout_s.
  int wait(double timeout_s) {
    const ros::WallTime end = ros::WallTime::now() + ros::WallDuration(timeout_s);
    while (running()) {
      if (ros::WallTime::now() > end) {
        stop();
        return -1;
      }
      ros::WallDuration(0.05).sleep();
    }
    return exit_status_;
  }

 private:
  // SIGINT to the whole group (roslaunch and its nodes), as Ctrl-C would.
  void stop() {
    kill(-pid_, SIGINT);
    waitpid(pid_, nullptr, 0);
    exited_ = true;
  }

  pid_t pid_ = -1;
  bool exited_ = false;
  int exit_status_ = -1;
};

}  // namespace test
}  // namespace threshing_sim
