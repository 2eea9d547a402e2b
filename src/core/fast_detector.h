// FAST-9/16 corners with non-max suppression, the same corners and scores as cv::FAST bit for bit
// but several times faster (internal to the front end; not installed).
#pragma once

#include <cstdint>
#include <vector>

#include <opencv2/core.hpp>

#include "cpu_features.h"

namespace visual_gyro {
namespace fast_detector {

/// What a detector computes, defined as cv::FAST(image(area), keypoints, threshold,
/// nonmaxSuppression = true, TYPE_9_16) defines it (OpenCV 4.6, which the tests compare with):
///  - the circle is the 16 pixels of the Bresenham circle of radius 3 around a pixel p of value v;
///  - p is a corner when 9 contiguous circle pixels (wrapping around) are all brighter than
///    v + t or all darker than v - t, both strict, where t is `threshold` clamped to 0..255
///    (the same corners as cv::FAST for thresholds 0..255; outside that range OpenCV 4.6's vector
///    code wraps the threshold modulo 256 in most columns and clamps it in the last few, so it
///    disagrees with itself there, while this detector clamps everywhere);
///  - only pixels at least 3 px from every edge of `area` are tested (none when the area is
///    smaller than 7 x 7): the circle never reads outside the area;
///  - a corner's score is the largest t at which it is still a corner: the greatest, over the 16
///    arcs of 9 contiguous circle pixels, of min over the arc of (v - pixel) or of min over the
///    arc of (pixel - v), minus 1 (so t <= score <= 254);
///  - non-max suppression keeps a corner when its score is strictly greater than the score of
///    each of its 8 neighbours, where pixels that are no corner, and pixels not tested (closer
///    than 3 px to the area's edge), count as 0; a corner of score 0 is never kept.
/// Corners come out in row-major order (y, then x), as cv::FAST lists them.
///
/// `image` is CV_8UC1 (any row step) and `area` lies inside it; throws std::invalid_argument
/// otherwise. Kept corners are appended to `corners` (not cleared) as (x, y, score) with x, y in
/// pixels in `image`'s coordinates (the area's offset added). `scratch` is working room, grown as
/// needed (about 3.2 bytes per column of the area): reusing it and `corners` across calls avoids
/// allocation once they have reached the largest size needed.
using Detector = void (*)(const cv::Mat& image, const cv::Rect& area, int threshold,
                          std::vector<uint8_t>* scratch, std::vector<cv::Point3i>* corners);

/// The detector of `level`, or nullptr for levels without one of their own or when this build or
/// this CPU cannot run it: kPortable (plain C++, one pixel at a time), kSse2 (16 pixels at a
/// time, every x86-64 CPU), kAvx2 (32 pixels at a time). The vector detectors take the portable
/// path for areas narrower than a block plus 6 columns. All give the same result; tests compare
/// each with cv::FAST.
Detector detectorFor(cpu::CpuLevel level);

/// cv::FAST itself, for CPUs with no vector detector here.
Detector openCvDetector();

/// The detector of the highest level from `at_most` down to kSse2 (cpu::selectKernel), else
/// cv::FAST (whose own vector code beats the portable path several times over): AVX2 where the
/// CPU has it, else SSE2 on x86-64, else cv::FAST.
Detector selectDetector(cpu::CpuLevel at_most);
/// selectDetector(cpu::activeLevel()).
Detector selectDetector();

/// Runs selectDetector()'s detector (chosen once).
void detect(const cv::Mat& image, const cv::Rect& area, int threshold, std::vector<uint8_t>* scratch,
            std::vector<cv::Point3i>* corners);

}  // namespace fast_detector
}  // namespace visual_gyro
