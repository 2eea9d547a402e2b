// Hamming-distance search kernels of the front end's matching (internal to the core library; not
// installed): brute force (every previous descriptor against every current one) and guided (each
// previous descriptor against the current ones inside its search window). Kernels of several
// instruction-set levels (cpu_features.h), chosen at run time; all give the same result bit for bit.
#pragma once

#include <vector>

#include <opencv2/core.hpp>

#include "cpu_features.h"
#include "visual_gyro/feature_front_end.h"

namespace visual_gyro {
namespace hamming {

/// Row or column without a candidate.
constexpr int kNoMatch = -1;
/// Elements the caller adds past the end of GuidedGrid::points and GuidedGrid::inside: the
/// vector kernels read points and write candidate indices up to this many places past a run's end.
constexpr int kGuidedPad = 16;

/// What a search produces, for collectMatches in the front end: for each previous descriptor i
/// (row) the best current column row_best[i] (kNoMatch when none was compared), its distance
/// row_best_d[i] and the second-best distance row_second_d[i] (INT_MAX when fewer than two were
/// compared); for each current column j the previous row that came closest, col_best[j], at
/// distance col_best_d[j]. Ties: the first in search order wins (the smaller column for a row, the
/// smaller row for a column). Each array has room for its rows or columns.
struct SearchTables {
  int* row_best;
  int* row_best_d;
  int* row_second_d;
  int* col_best;
  int* col_best_d;
};

/// Brute force: row i is previous[i], column j is current[j].
using BruteForceKernel = void (*)(const BriefDescriptor* previous, int n_previous,
                                  const BriefDescriptor* current, int n_current,
                                  const SearchTables& tables);

/// The current keypoints sorted into square cells of a grid, row-major: cell c holds the sorted
/// entries start[c] .. start[c + 1] - 1. The guided kernel's columns are these sorted entries.
struct GuidedGrid {
  const int* start;                    ///< cols * rows + 1 cell starts
  const BriefDescriptor* descriptors;  ///< n descriptors in sorted order
  const cv::Point2f* points;           ///< n keypoints [px] in sorted order, then kGuidedPad more
  int n = 0;                           ///< number of current keypoints
  int* inside;                         ///< working room for n + kGuidedPad indices
  int cols = 0, rows = 0;
  float cell_size = 1.f;  ///< [px]
};

/// Where sortIntoGrid keeps a grid's arrays (the caller's vectors, reused from call to call).
struct GridBuffers {
  std::vector<int>* start;                    ///< GuidedGrid::start
  std::vector<int>* cursor;                   ///< working room of the sort
  std::vector<int>* items;                    ///< items[k]: the keypoint index of sorted entry k
  std::vector<int>* inside;                   ///< GuidedGrid::inside
  std::vector<cv::Point2f>* points;           ///< GuidedGrid::points
  std::vector<BriefDescriptor>* descriptors;  ///< GuidedGrid::descriptors
};

/// Sorts `keypoints` (all at x, y >= 0; a negative coordinate counts as the first cell) and
/// their descriptors into cells of cell_size px covering them: a counting sort, row-major, with
/// the padding the kernels need. The grid refers to the buffers' vectors.
GuidedGrid sortIntoGrid(const std::vector<cv::Point2f>& keypoints,
                        const std::vector<BriefDescriptor>& descriptors, float cell_size,
                        const GridBuffers& buffers);

/// Guided: row i, previous[i], is compared with the columns whose points lie within radii[i] of
/// predicted[i] (squared distances in float, each product rounded, as
/// !((x - px)^2 + (y - py)^2 > r^2)); none when radii[i] < 0.
using GuidedKernel = void (*)(const BriefDescriptor* previous, int n_previous,
                              const cv::Point2f* predicted, const float* radii,
                              const GuidedGrid& grid, const SearchTables& tables);

/// The brute-force kernel of `level`, or nullptr for levels without one of their own or when this
/// build or this CPU cannot run it: kPortable (plain C++; on aarch64 its population count is the
/// vector cnt), kPopcnt, kAvx512Vbmi (distances and bookkeeping eight candidates at a time with
/// VPOPCNTDQ).
BruteForceKernel bruteForceKernelFor(cpu::CpuLevel level);
/// The guided kernel of `level`, or nullptr likewise: kPortable, kPopcnt, kAvx2 (the position test
/// eight points at a time), kAvx512Vbmi (as brute force's).
GuidedKernel guidedKernelFor(cpu::CpuLevel level);

/// The kernels of the highest level up to `at_most` (cpu::selectKernel).
BruteForceKernel selectBruteForceKernel(cpu::CpuLevel at_most);
GuidedKernel selectGuidedKernel(cpu::CpuLevel at_most);
/// The kernels of the highest level this CPU runs (cpu::activeLevel(); chosen once).
BruteForceKernel selectBruteForceKernel();
GuidedKernel selectGuidedKernel();

}  // namespace hamming
}  // namespace visual_gyro
