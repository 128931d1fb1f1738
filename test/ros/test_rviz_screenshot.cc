// rostest (rviz.test): demo.launch with rviz under Xvfb and the committed config. Once rviz
// listens, the paused demo runs into its first contact and is paused there; a screenshot of the
// display must then show the kernel, the tooth and the contact force arrow in their marker
// colours (not a blank or default scene).
#include <gtest/gtest.h>
#include <ros/master.h>
#include <ros/ros.h>
#include <std_srvs/SetBool.h>
#include <visualization_msgs/MarkerArray.h>

#include <atomic>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

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

TEST(Rviz, ScreenshotShowsTheContact) {
  ros::NodeHandle nh, pnh("~");
  const std::string display = pnh.param<std::string>("display", ":97");
  const std::string png = SCREENSHOT_PATH;

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
