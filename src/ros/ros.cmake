# ROS layer of visual_gyro (included from the top-level CMakeLists.txt).
#   visual_gyro_nodelet   the nodelet plugin (nodelet_plugins.xml)
#   visual_gyro_node      standalone node loading the same plugin in-process (nodelet::Loader)
#   make_bag              sequence folder -> rosbag (Image + CameraInfo, gyro, ground truth)
#   play_frames           frame-by-frame replay of such a bag through a running node
#   summarize_outputs     errors of the recorded outputs against the bag's ground truth (demo JSON)
#   integrate_imu         the recorded ~imu integrated as a filter does, orientation error over time
#   calibrate_imu         camera-IMU time offset, rotation and gyro bias from a EuRoC folder or a bag
#                         (src/tools/calibrate_imu.cpp: ROS-free itself, linked with the bag reader)

set(VISUAL_GYRO_ROS_INCLUDES
  ${CMAKE_CURRENT_SOURCE_DIR}/src/ros
  ${CATKIN_DEVEL_PREFIX}/${CATKIN_GLOBAL_INCLUDE_DESTINATION}  # generated messages and config
  ${catkin_INCLUDE_DIRS})

# The node's parts that the ROS tools and tests use too (messages, plot, inputs, diagnostics).
add_library(visual_gyro_ros_common
  src/ros/ros_conversions.cpp
  src/ros/yaw_plot.cpp
  src/ros/compressed_input.cpp
  src/ros/output_publisher.cpp
  src/ros/node_parameters.cpp
  src/ros/node_diagnostics.cpp)
target_include_directories(visual_gyro_ros_common PUBLIC ${VISUAL_GYRO_ROS_INCLUDES})
target_link_libraries(visual_gyro_ros_common PUBLIC visual_gyro_core visual_gyro_settings ${catkin_LIBRARIES})
add_dependencies(visual_gyro_ros_common ${PROJECT_NAME}_generate_messages_cpp ${PROJECT_NAME}_gencfg)
target_compile_options(visual_gyro_ros_common PRIVATE -Wall -Wextra)

add_library(visual_gyro_nodelet
  src/ros/visual_gyro_nodelet.cpp
  src/ros/input_probe.cpp
  src/ros/reconfigure_settings.cpp)
target_link_libraries(visual_gyro_nodelet visual_gyro_ros_common)
add_dependencies(visual_gyro_nodelet ${PROJECT_NAME}_generate_messages_cpp ${PROJECT_NAME}_gencfg)
target_compile_options(visual_gyro_nodelet PRIVATE -Wall -Wextra)

add_executable(visual_gyro_node src/ros/visual_gyro_node.cpp)
target_include_directories(visual_gyro_node PRIVATE ${VISUAL_GYRO_ROS_INCLUDES})
target_link_libraries(visual_gyro_node ${catkin_LIBRARIES})
# The node loads the plugin at run time; build them together.
add_dependencies(visual_gyro_node visual_gyro_nodelet)

# Bag writing/reading, frame-by-frame replay and output evaluation, shared by the commands and the
# ROS tests.
add_library(visual_gyro_ros_tools STATIC
  src/ros/alignment_bag.cpp
  src/ros/bag_tools.cpp
  src/ros/frame_player.cpp
  src/ros/imu_integration.cpp)
target_link_libraries(visual_gyro_ros_tools PUBLIC visual_gyro_ros_common visual_gyro_eval visual_gyro_sim)
target_compile_options(visual_gyro_ros_tools PRIVATE -Wall -Wextra)

foreach(tool make_bag play_frames summarize_outputs integrate_imu)
  add_executable(${tool} src/ros/${tool}.cpp)
  target_link_libraries(${tool} visual_gyro_ros_tools visual_gyro_cli)
endforeach()

add_executable(calibrate_imu src/tools/calibrate_imu.cpp)
target_link_libraries(calibrate_imu visual_gyro_ros_tools visual_gyro_cli)
target_compile_options(calibrate_imu PRIVATE -Wall -Wextra)

install(TARGETS visual_gyro_ros_common visual_gyro_nodelet visual_gyro_node make_bag play_frames summarize_outputs integrate_imu
  calibrate_imu
  ARCHIVE DESTINATION ${CATKIN_PACKAGE_LIB_DESTINATION}
  LIBRARY DESTINATION ${CATKIN_PACKAGE_LIB_DESTINATION}
  RUNTIME DESTINATION ${CATKIN_PACKAGE_BIN_DESTINATION})
install(FILES nodelet_plugins.xml DESTINATION ${CATKIN_PACKAGE_SHARE_DESTINATION})
