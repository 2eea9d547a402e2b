// Bearing files: the matched bearing vectors of a sequence, exported by the evaluation command so
// that the CUDA voter can be checked and timed on real data on a machine without ROS or OpenCV.
//
// Format (text, see cuda/README.md):
//   # visual_gyro bearings v1
//   frame <k> <n>
//   px py pz cx cy cz        (n lines: prev and current unit bearings, %.9g)
//   frame <k'> <n'>
//   ...
// Empty lines and further lines starting with '#' are ignored.
#pragma once

#include <string>
#include <vector>

#include "standalone/bearing_frames.h"

namespace visual_gyro {
namespace bearings {

/// The first line of every bearing file.
constexpr const char* kBearingFileHeader = "# visual_gyro bearings v1";

/// Reads a bearing file; throws std::runtime_error naming the file and line on any problem
/// (missing header, bad count, non-finite or non-unit bearing, truncated frame).
std::vector<BearingFrame> readBearingFile(const std::string& path);

/// Writes frames in the bearing file format; throws std::runtime_error when the file cannot be
/// written.
void writeBearingFile(const std::string& path, const std::vector<BearingFrame>& frames);

}  // namespace bearings
}  // namespace visual_gyro
