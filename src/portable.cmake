# The parts of visual_gyro that need neither ROS nor OpenCV, as object libraries. Included by the
# package (CMakeLists.txt, which puts them into its shared libraries) and by the stand-alone GPU
# build (cuda/CMakeLists.txt, which makes static libraries of them), so that each source file has
# exactly one target that compiles it, defined here.
#
#   visual_gyro_voter_objects      src/voter: hypothesis math, the voter interface, the CPU gold voter
#                                  (with its batched triple solver)
#   visual_gyro_cli_objects        src/tools/command_line: the commands' command-line conventions
#   visual_gyro_bearing_objects    src/io/bearing_file: the bearing-file format (plain C++)
#   visual_gyro_estimator_objects  rotation estimator and its stages (candidates, refinement and its
#                                  per-match passes, covariance), frame status,
#                                  setting fields (Eigen)
#   visual_gyro_metrics_objects    src/eval/metrics: per-frame errors and their summaries (Eigen)
#
# The estimator's sources are compiled with VISUAL_GYRO_WITH_CUDA when the caller sets
# VISUAL_GYRO_PORTABLE_WITH_CUDA (the CUDA voter's header then comes from target visual_gyro_cuda).
get_filename_component(VISUAL_GYRO_SRC_DIR "${CMAKE_CURRENT_LIST_DIR}" ABSOLUTE)
get_filename_component(VISUAL_GYRO_PUBLIC_INCLUDE "${CMAKE_CURRENT_LIST_DIR}/../include" ABSOLUTE)

add_library(visual_gyro_voter_objects OBJECT
  "${VISUAL_GYRO_SRC_DIR}/voter/cpu_voter.cpp" "${VISUAL_GYRO_SRC_DIR}/voter/triple_batch.cpp")
target_include_directories(visual_gyro_voter_objects PUBLIC "${VISUAL_GYRO_SRC_DIR}/voter")

add_library(visual_gyro_cli_objects OBJECT "${VISUAL_GYRO_SRC_DIR}/tools/command_line.cpp")
target_include_directories(visual_gyro_cli_objects PUBLIC "${VISUAL_GYRO_SRC_DIR}/tools")

add_library(visual_gyro_bearing_objects OBJECT "${VISUAL_GYRO_SRC_DIR}/io/bearing_file.cpp")
target_include_directories(visual_gyro_bearing_objects PUBLIC
  "${VISUAL_GYRO_SRC_DIR}/io" "${VISUAL_GYRO_SRC_DIR}/voter" "${VISUAL_GYRO_PUBLIC_INCLUDE}")

foreach(objects visual_gyro_voter_objects visual_gyro_cli_objects visual_gyro_bearing_objects)
  set_target_properties(${objects} PROPERTIES POSITION_INDEPENDENT_CODE ON)
  target_compile_features(${objects} PUBLIC cxx_std_17)
  target_compile_options(${objects} PRIVATE $<$<COMPILE_LANGUAGE:CXX>:-Wall -Wextra>)
endforeach()

if(VISUAL_GYRO_EIGEN_TARGET)
  add_library(visual_gyro_estimator_objects OBJECT
    "${VISUAL_GYRO_SRC_DIR}/core/frame_status.cpp"
    "${VISUAL_GYRO_SRC_DIR}/core/match_passes.cpp"
    "${VISUAL_GYRO_SRC_DIR}/core/rotation_estimator.cpp"
    "${VISUAL_GYRO_SRC_DIR}/core/rotation_refinement.cpp"
    "${VISUAL_GYRO_SRC_DIR}/core/candidate_refinement.cpp"
    "${VISUAL_GYRO_SRC_DIR}/core/vote_candidates.cpp"
    "${VISUAL_GYRO_SRC_DIR}/core/vote_covariance.cpp")
  target_include_directories(visual_gyro_estimator_objects PUBLIC
    "${VISUAL_GYRO_PUBLIC_INCLUDE}" "${VISUAL_GYRO_SRC_DIR}/voter")
  target_link_libraries(visual_gyro_estimator_objects PUBLIC ${VISUAL_GYRO_EIGEN_TARGET})
  if(VISUAL_GYRO_PORTABLE_WITH_CUDA)
    target_compile_definitions(visual_gyro_estimator_objects PRIVATE VISUAL_GYRO_WITH_CUDA=1)
    target_include_directories(visual_gyro_estimator_objects PRIVATE
      $<TARGET_PROPERTY:visual_gyro_cuda,INTERFACE_INCLUDE_DIRECTORIES>)
  endif()

  add_library(visual_gyro_metrics_objects OBJECT "${VISUAL_GYRO_SRC_DIR}/eval/metrics.cpp")
  target_include_directories(visual_gyro_metrics_objects PUBLIC
    "${VISUAL_GYRO_SRC_DIR}/eval" "${VISUAL_GYRO_PUBLIC_INCLUDE}")
  target_link_libraries(visual_gyro_metrics_objects PUBLIC ${VISUAL_GYRO_EIGEN_TARGET})

  foreach(objects visual_gyro_estimator_objects visual_gyro_metrics_objects)
    set_target_properties(${objects} PROPERTIES POSITION_INDEPENDENT_CODE ON)
    target_compile_features(${objects} PUBLIC cxx_std_17)
    target_compile_options(${objects} PRIVATE -Wall -Wextra)
  endforeach()
endif()
