// rostests rviz*.test: demo.launch with rviz under Xvfb and the view scene_rviz frames on the
// scene. Each .test runs one of the two tests (--gtest_filter):
//  - ScreenshotShowsTheContact (rviz.test, view:=contact): the paused demo runs into its first
//  contact and
//    is paused there; the screenshot must show the kernel, the tooth and the contact force arrow
//    in their marker colours;
//  - ScreenshotShowsTheScene (rviz_default/stream/knead.test, the whole-scene view): with
//  run_to_strike the
//    demo runs until the first strike_history and is paused, else it stays paused at t = 0; the
//    screenshot must show the whole drum rim inside the render area and at least 90 % of the
//    kernels (connected blobs in a kernel colour), and after a strike the strike chart's curve;
//    with run_to_retired (rviz_feed.test, the feed scene) the demo runs until feed_throughput
//    reports that many kernels retired, the overlay then showing the running fractions;
//  - ScreenshotShowsPausedThenFailed (rviz_status.test, a scene beyond the work budget, started
//    paused): the overlay and the status markers say PAUSED (sky blue), then, run, FAILED with
//    the integrator's cause (red), each agreeing with /diagnostics; screenshots of both;
//  - ScreenshotShowsTheSlowPace (rviz_slow.test, a pace the machine cannot hold): the overlay
//    and the status markers say SLOW in the warning colour (amber) while /diagnostics warns.
#include <diagnostic_msgs/DiagnosticArray.h>
#include <gtest/gtest.h>
#include <ros/master.h>
#include <ros/ros.h>
#include <std_msgs/Float64MultiArray.h>
#include <std_srvs/SetBool.h>
#include <visualization_msgs/MarkerArray.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <string>
#include <vector>

#include "threshing_sim/FeedThroughput.h"
#include "threshing_sim/KernelStateArray.h"
#include "threshing_sim/StrikeHistory.h"

namespace {

// Whether node `node` subscribes to `topic`, from the master's system state.
bool subscribes(const std::string& node, const std::string& topic) {
  XmlRpc::XmlRpcValue args, result, payload;
  args[0] = ros::this_node::getName();
  if (!ros::master::execute("getSystemState", args, result, payload, true)) return false;
  XmlRpc::XmlRpcValue& subscribers = payload[1];
  for (int i = 0; i < subscribers.size(); ++i) {
    if (static_cast<std::string>(subscribers[i][0]) != topic) continue;
    for (int j = 0; j < subscribers[i][1].size(); ++j)
      if (static_cast<std::string>(subscribers[i][1][j]) == node) return true;
  }
  return false;
}

struct Image {
  int width = 0, height = 0;
  std::vector<unsigned char> rgb;  // row-major, 3 bytes per pixel
};

// Reads a binary PPM (P6, maxval 255) as ImageMagick writes it.
Image readPpm(const std::string& path) {
  Image img;
  std::ifstream in(path, std::ios::binary);
  std::string magic;
  int maxval = 0;
  in >> magic >> img.width >> img.height >> maxval;
  in.get();
  if (magic != "P6" || maxval != 255) return Image();
  img.rgb.resize(3 * img.width * img.height);
  in.read(reinterpret_cast<char*>(img.rgb.data()), img.rgb.size());
  return img;
}

// Pixels whose colour passes `match(r, g, b)`.
template <typename Match>
long count(const Image& img, Match match) {
  long n = 0;
  for (size_t i = 0; i + 2 < img.rgb.size(); i += 3)
    n += match(img.rgb[i], img.rgb[i + 1], img.rgb[i + 2]) ? 1 : 0;
  return n;
}

// Screenshot of the whole display into png, read back as an Image.
Image screenshot(const std::string& display, const std::string& png) {
  const std::string ppm = png + ".ppm";
  std::filesystem::create_directories(std::filesystem::path(png).parent_path());
  if (std::system(("import -display " + display + " -window root " + png).c_str()) != 0 ||
      std::system(("convert " + png + " " + ppm).c_str()) != 0)
    return Image();
  const Image img = readPpm(ppm);
  std::remove(ppm.c_str());
  return img;
}

struct Box {
  int x0 = 1 << 30, y0 = 1 << 30, x1 = -1, y1 = -1;
  void add(int x, int y) {
    x0 = std::min(x0, x), y0 = std::min(y0, y), x1 = std::max(x1, x), y1 = std::max(y1, y);
  }
  bool empty() const { return x1 < x0; }
};

template <typename Match>
Box boxOf(const Image& img, const Box& within, Match match) {
  Box b;
  for (int y = std::max(0, within.y0); y <= std::min(img.height - 1, within.y1); ++y)
    for (int x = std::max(0, within.x0); x <= std::min(img.width - 1, within.x1); ++x) {
      const unsigned char* p = &img.rgb[3 * (y * img.width + x)];
      if (match(p[0], p[1], p[2])) b.add(x, y);
    }
  return b;
}

// Connected blobs (8-neighbourhood) of matching pixels inside `within`: (size, box) each.
template <typename Match>
std::vector<std::pair<int, Box>> blobList(const Image& img, const Box& within, Match match) {
  std::vector<char> seen(img.width * img.height, 0);
  std::vector<std::pair<int, Box>> out;
  for (int y = within.y0; y <= within.y1; ++y)
    for (int x = within.x0; x <= within.x1; ++x) {
      const int i = y * img.width + x;
      const unsigned char* p = &img.rgb[3 * i];
      if (seen[i] || !match(p[0], p[1], p[2])) continue;
      std::pair<int, Box> blob(0, Box());
      std::vector<int> stack = {i};
      seen[i] = 1;
      while (!stack.empty()) {
        const int j = stack.back();
        stack.pop_back();
        const int jx = j % img.width, jy = j / img.width;
        ++blob.first;
        blob.second.add(jx, jy);
        for (int dy = -1; dy <= 1; ++dy)
          for (int dx = -1; dx <= 1; ++dx) {
            const int kx = jx + dx, ky = jy + dy;
            if (kx < within.x0 || kx > within.x1 || ky < within.y0 || ky > within.y1) continue;
            const int k = ky * img.width + kx;
            const unsigned char* q = &img.rgb[3 * k];
            if (!seen[k] && match(q[0], q[1], q[2])) {
              seen[k] = 1;
              stack.push_back(k);
            }
          }
      }
      out.push_back(blob);
    }
  return out;
}

// Number of blobs of at least min_px pixels.
template <typename Match>
int blobs(const Image& img, const Box& within, int min_px, Match match) {
  int n = 0;
  for (const auto& b : blobList(img, within, match)) n += b.first >= min_px ? 1 : 0;
  return n;
}

bool near(int v, int target, int tol) { return std::abs(v - target) <= tol; }

// The longest run of indices whose fraction of dark pixels is at least 0.6.
template <typename DarkAt>
std::pair<int, int> darkRun(int n, int m, DarkAt dark) {
  int best0 = 0, best1 = -1, start = -1;
  for (int i = 0; i <= n; ++i) {
    int d = 0;
    for (int j = 0; i < n && j < m; ++j) d += dark(i, j) ? 1 : 0;
    const bool in = i < n && d >= 0.6 * m;
    if (in && start < 0) start = i;
    if (!in && start >= 0) {
      if (i - 1 - start > best1 - best0) best0 = start, best1 = i - 1;
      start = -1;
    }
  }
  return {best0, best1};
}

// rviz's render area: the columns, then the rows, that are mostly dark (rviz's background and
// grid against the light panels around it).
Box renderArea(const Image& img) {
  auto dark = [&](int x, int y) {
    const unsigned char* p = &img.rgb[3 * (y * img.width + x)];
    return std::max({p[0], p[1], p[2]}) < 160;  // grid lines reach 140
  };
  const auto cols = darkRun(img.width, img.height, [&](int x, int y) { return dark(x, y); });
  const int w = cols.second - cols.first + 1;
  const auto rows = darkRun(img.height, w, [&](int y, int j) { return dark(cols.first + j, y); });
  Box b;
  b.add(cols.first, rows.first);
  b.add(cols.second, rows.second);
  return b;
}

// Kernel colours (messages.cc): gold (free), green (on its pedicel), pink (damaged).
bool kernelColour(int r, int g, int b) {
  const bool gold = r > 230 && g > 180 && g < 215 && b < 50;
  const bool green = near(r, 89, 20) && near(g, 217, 20) && near(b, 89, 20);
  const bool pink = r > 230 && near(g, 89, 20) && near(b, 153, 20);
  return gold || green || pink;
}

void waitForRviz() {
  const ros::WallTime end = ros::WallTime::now() + ros::WallDuration(60);
  while (!subscribes("/rviz", "/markers") && ros::WallTime::now() < end)
    ros::WallDuration(0.2).sleep();
  ASSERT_TRUE(subscribes("/rviz", "/markers")) << "rviz did not come up";
  ros::WallDuration(3.0).sleep();
}

void pause(bool on) {
  std_srvs::SetBool srv;
  srv.request.data = on;
  ASSERT_TRUE(ros::service::waitForService("/threshing_sim_node/pause", ros::Duration(10)));
  ASSERT_TRUE(ros::service::call("/threshing_sim_node/pause", srv));
}

// The whole-scene view: every point of the drum rim drawn inside the render area, >= 90 % of
// the kernels seen where kernel_states puts them, and (after a strike) the strike chart's curve.
// World -> pixel as scene_rviz sets up the camera: the top-down view centred on the view box's
// centre at the render area's centre, its scale fitted into a 1050 x 760 px render area.
TEST(Rviz, ScreenshotShowsTheScene) {
  ros::NodeHandle nh, pnh("~");
  const std::string display = pnh.param<std::string>("display", ":97");
  const std::string png =
      std::string(SCREENSHOT_DIR) + "/" + pnh.param<std::string>("png", "x.png");
  const bool run_to_strike = pnh.param("run_to_strike", false);
  const int run_to_retired = pnh.param("run_to_retired", 0);

  std::mutex mutex;
  std::atomic<long> retired{0};
  ros::Subscriber ft = nh.subscribe<threshing_sim::FeedThroughput>(
      "/feed_throughput", 10,
      boost::function<void(const threshing_sim::FeedThroughput::ConstPtr&)>(
          [&](const threshing_sim::FeedThroughput::ConstPtr& m) {
            retired = m->total_fed - m->in_drum;
          }));
  threshing_sim::KernelStateArray kernels;
  std::vector<double> box;
  std::vector<geometry_msgs::Point> rim_W;
  std::atomic<bool> struck{false};
  ros::Subscriber ks = nh.subscribe<threshing_sim::KernelStateArray>(
      "/kernel_states", 10,
      boost::function<void(const threshing_sim::KernelStateArray::ConstPtr&)>(
          [&](const threshing_sim::KernelStateArray::ConstPtr& m) {
            std::lock_guard<std::mutex> lock(mutex);
            kernels = *m;
          }));
  ros::Subscriber vb = nh.subscribe<std_msgs::Float64MultiArray>(
      "/view_box", 1,
      boost::function<void(const std_msgs::Float64MultiArray::ConstPtr&)>(
          [&](const std_msgs::Float64MultiArray::ConstPtr& m) {
            std::lock_guard<std::mutex> lock(mutex);
            box = m->data;
          }));
  ros::Subscriber sm = nh.subscribe<visualization_msgs::MarkerArray>(
      "/static_markers", 1,
      boost::function<void(const visualization_msgs::MarkerArray::ConstPtr&)>(
          [&](const visualization_msgs::MarkerArray::ConstPtr& m) {
            std::lock_guard<std::mutex> lock(mutex);
            for (const auto& marker : m->markers)
              if (marker.ns == "drum") rim_W = marker.points;
          }));
  ros::Subscriber ss = nh.subscribe<threshing_sim::StrikeHistory>(
      "/strike_history", 10,
      boost::function<void(const threshing_sim::StrikeHistory::ConstPtr&)>(
          [&](const threshing_sim::StrikeHistory::ConstPtr&) { struck = true; }));
  waitForRviz();
  if (run_to_strike) {
    pause(false);
    const ros::WallTime end = ros::WallTime::now() + ros::WallDuration(40);
    while (!struck && ros::WallTime::now() < end) ros::WallDuration(1e-3).sleep();
    pause(true);
    ASSERT_TRUE(struck) << "no strike_history";
  }
  if (run_to_retired > 0) {
    pause(false);
    const ros::WallTime end = ros::WallTime::now() + ros::WallDuration(120);
    while (retired < run_to_retired && ros::WallTime::now() < end) ros::WallDuration(1e-3).sleep();
    pause(true);
    ASSERT_GE(retired, run_to_retired) << "too few kernels retired";
  }
  ros::WallDuration(1.5).sleep();  // rviz draws the last markers

  const Image img = screenshot(display, png);
  ASSERT_GT(img.width * img.height, 0);
  std::lock_guard<std::mutex> lock(mutex);
  ASSERT_EQ(box.size(), 4u) << "no view_box";
  ASSERT_FALSE(rim_W.empty()) << "no drum in static_markers";
  ASSERT_FALSE(kernels.kernels.empty()) << "no kernel_states";
  const Box render = renderArea(img);
  ASSERT_FALSE(render.empty());
  const double w_m = box[2] - box[0], h_m = box[3] - box[1];
  const double scale = 0.95 * std::min(1050 / w_m, 760 / h_m);  // as scene_rviz [px/m]
  const double cx_px = 0.5 * (render.x0 + render.x1), cy_px = 0.5 * (render.y0 + render.y1);
  auto pixel = [&](double x_m, double y_m) {
    return std::make_pair(
        static_cast<int>(std::lround(cx_px + (x_m - 0.5 * (box[0] + box[2])) * scale)),
        static_cast<int>(std::lround(cy_px - (y_m - 0.5 * (box[1] + box[3])) * scale)));
  };
  // Whether a pixel within r px of (x, y), inside the render area, passes match.
  auto seenNear = [&](std::pair<int, int> p, int r, auto match) {
    for (int y = std::max(render.y0, p.second - r); y <= std::min(render.y1, p.second + r); ++y)
      for (int x = std::max(render.x0, p.first - r); x <= std::min(render.x1, p.first + r); ++x) {
        const unsigned char* q = &img.rgb[3 * (y * img.width + x)];
        if (match(q[0], q[1], q[2])) return true;
      }
    return false;
  };
  int rim_points = 0, rim_inside = 0, rim_drawn = 0;
  for (size_t j = 0; j < rim_W.size(); j += 10) {
    const auto p = pixel(rim_W[j].x, rim_W[j].y);
    ++rim_points;
    const bool inside = p.first > render.x0 + 2 && p.first < render.x1 - 2 &&
                        p.second > render.y0 + 2 && p.second < render.y1 - 2;
    rim_inside += inside ? 1 : 0;
    // Drawn: the rim's grey (lit: 110..200) or a tooth's blue over it.
    rim_drawn += inside && seenNear(p, 3, [](int r, int g, int b) {
                   const bool grey = r >= 105 && r <= 200 && near(g, r, 10) && near(b, r, 10);
                   const bool blue = b > 200 && r < 120;
                   return grey || blue;
                 });
  }
  int kernels_seen = 0;
  for (const auto& k : kernels.kernels)
    kernels_seen += seenNear(pixel(k.pose.x, k.pose.y), 4, kernelColour) ? 1 : 0;
  const int n = static_cast<int>(kernels.kernels.size());
  const long chart = count(img, [](int r, int g, int b) {
    return r > 230 && near(g, 115, 25) && b < 30;  // the normal force curve, orange
  });
  std::printf(
      "screenshot %s: render area %dx%d px, %.0f px/m; drum rim: %d of %d points inside the view, "
      "%d drawn; %d of %d kernels seen; strike chart %ld px\n",
      png.c_str(), render.x1 - render.x0, render.y1 - render.y0, scale, rim_inside, rim_points,
      rim_drawn, kernels_seen, n, chart);
  EXPECT_EQ(rim_inside, rim_points) << "the drum is not wholly in view";
  EXPECT_GE(rim_drawn, 0.95 * rim_points) << "the drum rim is not drawn where expected";
  EXPECT_GE(kernels_seen, std::ceil(0.9 * n));
  if (run_to_strike) {
    EXPECT_GT(chart, 100) << "no strike chart";
  }
}

TEST(Rviz, ScreenshotShowsTheContact) {
  ros::NodeHandle nh, pnh("~");
  const std::string display = pnh.param<std::string>("display", ":97");
  const std::string png = std::string(SCREENSHOT_DIR) + "/rviz_screenshot.png";

  // rviz up and listening, then a few frames to settle.
  const ros::WallTime end = ros::WallTime::now() + ros::WallDuration(60);
  while (!subscribes("/rviz", "/markers") && ros::WallTime::now() < end)
    ros::WallDuration(0.2).sleep();
  ASSERT_TRUE(subscribes("/rviz", "/markers")) << "rviz did not come up";
  ros::WallDuration(3.0).sleep();

  // Run the demo into its first contact and pause it as soon as rviz has been sent a contact
  // force arrow at least 8 mm long (16 N at 0.5 mm/N; the peak is about 60 N).
  std::atomic<bool> touching{false};
  ros::Subscriber sub = nh.subscribe<visualization_msgs::MarkerArray>(
      "/markers", 10,
      boost::function<void(const visualization_msgs::MarkerArray::ConstPtr&)>(
          [&](const visualization_msgs::MarkerArray::ConstPtr& m) {
            for (const auto& marker : m->markers)
              if (marker.ns == "contact_forces" && marker.points.size() == 2 &&
                  std::hypot(marker.points[1].x - marker.points[0].x,
                             marker.points[1].y - marker.points[0].y) > 8e-3)
                touching = true;
          }));
  std_srvs::SetBool pause;
  ASSERT_TRUE(ros::service::waitForService("/threshing_sim_node/pause", ros::Duration(10)));
  pause.request.data = false;
  ASSERT_TRUE(ros::service::call("/threshing_sim_node/pause", pause));
  const ros::WallTime contact_end = ros::WallTime::now() + ros::WallDuration(30);
  while (!touching && ros::WallTime::now() < contact_end) ros::WallDuration(1e-3).sleep();
  pause.request.data = true;
  ASSERT_TRUE(ros::service::call("/threshing_sim_node/pause", pause));
  ASSERT_TRUE(touching) << "no contact";
  ros::WallDuration(1.0).sleep();  // rviz draws the last markers

  // Screenshot of the whole display, and a PPM copy to count colours in.
  const std::string ppm = png + ".ppm";
  std::filesystem::create_directories(std::filesystem::path(png).parent_path());
  ASSERT_EQ(std::system(("import -display " + display + " -window root " + png).c_str()), 0);
  ASSERT_EQ(std::system(("convert " + png + " " + ppm).c_str()), 0);
  const Image img = readPpm(ppm);
  std::remove(ppm.c_str());
  ASSERT_GT(img.width * img.height, 0);

  // Marker colours (messages.cc); flat faces keep them, rviz's lighting shades the arrows:
  // kernel gold (255, 199, 26), tooth blue (76, 153, 255), contact arrows orange (impact),
  // cyan (stick) or lime (slip) - none of them tf's red, green or blue axes.
  const long kernel =
      count(img, [](int r, int g, int b) { return r > 230 && g > 180 && g < 215 && b < 50; });
  const long tooth = count(img, [](int r, int g, int b) {
    return std::abs(r - 76) < 10 && std::abs(g - 153) < 10 && b > 240;
  });
  const long arrow = count(img, [](int r, int g, int b) {
    const bool orange = r > 120 && g > 0.3 * r && g < 0.6 * r && b < 0.2 * r;
    const bool cyan = g > 100 && b > 100 && r < 0.3 * g && std::abs(g - b) < 30;
    const bool lime = g > 120 && r > 0.55 * g && r < 0.85 * g && b < 0.2 * g;
    return orange || cyan || lime;
  });
  std::printf("screenshot %s: kernel %ld px, tooth %ld px, contact arrow %ld px\n", png.c_str(),
              kernel, tooth, arrow);
  EXPECT_GT(kernel, 50);
  EXPECT_GT(tooth, 1000);
  EXPECT_GT(arrow, 20);
}

// What the node shows of its state: the overlay and status markers on /markers and the
// /diagnostics summary.
struct StatusSeen {
  std::mutex mutex;
  std::string overlay, word;  // overlay text, the status word
  std::string cause;          // the status cause marker's text, its lines joined by spaces
  std_msgs::ColorRGBA overlay_color, word_color;  // their colours
  int frame_action = -1;                          // the status_frame marker's last action
  int level = -1;                                 // /diagnostics level of the simulation status
  std::string summary;                            // and its summary
  double sim_time_s = -1;                         // and its "simulation time [s]"
};

void watchStatus(ros::NodeHandle& nh, StatusSeen* seen, std::vector<ros::Subscriber>* subs) {
  subs->push_back(nh.subscribe<visualization_msgs::MarkerArray>(
      "/markers", 10,
      boost::function<void(const visualization_msgs::MarkerArray::ConstPtr&)>(
          [seen](const visualization_msgs::MarkerArray::ConstPtr& m) {
            std::lock_guard<std::mutex> lock(seen->mutex);
            for (const auto& marker : m->markers) {
              if (marker.ns == "overlay") {
                seen->overlay = marker.text;
                seen->overlay_color = marker.color;
              } else if (marker.ns == "status" && marker.id == 0) {
                seen->word = marker.action == visualization_msgs::Marker::ADD ? marker.text : "";
                seen->word_color = marker.color;
              } else if (marker.ns == "status" && marker.id == 1) {
                seen->cause = marker.action == visualization_msgs::Marker::ADD ? marker.text : "";
                std::replace(seen->cause.begin(), seen->cause.end(), '\n', ' ');
              } else if (marker.ns == "status_frame") {
                seen->frame_action = marker.action;
              }
            }
          })));
  subs->push_back(nh.subscribe<diagnostic_msgs::DiagnosticArray>(
      "/diagnostics", 100,
      boost::function<void(const diagnostic_msgs::DiagnosticArray::ConstPtr&)>(
          [seen](const diagnostic_msgs::DiagnosticArray::ConstPtr& m) {
            std::lock_guard<std::mutex> lock(seen->mutex);
            for (const auto& s : m->status) {
              if (s.name.find("simulation") == std::string::npos) continue;
              seen->level = s.level;
              seen->summary = s.message;
              for (const auto& kv : s.values)
                if (kv.key == "simulation time [s]") seen->sim_time_s = std::stod(kv.value);
            }
          })));
}

bool colourIs(const std_msgs::ColorRGBA& c, float r, float g, float b) {
  return std::abs(c.r - r) < 0.02 && std::abs(c.g - g) < 0.02 && std::abs(c.b - b) < 0.02;
}

std::string describe(const StatusSeen& s) {
  char c[120];
  std::snprintf(c, sizeof(c), "overlay colour (%.2f, %.2f, %.2f), status word '%s'",
                s.overlay_color.r, s.overlay_color.g, s.overlay_color.b, s.word.c_str());
  return "overlay:\n" + s.overlay + "\n" + c + "\nstatus cause: " + s.cause +
         "\n/diagnostics level " + std::to_string(s.level) + ": " + s.summary;
}

// Waits until pred(seen) holds (under its mutex), up to timeout_s of wall time.
template <typename Pred>
bool waitForStatus(StatusSeen* seen, double timeout_s, Pred pred) {
  const ros::WallTime end = ros::WallTime::now() + ros::WallDuration(timeout_s);
  while (ros::WallTime::now() < end) {
    {
      std::lock_guard<std::mutex> lock(seen->mutex);
      if (pred(*seen)) return true;
    }
    ros::WallDuration(0.05).sleep();
  }
  return false;
}

// The overlay's first line: the state, and the head of its cause (the whole cause is the
// status cause marker, the /diagnostics summary word for word).
std::string firstLine(const std::string& text) { return text.substr(0, text.find('\n')); }

// Status colours (messages.cc statusColor): paused sky blue (153, 204, 255), warning amber
// (255, 153, 0), error red (255, 38, 38); text and lines are drawn unlit.
bool skyBlue(int r, int g, int b) { return near(r, 153, 12) && near(g, 204, 12) && b > 240; }
bool amber(int r, int g, int b) { return r > 240 && near(g, 153, 12) && b < 30; }
bool red(int r, int g, int b) { return r > 235 && near(g, 38, 12) && near(b, 38, 12); }

TEST(Rviz, ScreenshotShowsPausedThenFailed) {
  ros::NodeHandle nh, pnh("~");
  const std::string display = pnh.param<std::string>("display", ":73");
  StatusSeen seen;
  std::vector<ros::Subscriber> subs;
  watchStatus(nh, &seen, &subs);
  waitForRviz();

  // Paused at start: PAUSED in sky blue on the overlay and the status markers, /diagnostics OK
  // with the cause the markers show.
  const bool paused = waitForStatus(&seen, 30.0, [](const StatusSeen& s) {
    return s.level == diagnostic_msgs::DiagnosticStatus::OK && !s.summary.empty() &&
           firstLine(s.overlay) == "PAUSED" && s.word == "PAUSED" && s.cause == s.summary;
  });
  {
    std::lock_guard<std::mutex> lock(seen.mutex);
    ASSERT_TRUE(paused) << describe(seen);
    EXPECT_NE(seen.summary.find("~pause"), std::string::npos) << seen.summary;
    EXPECT_TRUE(colourIs(seen.overlay_color, 0.6f, 0.8f, 1.f)) << describe(seen);
    EXPECT_TRUE(colourIs(seen.word_color, 0.6f, 0.8f, 1.f)) << describe(seen);
    EXPECT_EQ(seen.frame_action, visualization_msgs::Marker::DELETE) << "an alarm frame";
  }
  ros::WallDuration(1.5).sleep();  // rviz draws the last markers
  const std::string paused_png = std::string(SCREENSHOT_DIR) + "/rviz_paused.png";
  const Image paused_img = screenshot(display, paused_png);
  ASSERT_GT(paused_img.width * paused_img.height, 0);
  const long paused_blue = count(paused_img, skyBlue), paused_red = count(paused_img, red);
  std::printf("screenshot %s: sky blue (paused) %ld px, red %ld px\n", paused_png.c_str(),
              paused_blue, paused_red);
  EXPECT_GT(paused_blue, 500) << "no PAUSED status drawn";

  // Run: the first physics step exceeds the core's work budget. FAILED with the cause in red,
  // /diagnostics ERROR with the same summary.
  pause(false);
  const bool failed = waitForStatus(&seen, 90.0, [](const StatusSeen& s) {
    return s.level == diagnostic_msgs::DiagnosticStatus::ERROR && !s.summary.empty() &&
           firstLine(s.overlay) == "FAILED: integrator failed" && s.word == "FAILED" &&
           s.cause == s.summary;
  });
  {
    std::lock_guard<std::mutex> lock(seen.mutex);
    ASSERT_TRUE(failed) << describe(seen);
    EXPECT_NE(seen.cause.find("integrator failed (work budget exceeded"), std::string::npos)
        << describe(seen);
    EXPECT_NE(seen.cause.find("[work_budget]"), std::string::npos) << describe(seen);
    EXPECT_NE(seen.cause.find("call ~reset"), std::string::npos) << describe(seen);
    // The time the overlay shows is that of the state kept, as /diagnostics reports it.
    double overlay_t_s = -1;
    const size_t t_at = seen.overlay.find("\nt = ");
    ASSERT_NE(t_at, std::string::npos) << describe(seen);
    overlay_t_s = std::stod(seen.overlay.substr(t_at + 5));
    EXPECT_NEAR(overlay_t_s, seen.sim_time_s, 1e-6) << describe(seen);
    EXPECT_LT(overlay_t_s, 1e-4) << "the failed step's end, not the state kept";
    EXPECT_TRUE(colourIs(seen.overlay_color, 1.f, 0.15f, 0.15f)) << describe(seen);
    EXPECT_TRUE(colourIs(seen.word_color, 1.f, 0.15f, 0.15f)) << describe(seen);
    EXPECT_EQ(seen.frame_action, visualization_msgs::Marker::ADD) << "no alarm frame";
  }
  ros::WallDuration(2.5).sleep();  // the paused node republishes its markers once a second
  const std::string failed_png = std::string(SCREENSHOT_DIR) + "/rviz_failed.png";
  const Image failed_img = screenshot(display, failed_png);
  ASSERT_GT(failed_img.width * failed_img.height, 0);
  const long failed_red = count(failed_img, red), failed_blue = count(failed_img, skyBlue);
  std::printf("screenshot %s: red (failed) %ld px, sky blue %ld px\n", failed_png.c_str(),
              failed_red, failed_blue);
  EXPECT_GT(failed_red, paused_red + 1000) << "no FAILED status drawn";
  EXPECT_LT(failed_blue, paused_blue / 4) << "the PAUSED status is still drawn";
}

TEST(Rviz, ScreenshotShowsTheSlowPace) {
  ros::NodeHandle nh, pnh("~");
  const std::string display = pnh.param<std::string>("display", ":74");
  StatusSeen seen;
  std::vector<ros::Subscriber> subs;
  watchStatus(nh, &seen, &subs);
  waitForRviz();
  // Real time asked of 1 us physics steps: the pace is not held. SLOW in amber on the overlay
  // and the status marker while /diagnostics warns of it.
  const std::string kSlow = "slower than the target real time";
  const bool slow = waitForStatus(&seen, 60.0, [&](const StatusSeen& s) {
    return s.level == diagnostic_msgs::DiagnosticStatus::WARN && s.summary.rfind(kSlow, 0) == 0 &&
           firstLine(s.overlay) == "SLOW: " + kSlow && s.cause.rfind(kSlow, 0) == 0 &&
           s.word == "SLOW";
  });
  {
    std::lock_guard<std::mutex> lock(seen.mutex);
    ASSERT_TRUE(slow) << describe(seen);
    EXPECT_TRUE(colourIs(seen.overlay_color, 1.f, 0.6f, 0.f)) << describe(seen);
    EXPECT_TRUE(colourIs(seen.word_color, 1.f, 0.6f, 0.f)) << describe(seen);
    EXPECT_EQ(seen.frame_action, visualization_msgs::Marker::ADD);
  }
  ros::WallDuration(1.0).sleep();
  const std::string png = std::string(SCREENSHOT_DIR) + "/rviz_slow.png";
  const Image img = screenshot(display, png);
  ASSERT_GT(img.width * img.height, 0);
  const long warn = count(img, amber);
  std::printf("screenshot %s: amber (slow) %ld px\n", png.c_str(), warn);
  EXPECT_GT(warn, 1000) << "no SLOW status drawn";
}

}  // namespace

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_rviz_screenshot");
  ros::AsyncSpinner spinner(1);
  spinner.start();
  const int result = RUN_ALL_TESTS();
  ros::shutdown();
  return result;
}
