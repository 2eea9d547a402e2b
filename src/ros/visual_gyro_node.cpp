// Standalone visual_gyro node: loads the VisualGyroNodelet plugin in-process with nodelet::Loader,
// so the node and the nodelet run exactly the same code (names, remappings and parameters as for
// any node: private topics ~imu, ~rotation, ... under the node's name).
#include <nodelet/loader.h>
#include <ros/ros.h>

int main(int argc, char** argv) {
  ros::init(argc, argv, "visual_gyro");
  nodelet::Loader loader;
  const nodelet::M_string remappings(ros::names::getRemappings());
  const nodelet::V_string nodelet_argv;
  if (!loader.load(ros::this_node::getName(), "visual_gyro/VisualGyroNodelet", remappings, nodelet_argv)) {
    ROS_FATAL("visual_gyro_node: could not load the visual_gyro/VisualGyroNodelet plugin "
              "(is the workspace's devel/setup.bash sourced, so pluginlib finds nodelet_plugins.xml?)");
    return 1;
  }
  ros::spin();
  return 0;
}
