// Bearing files: the matched bearing vectors of a sequence, exported by the evaluation command so
// that the CUDA backend can be checked and timed on real data on a machine without ROS or OpenCV.
//
// Format (text, see cuda/README.md):
//   # visual_gyro bearings v2
//   frame <k> <n> <dt>
//   truth r00 r01 r02 r10 r11 r12 r20 r21 r22    (optional: true rotation, b_prev ~ R b_cur)
//   px py pz cx cy cz        (n lines: prev and current unit bearings, %.9g)
//   frame <k'> <n'> <dt'>
//   ...
// Empty lines and further lines starting with '#' are ignored. Version 1 files (no dt, no truth
// lines) are still read.
#pragma once

#include <string>
#include <vector>

#include "bearing_frames.h"

namespace visual_gyro {
namespace bearings {

/// The first line of the bearing files this version writes.
constexpr const char* kBearingFileHeader = "# visual_gyro bearings v2";
/// The first line of version 1 files (no dt, no truth), still read.
constexpr const char* kBearingFileHeaderV1 = "# visual_gyro bearings v1";

/// Reads a bearing file (v1 or v2); throws std::runtime_error naming the file and line on any
/// problem (missing header, bad count or dt, bad truth line, non-finite or non-unit bearing,
/// truncated frame).
std::vector<BearingFrame> readBearingFile(const std::string& path);

/// Writes frames in the bearing file format (v2; truth lines for frames that have it); throws
/// std::runtime_error when the file cannot be written.
void writeBearingFile(const std::string& path, const std::vector<BearingFrame>& frames);

}  // namespace bearings
}  // namespace visual_gyro
