# ROS tests of visual_gyro (included from the top-level CMakeLists.txt when testing is enabled).
# All run with `catkin_make run_tests` (or one: catkin_make run_tests_visual_gyro_rostest_test_ros_hz.test).
find_package(rostest REQUIRED)
find_package(roslaunch REQUIRED)

# Scaffolding shared by the ROS tests (waits, the rendered scene, an output recorder, main()).
add_library(visual_gyro_ros_test_support STATIC EXCLUDE_FROM_ALL test/ros/ros_test_support.cpp)
target_include_directories(visual_gyro_ros_test_support PUBLIC ${CMAKE_CURRENT_SOURCE_DIR}/test/ros)
target_link_libraries(visual_gyro_ros_test_support PUBLIC visual_gyro_ros_tools ${catkin_LIBRARIES} ${GTEST_LIBRARIES})

# One gtest-with-ROS source, run against the node and against the nodelet.
add_rostest_gtest(test_visual_gyro_ros test/ros/visual_gyro_node.test test/ros/test_visual_gyro_ros.cpp)
target_link_libraries(test_visual_gyro_ros visual_gyro_ros_test_support)
add_rostest(test/ros/visual_gyro_nodelet.test DEPENDENCIES test_visual_gyro_ros visual_gyro_nodelet)
# The same with ~output_frame (outputs rotated into a body frame through tf2).
add_rostest(test/ros/visual_gyro_output_frame.test DEPENDENCIES test_visual_gyro_ros visual_gyro_nodelet)
# The same with intrinsics from parameters instead of camera_info (plain image subscription).
add_rostest(test/ros/visual_gyro_parameters.test DEPENDENCIES test_visual_gyro_ros visual_gyro_node)

# ROS conversions without a master (mono16 scaling, Bayer and YUV images, malformed images,
# binning; the encodings the docs list).
catkin_add_gtest(test_ros_conversions test/ros/test_ros_conversions.cpp)
target_link_libraries(test_ros_conversions visual_gyro_ros_tools ${catkin_LIBRARIES} gtest_main)
target_compile_definitions(test_ros_conversions PRIVATE VISUAL_GYRO_SOURCE_DIR="${VISUAL_GYRO_REPO_DIR}")

# The nodelet's output messages without a master (invalid = identity, Imu policy, output frame).
catkin_add_gtest(test_output_messages test/ros/test_output_messages.cpp)
target_link_libraries(test_output_messages visual_gyro_ros_tools ${catkin_LIBRARIES} gtest_main)

# The node's diagnostics summary without a master (which cause wins, at which level).
catkin_add_gtest(test_node_diagnostics test/ros/test_node_diagnostics.cpp)
target_link_libraries(test_node_diagnostics visual_gyro_ros_common gtest_main)

# Bad ROS input: plausibility, frozen frames, mono16, calibration, diagnostics and throttled logs.
add_rostest_gtest(test_reliability_ros test/ros/reliability.test test/ros/test_reliability_ros.cpp)
target_link_libraries(test_reliability_ros visual_gyro_ros_test_support)
add_dependencies(test_reliability_ros visual_gyro_node visual_gyro_nodelet)

# Start-up parameters the settings gate refuses: replaced by their defaults and named.
add_rostest_gtest(test_settings_startup_ros test/ros/settings_startup.test test/ros/test_settings_startup_ros.cpp)
target_link_libraries(test_settings_startup_ros visual_gyro_ros_test_support)
add_dependencies(test_settings_startup_ros visual_gyro_node visual_gyro_nodelet)

# Soak: 1 minute of 30 Hz replay; memory, descriptors and answers checked (make soak runs it longer).
add_rostest_gtest(test_soak test/ros/soak.test test/ros/soak.cpp test/test_support.cpp)
target_link_libraries(test_soak visual_gyro_ros_tools ${catkin_LIBRARIES})
target_include_directories(test_soak PRIVATE ${CMAKE_CURRENT_SOURCE_DIR}/test)
target_compile_definitions(test_soak PRIVATE VISUAL_GYRO_DEFAULT_DATA="${VISUAL_GYRO_DEFAULT_DATA}")
add_dependencies(test_soak visual_gyro_node visual_gyro_nodelet)

# Replay of a bag made from ../shared/data/kitti_turn (skipped with a message when absent).
add_rostest_gtest(test_replay_ros test/ros/replay_kitti.test test/ros/test_replay_ros.cpp test/test_support.cpp)
target_link_libraries(test_replay_ros visual_gyro_ros_test_support)
target_include_directories(test_replay_ros PRIVATE ${CMAKE_CURRENT_SOURCE_DIR}/test)
target_compile_definitions(test_replay_ros PRIVATE VISUAL_GYRO_DEFAULT_DATA="${VISUAL_GYRO_DEFAULT_DATA}")

# Publication rates (hztest) of ~imu and /diagnostics, fed by a rendered camera.
add_executable(publish_rendered EXCLUDE_FROM_ALL test/ros/publish_rendered.cpp)
target_link_libraries(publish_rendered visual_gyro_ros_test_support)
if(TARGET tests)
  add_dependencies(tests publish_rendered)
endif()
add_rostest(test/ros/hz.test DEPENDENCIES publish_rendered visual_gyro_node visual_gyro_nodelet)

# Yaw plot markers, compressed images, filter-style integration of the rates (no ROS master).
catkin_add_gtest(test_plot_and_inputs test/ros/test_plot_and_inputs.cpp)
target_link_libraries(test_plot_and_inputs visual_gyro_ros_tools gtest_main)
target_compile_definitions(test_plot_and_inputs PRIVATE VISUAL_GYRO_SOURCE_DIR="${VISUAL_GYRO_REPO_DIR}")

# replay.launch with the real rosbag play (rate 1 unless the build is too slow for it) against the frame-by-frame replay (kitti_turn).
add_rostest_gtest(test_rosbag_replay test/ros/rosbag_replay.test test/ros/test_rosbag_replay.cpp test/test_support.cpp)
target_link_libraries(test_rosbag_replay visual_gyro_ros_test_support)
target_include_directories(test_rosbag_replay PRIVATE ${CMAKE_CURRENT_SOURCE_DIR}/test)
target_compile_definitions(test_rosbag_replay PRIVATE VISUAL_GYRO_DEFAULT_DATA="${VISUAL_GYRO_DEFAULT_DATA}"
  VISUAL_GYRO_SOURCE_DIR="${VISUAL_GYRO_REPO_DIR}")
add_dependencies(test_rosbag_replay visual_gyro_nodelet)

# rviz for real: replay.launch with rviz and rosbag play under Xvfb, screenshot checked.
add_rostest(test/ros/rviz_shot.test DEPENDENCIES visual_gyro_nodelet make_bag render_sequence)

# Every launch file resolves (packages, nodes, args); rviz is in a group that is off by default.
roslaunch_add_file_check(launch/visual_gyro.launch)
roslaunch_add_file_check(launch/replay.launch IGNORE_UNSET_ARGS)

# The same figures offline (evaluate) and through the node, on a rendered sequence with a black image.
add_rostest_gtest(test_offline_equivalence test/ros/offline_equivalence.test test/ros/test_offline_equivalence.cpp
  test/test_support.cpp)
target_link_libraries(test_offline_equivalence visual_gyro_ros_test_support)
target_include_directories(test_offline_equivalence PRIVATE ${CMAKE_CURRENT_SOURCE_DIR}/test)
target_compile_definitions(test_offline_equivalence PRIVATE VISUAL_GYRO_DEFAULT_DATA="${VISUAL_GYRO_DEFAULT_DATA}"
  VISUAL_GYRO_RENDER="$<TARGET_FILE:render_sequence>" VISUAL_GYRO_EVALUATE="$<TARGET_FILE:evaluate>")
add_dependencies(test_offline_equivalence visual_gyro_node render_sequence evaluate)

# rospack, rosrun and roslaunch find the package in the workspace without a warning (no master).
catkin_add_gtest(test_workspace_layout test/ros/test_workspace_layout.cpp test/test_support.cpp)
target_include_directories(test_workspace_layout PRIVATE ${CMAKE_CURRENT_SOURCE_DIR}/test)
target_link_libraries(test_workspace_layout visual_gyro_sim gtest_main)
target_compile_definitions(test_workspace_layout PRIVATE VISUAL_GYRO_DEFAULT_DATA="${VISUAL_GYRO_DEFAULT_DATA}"
  VISUAL_GYRO_REPO_DIR="${VISUAL_GYRO_REPO_DIR}")
add_dependencies(test_workspace_layout make_bag)
