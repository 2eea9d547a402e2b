// The 13-tap Gaussian that smooths images before BRIEF, computed in 16-bit fixed point with the
// same result as cv::GaussianBlur bit for bit (internal to the front end; not installed).
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include <opencv2/core.hpp>

#include "cpu_features.h"

namespace visual_gyro {
namespace fixed_point_gaussian {

/// Kernel size the filter computes: OpenCV's size for an 8-bit image and sigma in (5/3, 2]
/// (2 * ceil(3 sigma) + 1), which holds the default smoothing_sigma of 2 px.
constexpr int kTaps = 13;
/// Weights w[0] (centre) .. w[kTaps / 2] in units of 1/256, summing to 256 over all taps.
using Weights = std::array<uint16_t, kTaps / 2 + 1>;
/// Filters the 8-bit `src` into `dst` (allocated by the caller, same size) with `weights` and
/// BORDER_REFLECT_101; `buffer` holds bufferSize(src.cols, src.rows) values.
using Filter = void (*)(const cv::Mat& src, const Weights& weights, cv::Mat* dst, uint16_t* buffer);

/// The filter of `level`, or nullptr for levels without one of their own or when this build or
/// this CPU cannot run it: kPortable (the baseline instruction set), kAvx2 (the column pass by
/// multiply-adds of 16 pixels), kAvx512Bw (32 pixels a step).
Filter filterFor(cpu::CpuLevel level);

/// The filter of the highest level up to `at_most` (cpu::selectKernel).
Filter selectFilter(cpu::CpuLevel at_most);
/// selectFilter(cpu::activeLevel()).
Filter selectFilter();

/// Every filter this CPU runs, by level name (cpu::levelName), lowest level first, so tests can
/// check each one and not only the one selectFilter() picks.
std::vector<std::pair<std::string, Filter>> availableFilters();

/// Scratch values a filter call needs for an image of `cols` x `rows`.
size_t bufferSize(int cols, int rows);

/// Reads OpenCV's fixed-point weights for `sigma` back from cv::GaussianBlur, then checks that
/// `filter` gives cv::GaussianBlur's result bit for bit on a test image. False when it does not
/// (an OpenCV build with another algorithm): the caller uses cv::GaussianBlur then.
bool readWeights(double sigma, Filter filter, Weights* weights);

}  // namespace fixed_point_gaussian
}  // namespace visual_gyro
