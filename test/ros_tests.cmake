# ROS tests of visual_gyro (included from the top-level CMakeLists.txt when testing is enabled).
# All run with `catkin_make run_tests` (or one: catkin_make run_tests_visual_gyro_rostest_test_ros_hz.test).
find_package(rostest REQUIRED)
find_package(roslaunch REQUIRED)

# One gtest-with-ROS source, run against the node and against the nodelet.
add_rostest_gtest(test_visual_gyro_ros test/ros/visual_gyro_node.test test/ros/test_visual_gyro_ros.cpp)
target_link_libraries(test_visual_gyro_ros visual_gyro_ros_tools ${catkin_LIBRARIES})
add_rostest(test/ros/visual_gyro_nodelet.test DEPENDENCIES test_visual_gyro_ros visual_gyro_nodelet)
# The same with ~output_frame (outputs rotated into a body frame through tf2).
add_rostest(test/ros/visual_gyro_output_frame.test DEPENDENCIES test_visual_gyro_ros visual_gyro_nodelet)
# The same with intrinsics from parameters instead of camera_info (plain image subscription).
add_rostest(test/ros/visual_gyro_parameters.test DEPENDENCIES test_visual_gyro_ros visual_gyro_node)

# ROS conversions without a master (mono16 scaling, malformed images, binning).
catkin_add_gtest(test_ros_conversions test/ros/test_ros_conversions.cpp)
target_link_libraries(test_ros_conversions visual_gyro_ros_tools ${catkin_LIBRARIES} gtest_main)

# The node's diagnostics summary without a master (which cause wins, at which level).
catkin_add_gtest(test_node_diagnostics test/ros/test_node_diagnostics.cpp src/ros/node_diagnostics.cpp)
target_include_directories(test_node_diagnostics PRIVATE ${VISUAL_GYRO_ROS_INCLUDES})
target_link_libraries(test_node_diagnostics ${catkin_LIBRARIES} gtest_main)

# Bad ROS input: plausibility, frozen frames, mono16, calibration, diagnostics and throttled logs.
add_rostest_gtest(test_reliability_ros test/ros/reliability.test test/ros/test_reliability_ros.cpp)
target_link_libraries(test_reliability_ros visual_gyro_ros_tools ${catkin_LIBRARIES})
add_dependencies(test_reliability_ros visual_gyro_node visual_gyro_nodelet)

# Soak: 1 minute of 30 Hz replay; memory, descriptors and answers checked (make soak runs it longer).
add_rostest_gtest(test_soak test/ros/soak.test test/ros/soak.cpp test/test_support.cpp)
target_link_libraries(test_soak visual_gyro_ros_tools ${catkin_LIBRARIES})
target_include_directories(test_soak PRIVATE ${CMAKE_CURRENT_SOURCE_DIR}/test)
target_compile_definitions(test_soak PRIVATE VISUAL_GYRO_DEFAULT_DATA="${VISUAL_GYRO_DEFAULT_DATA}")
add_dependencies(test_soak visual_gyro_node visual_gyro_nodelet)

# Replay of a bag made from ../shared/data/kitti_turn (skipped with a message when absent).
add_rostest_gtest(test_replay_ros test/ros/replay_kitti.test test/ros/test_replay_ros.cpp test/test_support.cpp)
target_link_libraries(test_replay_ros visual_gyro_ros_tools ${catkin_LIBRARIES})
target_include_directories(test_replay_ros PRIVATE ${CMAKE_CURRENT_SOURCE_DIR}/test)
target_compile_definitions(test_replay_ros PRIVATE VISUAL_GYRO_DEFAULT_DATA="${VISUAL_GYRO_DEFAULT_DATA}")

# Publication rates (hztest) of ~imu and /diagnostics, fed by a rendered camera.
add_executable(publish_rendered EXCLUDE_FROM_ALL test/ros/publish_rendered.cpp)
target_link_libraries(publish_rendered visual_gyro_ros_tools ${catkin_LIBRARIES})
if(TARGET tests)
  add_dependencies(tests publish_rendered)
endif()
add_rostest(test/ros/hz.test DEPENDENCIES publish_rendered visual_gyro_node visual_gyro_nodelet)

# Yaw plot markers, compressed images, filter-style integration of the rates (no ROS master).
catkin_add_gtest(test_plot_and_inputs test/ros/test_plot_and_inputs.cpp)
target_link_libraries(test_plot_and_inputs visual_gyro_ros_tools gtest_main)
target_compile_definitions(test_plot_and_inputs PRIVATE VISUAL_GYRO_SOURCE_DIR="${VISUAL_GYRO_REPO_DIR}")

# replay.launch with the real rosbag play at rate 1 against the frame-by-frame replay (kitti_turn).
add_rostest_gtest(test_rosbag_replay test/ros/rosbag_replay.test test/ros/test_rosbag_replay.cpp test/test_support.cpp)
target_link_libraries(test_rosbag_replay visual_gyro_ros_tools ${catkin_LIBRARIES})
target_include_directories(test_rosbag_replay PRIVATE ${CMAKE_CURRENT_SOURCE_DIR}/test)
target_compile_definitions(test_rosbag_replay PRIVATE VISUAL_GYRO_DEFAULT_DATA="${VISUAL_GYRO_DEFAULT_DATA}"
  VISUAL_GYRO_SOURCE_DIR="${VISUAL_GYRO_REPO_DIR}")
add_dependencies(test_rosbag_replay visual_gyro_nodelet)

# rviz for real: replay.launch with rviz and rosbag play under Xvfb, screenshot checked.
add_rostest(test/ros/rviz_shot.test DEPENDENCIES visual_gyro_nodelet make_bag render_sequence)

# Every launch file resolves (packages, nodes, args); rviz is in a group that is off by default.
roslaunch_add_file_check(launch/visual_gyro.launch)
roslaunch_add_file_check(launch/replay.launch IGNORE_UNSET_ARGS)
