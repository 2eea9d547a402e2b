// FAST corners with grid bucketing, BRIEF-256 descriptors, brute-force and guided Hamming matching
// (the search kernels are in hamming_kernels.cpp).
#include "visual_gyro/feature_front_end.h"
#include "visual_gyro/random.h"
#include "brief_kernels.h"
#include "fast_detector.h"
#include "fixed_point_gaussian.h"
#include "hamming_kernels.h"
#include "match_passes.h"
#include "patch_alignment.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <opencv2/imgproc.hpp>
#include <sstream>
#include <stdexcept>

namespace visual_gyro {

namespace {

// Corners must keep this distance from the border (the BRIEF patch plus one pixel of margin, so a
// keypoint that moves by rounding still has its whole patch inside the image).
constexpr int kDetectBorder = kBriefHalfPatch + 1;
// What a kept corner's FAST tests read beyond it: its 3 px circle, and the scores of its
// neighbours for the non-max suppression, 1 px further.
constexpr int kFastMargin = 4;
constexpr int kFastRadius = 3;

/// Whether FAST can run on `area` (its circle fits).
bool fastFits(const cv::Rect& area) {
  return area.width >= 2 * kFastRadius + 1 && area.height >= 2 * kFastRadius + 1;
}

void checkImage(const cv::Mat& gray, const char* where) {
  if (gray.empty()) {
    throw std::invalid_argument(std::string("FeatureFrontEnd::") + where + ": empty image");
  }
  if (gray.type() != CV_8UC1) {
    throw std::invalid_argument(std::string("FeatureFrontEnd::") + where +
                                ": image must be 8-bit single-channel (CV_8UC1), got type " +
                                std::to_string(gray.type()) + " with " +
                                std::to_string(gray.channels()) + " channel(s)");
  }
}

void checkSettings(const FrontEndSettings& settings) {
  const std::string why = validateFrontEndSettings(settings);
  if (!why.empty()) throw std::invalid_argument("FeatureFrontEnd: " + why);
}

std::vector<std::array<int8_t, 4>> buildBriefPattern() {
  // Calonder et al. 2010, "G II": both points drawn i.i.d. from an isotropic Gaussian with
  // sigma^2 = S^2 / 25 for a patch of size S = 31.
  constexpr double kSigma = 31.0 / 5.0;
  constexpr uint64_t kSeed = 0x62726965665F5F31ULL;  // "brief__1"
  constexpr double kTwoPi = 6.283185307179586476925286766559;
  // The package's generator: fully specified, so the pattern is the same wherever it is built.
  SplitMix64 rng(kSeed);
  // Box-Muller produces normals in pairs; they are consumed in order x1, y1, x2, y2, each pair of
  // uniforms (u1, u2) giving sqrt(-2 ln u1) * cos(2 pi u2) then sqrt(-2 ln u1) * sin(2 pi u2).
  bool have_spare = false;
  double spare = 0.0;
  auto normal = [&]() {
    if (have_spare) {
      have_spare = false;
      return spare;
    }
    const double u1 = rng.uniformPositive();  // (0, 1]: log() never sees 0
    const double u2 = rng.uniformPositive();
    const double radius = std::sqrt(-2.0 * std::log(u1));
    spare = radius * std::sin(kTwoPi * u2);
    have_spare = true;
    return radius * std::cos(kTwoPi * u2);
  };
  auto offset = [&]() {
    const double value = std::round(kSigma * normal());
    return static_cast<int8_t>(
        std::clamp(value, double(-kBriefHalfPatch), double(kBriefHalfPatch)));
  };
  std::vector<std::array<int8_t, 4>> pairs;
  pairs.reserve(256);
  while (pairs.size() < 256) {
    std::array<int8_t, 4> pair;
    for (auto& value : pair) value = offset();
    // A test comparing a pixel with itself is always 0 and carries no information.
    if (pair[0] == pair[2] && pair[1] == pair[3]) continue;
    pairs.push_back(pair);
  }
  return pairs;
}

/// Orders detected corners strongest first, ties broken by position (smaller y, then smaller x) so the
/// selection does not depend on the sort: the FAST score (an integer from 0 to 254 on 8-bit
/// images) above the complemented pixel coordinates, 40 bits in all. The position is read back
/// from the key, so a corner is just its key.
uint64_t candidateKey(int fast_score, int x, int y) {
  const uint64_t score = static_cast<uint64_t>(std::clamp(fast_score, 0, 255));
  const uint64_t yc = 0xFFFF - static_cast<uint64_t>(std::clamp(y, 0, 0xFFFF));
  const uint64_t xc = 0xFFFF - static_cast<uint64_t>(std::clamp(x, 0, 0xFFFF));
  return (score << 32) | (yc << 16) | xc;
}

int keyX(uint64_t key) { return 0xFFFF - static_cast<int>(key & 0xFFFF); }
int keyY(uint64_t key) { return 0xFFFF - static_cast<int>((key >> 16) & 0xFFFF); }

/// Sorts candidate keys in descending order: five 8-bit radix passes over their 40 bits, linear in
/// the count (a comparison sort of a few thousand corners took about a tenth of the detection
/// time). `scratch` is working room of the same size.
void sortKeysDescending(std::vector<uint64_t>* keys, std::vector<uint64_t>* scratch) {
  scratch->resize(keys->size());
  uint64_t* from = keys->data();
  uint64_t* to = scratch->data();
  const size_t n = keys->size();
  for (int pass = 0; pass < 5; ++pass) {
    const int shift = 8 * pass;
    std::array<size_t, 256> count{};
    for (size_t i = 0; i < n; ++i) ++count[(from[i] >> shift) & 0xFF];
    // Descending: the largest digit goes first.
    size_t position = 0;
    for (int digit = 255; digit >= 0; --digit) {
      const size_t c = count[digit];
      count[digit] = position;
      position += c;
    }
    for (size_t i = 0; i < n; ++i) to[count[(from[i] >> shift) & 0xFF]++] = from[i];
    std::swap(from, to);
  }
  // An odd number of passes leaves the result in the scratch buffer.
  keys->swap(*scratch);
}

/// The indices 0 .. n - 1 ordered by the image row rowOf(k) returns (a stable counting sort; rows
/// outside 0 .. height - 1 count as the nearest one): patches read in that order share the rows
/// already in cache.
template <typename RowOf>
void orderByRow(size_t n, int height, RowOf rowOf, std::vector<int>* row_start, std::vector<int>* order) {
  row_start->assign(static_cast<size_t>(height) + 1, 0);
  for (size_t k = 0; k < n; ++k) ++(*row_start)[std::clamp(rowOf(k), 0, height - 1) + 1];
  for (int y = 0; y < height; ++y) (*row_start)[y + 1] += (*row_start)[y];
  order->resize(n);
  for (size_t k = 0; k < n; ++k) (*order)[(*row_start)[std::clamp(rowOf(k), 0, height - 1)]++] = static_cast<int>(k);
}

/// The whole-pixel row of `p` for orderByRow (0 when it is not finite).
int pixelRow(const cv::Point2f& p) {
  return std::isfinite(p.y) && std::abs(p.y) < 1e9f ? static_cast<int>(std::lround(p.y)) : 0;
}

}  // namespace

const std::vector<SettingField<FrontEndSettings>>& frontEndSettingFields() {
  using S = FrontEndSettings;
  static const std::vector<SettingField<S>> fields = {
      intField<S>("fast_threshold", &S::fast_threshold, 1, 254, "grey levels", "FAST intensity threshold"),
      intField<S>("max_features", &S::max_features, 1, 20000, "", "corners per frame at most"),
      intField<S>("grid_cols", &S::grid_cols, 1, 64, "", "bucketing grid columns"),
      intField<S>("grid_rows", &S::grid_rows, 1, 64, "", "bucketing grid rows"),
      doubleField<S>("smoothing_sigma", &S::smoothing_sigma, 0.0, 20.0, "px",
                     "Gaussian smoothing before BRIEF (0: none)"),
      doubleField<S>("max_ratio", &S::max_ratio, 0.01, 1.0, "", "ratio test: best / second-best Hamming distance below this"),
      intField<S>("max_hamming", &S::max_hamming, 0, 256, "bits", "largest Hamming distance of a match"),
      boolField<S>("cross_check", &S::cross_check, "keep only mutual best matches"),
      intField<S>("min_fast_threshold", &S::min_fast_threshold, 1, 254, "grey levels",
                  "adaptive detection: when the corners at `fast_threshold` cannot fill `max_features` (or always, "
                  "with `track_unmatched`), every grid cell short of its share is detected again at this "
                  "threshold (at or above `fast_threshold`: off)"),
      enumField<S, MatchingMode>("matching", &S::matching,
                                 {{matchingModeName(MatchingMode::kGuided), MatchingMode::kGuided},
                                  {matchingModeName(MatchingMode::kGlobal), MatchingMode::kGlobal}},
                                 "`guided`: search each corner's match only near where the rotation prior puts it (global when "
                                 "there is no prior or too few are found); `global`: every descriptor against every other"),
      doubleField<S>("guided_radius_px", &S::guided_radius_px, 1.0, 10000.0, "px",
                     "guided search radius before the parallax and prior-uncertainty terms"),
      doubleField<S>("guided_radius_growth", &S::guided_radius_growth, 0.0, 10.0, "px/px",
                     "guided radius growth per pixel of distance from the principal point (parallax of near "
                     "points under forward motion)"),
      intField<S>("guided_min_matches", &S::guided_min_matches, 0, 100000, "",
                  "fewer guided matches fall back to global matching"),
      boolField<S>("subpixel_refinement", &S::subpixel_refinement,
                   "sub-pixel match positions: the previous corner's 11 x 11 patch aligned with the current image "
                   "by Lucas-Kanade (translation); off: integer FAST positions"),
      boolField<S>("track_unmatched", &S::track_unmatched,
                   "track the previous corners no descriptor match holds by patch alignment where their cell's "
                   "matches moved"),
      doubleField<S>("min_track_correlation", &S::min_track_correlation, -1.0, 1.0, "",
                     "a tracked corner's previous and current 11 x 11 patches must correlate (zero-mean "
                     "normalised) at least this much"),
      intField<S>("half_resolution_below", &S::half_resolution_below, 0, 100000, "",
                  "a pair with fewer matches (and tracks) is matched again at half resolution, whose estimate is "
                  "kept when it has at least as many inliers and a smaller covariance (motion blur); 0: never"),
  };
  return fields;
}

const char* matchingModeName(MatchingMode mode) { return mode == MatchingMode::kGlobal ? "global" : "guided"; }

std::string validateFrontEndSettings(const FrontEndSettings& s) { return checkRanges(s, frontEndSettingFields()); }

const std::vector<std::array<int8_t, 4>>& briefPattern() {
  // Pair i = {x1, y1, x2, y2} (offsets from the keypoint in px); descriptor bit i is set when the
  // smoothed intensity at p1 is lower than at p2: bit_i = I(x + x1, y + y1) < I(x + x2, y + y2).
  // Bit i lives in word i / 64 at bit position i % 64.
  static const std::vector<std::array<int8_t, 4>> pattern = buildBriefPattern();
  return pattern;
}

int hammingDistance(const BriefDescriptor& a, const BriefDescriptor& b) {
  return __builtin_popcountll(a[0] ^ b[0]) + __builtin_popcountll(a[1] ^ b[1]) +
         __builtin_popcountll(a[2] ^ b[2]) + __builtin_popcountll(a[3] ^ b[3]);
}

FeatureFrontEnd::FeatureFrontEnd(const FrontEndSettings& settings) : settings_(settings) {
  checkSettings(settings_);
}

std::vector<cv::Point2f> FeatureFrontEnd::detect(const cv::Mat& gray) const {
  std::vector<cv::Point2f> keypoints;
  detect(gray, &keypoints);
  return keypoints;
}

/// One detection's image and bucketing grid: which pixels may hold a corner, the cell of a
/// corner (through the workspace's per-column and per-row lookup), and where FAST must run to
/// find a run of cells' corners.
struct FeatureFrontEnd::DetectGrid {
  int width = 0, height = 0;  ///< image size [px]
  int cols = 0, rows = 0;     ///< bucketing grid
  int n_cells = 0;
  size_t budget = 0;  ///< max_features
  int per_cell = 0;   ///< each cell's share of the budget
  const int* cell_of_x = nullptr;  ///< grid column of each pixel column
  const int* cell_of_y = nullptr;  ///< first cell of the grid row of each pixel row
  /// Where FAST runs for the whole image: where a corner can be kept, widened by what the kept
  /// corners' tests read (their 3 px circle, and the scores of their neighbours for the non-max
  /// suppression, 1 px further): the same corners as on the whole image, without scoring the
  /// border strip that is dropped.
  cv::Rect fast_area;
  cv::Rect whole_image;

  /// Whether (x, y) keeps the border distance.
  bool inside(int x, int y) const {
    return !(x < kDetectBorder || y < kDetectBorder || x > width - 1 - kDetectBorder ||
             y > height - 1 - kDetectBorder);
  }
  /// Cell of a candidate key (FAST corners lie on whole pixels inside the image).
  int cellOf(uint64_t key) const { return cell_of_x[keyX(key)] + cell_of_y[keyY(key)]; }
  /// Cells [cx0, cx1] of grid row cy as cell_of_x and cell_of_y assign them: x in [x0, x1), y in
  /// [y0, y1).
  cv::Rect cellBounds(int cx0, int cx1, int cy) const {
    const int x0 = (cx0 * width + cols - 1) / cols, x1 = ((cx1 + 1) * width + cols - 1) / cols;
    const int y0 = (cy * height + rows - 1) / rows, y1 = ((cy + 1) * height + rows - 1) / rows;
    return cv::Rect(x0, y0, x1 - x0, y1 - y0);
  }
  /// Cells [cx0, cx1] of grid row cy widened by kFastMargin, inside `limit`: FAST there gives the
  /// cells' corners exactly as FAST on all of `limit` does.
  cv::Rect searchArea(int cx0, int cx1, int cy, const cv::Rect& limit) const {
    const cv::Rect cells = cellBounds(cx0, cx1, cy);
    return cv::Rect(cells.x - kFastMargin, cells.y - kFastMargin, cells.width + 2 * kFastMargin,
                    cells.height + 2 * kFastMargin) &
           limit;
  }
  /// Whether FAST can run on cell c's own search area (a cell too small for it keeps what the
  /// strong pass found).
  bool cellFits(int c) const { return fastFits(searchArea(c % cols, c % cols, c / cols, whole_image)); }
};

FeatureFrontEnd::DetectGrid FeatureFrontEnd::detectGrid(int width, int height) const {
  Workspace& w = work_;
  const int cols = settings_.grid_cols, rows = settings_.grid_rows;
  // Grid cell of each pixel column and row (cell = row cell * cols + column cell), looked up
  // rather than divided per corner; rebuilt only when the image size or the grid changes.
  if (w.cell_of_x.size() != static_cast<size_t>(width) || w.cell_of_y.size() != static_cast<size_t>(height) ||
      w.grid_size != cv::Size(cols, rows)) {
    w.cell_of_x.resize(width);
    w.cell_of_y.resize(height);
    for (int x = 0; x < width; ++x) w.cell_of_x[x] = std::min(cols - 1, x * cols / width);
    for (int y = 0; y < height; ++y) w.cell_of_y[y] = std::min(rows - 1, y * rows / height) * cols;
    w.grid_size = cv::Size(cols, rows);
  }
  DetectGrid grid;
  grid.width = width;
  grid.height = height;
  grid.cols = cols;
  grid.rows = rows;
  grid.n_cells = cols * rows;
  grid.budget = static_cast<size_t>(settings_.max_features);
  grid.per_cell = static_cast<int>(grid.budget / grid.n_cells);
  grid.cell_of_x = w.cell_of_x.data();
  grid.cell_of_y = w.cell_of_y.data();
  const int margin = kDetectBorder - kFastMargin;
  grid.fast_area = cv::Rect(margin, margin, width - 2 * margin, height - 2 * margin);
  grid.whole_image = cv::Rect(0, 0, width, height);
  return grid;
}

void FeatureFrontEnd::detect(const cv::Mat& gray, std::vector<cv::Point2f>* keypoints) const {
  checkImage(gray, "detect");
  checkSettings(settings_);  // setSettings() does not validate
  keypoints->clear();
  const int width = gray.cols, height = gray.rows;
  // No pixel can keep the border distance: nothing to detect (not an error).
  if (width < 2 * kDetectBorder + 1 || height < 2 * kDetectBorder + 1) return;

  Workspace& w = work_;
  const DetectGrid grid = detectGrid(width, height);
  // Adaptive threshold: when the strong corners cannot fill the budget, each cell short of its
  // share is detected again at the floor threshold, as ORB-SLAM does, so dim or low-contrast
  // regions still contribute corners while textured ones keep only their strong corners. When
  // they can, only tracking makes that second pass worth its cost: a weak corner that matching
  // needs FAST to find again in the next frame rarely matches (it would only take the place of a
  // strong one), while tracking needs no second detection, and corners spread over weak regions
  // are what separates rotation from translation near structure. FAST's score is the largest
  // threshold at which a pixel is still a corner, and non-max suppression compares scores, so a
  // cell's corners at the floor whose score reaches fast_threshold are its strong corners: a
  // cell holds its strong corners when they fill its share, else all its corners at the floor.
  const bool adaptive = settings_.min_fast_threshold < settings_.fast_threshold && grid.per_cell > 0;
  // With tracking every short cell is detected at the floor, so a cell the last frame found short
  // (and likely short again) is detected at the floor only: its strong corners come from that
  // pass. A wrong guess costs time, not corners: a skipped cell that turns out to hold its share
  // keeps only its strong corners, and a scanned one that falls short is detected again.
  const std::array<int, 7> short_key = {width, height, grid.cols, grid.rows, settings_.fast_threshold,
                                        settings_.min_fast_threshold, grid.per_cell};
  const bool guess_short = adaptive && settings_.track_unmatched && w.short_cells_key == short_key &&
                           w.short_cells.size() == static_cast<size_t>(grid.n_cells);
  w.corners.clear();
  w.candidates.clear();
  w.cell_count.assign(grid.n_cells, 0);
  if (!guess_short) {
    // The package's FAST detector: cv::FAST's corners and scores on the same area, in less time.
    fast_detector::detect(gray, grid.fast_area, settings_.fast_threshold, &w.fast_scratch, &w.corners);
    addCorners(grid, 0, -1, 0, grid.cols - 1);
  } else {
    detectCellsGuessedFull(gray, grid);
  }
  if (adaptive && (w.candidates.size() < grid.budget || settings_.track_unmatched)) {
    redetectShortCells(gray, grid);
  }
  if (adaptive && settings_.track_unmatched) {
    w.short_cells.resize(grid.n_cells);
    for (int c = 0; c < grid.n_cells; ++c) w.short_cells[c] = w.cell_count[c] < grid.per_cell;
    w.short_cells_key = short_key;
  } else {
    w.short_cells.clear();
  }
  selectCorners(grid, keypoints);
}

int FeatureFrontEnd::addCorners(const DetectGrid& grid, size_t from, int cy, int cx0, int cx1) const {
  Workspace& w = work_;
  int strong = 0;
  for (size_t k = from; k < w.corners.size(); ++k) {
    const cv::Point3i& corner = w.corners[k];
    if (!grid.inside(corner.x, corner.y)) continue;
    const uint64_t key = candidateKey(corner.z, corner.x, corner.y);
    const int cell = grid.cellOf(key);
    // In the margin of the cells FAST ran for.
    if (cy >= 0 && (cell / grid.cols != cy || cell % grid.cols < cx0 || cell % grid.cols > cx1)) continue;
    w.candidates.push_back(key);
    ++w.cell_count[cell];
    strong += corner.z >= settings_.fast_threshold;
  }
  return strong;
}

void FeatureFrontEnd::detectCellsGuessedFull(const cv::Mat& gray, const DetectGrid& grid) const {
  Workspace& w = work_;
  // Runs of cells guessed full, one grid row at a time.
  auto skipped = [&](int c) { return w.short_cells[c] && grid.cellFits(c); };
  for (int cy = 0; cy < grid.rows; ++cy) {
    for (int cx = 0; cx < grid.cols;) {
      if (skipped(cy * grid.cols + cx)) {
        ++cx;
        continue;
      }
      int end = cx;
      while (end + 1 < grid.cols && !skipped(cy * grid.cols + end + 1)) ++end;
      const cv::Rect area = grid.searchArea(cx, end, cy, grid.fast_area);
      if (fastFits(area)) {
        const size_t from = w.corners.size();
        fast_detector::detect(gray, area, settings_.fast_threshold, &w.fast_scratch, &w.corners);
        addCorners(grid, from, cy, cx, end);
      }
      cx = end + 1;
    }
  }
}

void FeatureFrontEnd::redetectShortCells(const cv::Mat& gray, const DetectGrid& grid) const {
  Workspace& w = work_;
  const int cols = grid.cols;
  // The short cells' strong corners are replaced by everything found at the floor.
  w.redetect.assign(grid.n_cells, 0);
  for (int c = 0; c < grid.n_cells; ++c) w.redetect[c] = w.cell_count[c] < grid.per_cell && grid.cellFits(c);
  w.candidates.erase(std::remove_if(w.candidates.begin(), w.candidates.end(),
                                    [&](uint64_t key) { return w.redetect[grid.cellOf(key)] != 0; }),
                     w.candidates.end());
  for (int cell = 0; cell < grid.n_cells; ++cell) {
    if (!w.redetect[cell]) continue;
    w.corners.clear();
    fast_detector::detect(gray, grid.searchArea(cell % cols, cell % cols, cell / cols, grid.whole_image),
                          settings_.min_fast_threshold, &w.fast_scratch, &w.corners);
    const size_t first = w.candidates.size();
    const int strong = addCorners(grid, 0, cell / cols, cell % cols, cell % cols);
    w.cell_count[cell] = strong;
    if (strong >= grid.per_cell) {
      // A cell guessed short that holds its share: its strong corners only.
      w.candidates.erase(std::remove_if(w.candidates.begin() + static_cast<std::ptrdiff_t>(first),
                                        w.candidates.end(),
                                        [&](uint64_t key) {
                                          return static_cast<int>(key >> 32) < settings_.fast_threshold;
                                        }),
                         w.candidates.end());
    }
  }
}

void FeatureFrontEnd::selectCorners(const DetectGrid& grid, std::vector<cv::Point2f>* keypoints) const {
  Workspace& w = work_;
  // Bucketing: an equal share per cell first, so texture-rich regions cannot take the whole
  // budget; the unused share of sparse cells then goes to the strongest corners left anywhere.
  // One sort, strongest first: a cell's share is its first corners in that order, the leftovers
  // stay in that order for the fill, and the selection comes out strongest first.
  sortKeysDescending(&w.candidates, &w.sort_scratch);
  const size_t n = w.candidates.size();
  w.chosen.assign(n, 0);
  w.cell_count.assign(grid.n_cells, 0);
  size_t selected = 0;
  for (size_t i = 0; i < n; ++i) {
    int& taken = w.cell_count[grid.cellOf(w.candidates[i])];
    if (taken < grid.per_cell) {
      ++taken;
      w.chosen[i] = 1;
      ++selected;
    }
  }
  for (size_t i = 0; i < n && selected < grid.budget; ++i) {
    if (w.chosen[i]) continue;
    w.chosen[i] = 1;
    ++selected;
  }

  keypoints->reserve(selected);
  for (size_t i = 0; i < n; ++i) {
    if (w.chosen[i]) {
      keypoints->emplace_back(static_cast<float>(keyX(w.candidates[i])),
                              static_cast<float>(keyY(w.candidates[i])));
    }
  }
}

FrameFeatures FeatureFrontEnd::describe(const cv::Mat& gray,
                                        const std::vector<cv::Point2f>& keypoints) const {
  FrameFeatures features;
  describe(gray, keypoints, &features);
  return features;
}

void FeatureFrontEnd::describe(const cv::Mat& gray, const std::vector<cv::Point2f>& keypoints,
                               FrameFeatures* features) const {
  checkImage(gray, "describe");
  checkSettings(settings_);
  features->keypoints.clear();
  features->descriptors.clear();
  const int width = gray.cols, height = gray.rows;
  if (keypoints.empty() || width < 2 * kBriefHalfPatch + 1 || height < 2 * kBriefHalfPatch + 1) {
    return;
  }

  cv::Mat smoothed;
  if (settings_.smoothing_sigma > 0.0) {
    // Kernel covering +-3 sigma, odd.
    const int ksize = 2 * static_cast<int>(std::ceil(3.0 * settings_.smoothing_sigma)) + 1;
    // The default sigma's kernel: the package's filter, the same result as cv::GaussianBlur in
    // about two thirds of the time or less (with AVX2). Its weights are read from OpenCV whenever
    // sigma changes.
    static const fixed_point_gaussian::Filter gaussian = fixed_point_gaussian::selectFilter();
    if (ksize == fixed_point_gaussian::kTaps && work_.gaussian_sigma != settings_.smoothing_sigma) {
      work_.gaussian_sigma = settings_.smoothing_sigma;
      work_.gaussian_exact =
          fixed_point_gaussian::readWeights(settings_.smoothing_sigma, gaussian, &work_.gaussian_weights);
    }
    if (ksize == fixed_point_gaussian::kTaps && work_.gaussian_exact) {
      const size_t buffer_size = fixed_point_gaussian::bufferSize(width, height);
      if (work_.smoothing.size() < buffer_size) work_.smoothing.resize(buffer_size);
      work_.smoothed.create(height, width, CV_8UC1);
      gaussian(gray, work_.gaussian_weights, &work_.smoothed, work_.smoothing.data());
    } else {
      // Isolated: a view into a larger image is filtered as an image of its own, as the
      // package's filter does.
      cv::GaussianBlur(gray, work_.smoothed, cv::Size(ksize, ksize), settings_.smoothing_sigma,
                       settings_.smoothing_sigma, cv::BORDER_REFLECT_101 | cv::BORDER_ISOLATED);
    }
    smoothed = work_.smoothed;
  } else {
    smoothed = gray;
  }

  // The pattern as 32-bit byte offsets in the smoothed image, computed once per call. They reach
  // kBriefHalfPatch rows either way; a row step too large for them (no real image) takes the plain
  // loop below, which indexes in 64 bits, for every corner (and the offsets go unused).
  const std::ptrdiff_t step = static_cast<std::ptrdiff_t>(smoothed.step[0]);
  const bool offsets_fit = step <= std::numeric_limits<int32_t>::max() / (2 * kBriefHalfPatch + 2);
  static const brief_kernels::TestKernel tests = brief_kernels::selectKernel();
  const brief_kernels::TestOffsets offsets = brief_kernels::testOffsets(offsets_fit ? step : 0);

  features->keypoints.reserve(keypoints.size());
  Workspace& w = work_;
  w.describe_rows.clear();
  for (const cv::Point2f& kp : keypoints) {
    if (!std::isfinite(kp.x) || !std::isfinite(kp.y)) continue;
    const long x = std::lround(kp.x), y = std::lround(kp.y);
    if (x < kBriefHalfPatch || y < kBriefHalfPatch || x > width - 1 - kBriefHalfPatch ||
        y > height - 1 - kBriefHalfPatch) {
      continue;
    }
    features->keypoints.push_back(kp);
    w.describe_rows.push_back(static_cast<int>(y));
  }
  // The descriptors are computed in image-row order (a counting sort of the keypoints by row) and
  // stored in the keypoints' order: consecutive keypoints then read patches whose rows are still
  // in cache, which takes about a fifth less time than the strength order.
  const size_t n = features->keypoints.size();
  features->descriptors.resize(n);
  orderByRow(n, height, [&](size_t k) { return w.describe_rows[k]; }, &w.row_start, &w.row_order);
  for (const int k : w.row_order) {
    const long x = std::lround(features->keypoints[k].x), y = w.describe_rows[k];
    const uint8_t* centre = smoothed.ptr<uint8_t>(static_cast<int>(y)) + x;
    // A vector kernel may read a few bytes past a patch pixel: those must lie inside the image's
    // memory, which holds unless the patch ends within that many bytes of the end of the image's
    // last row.
    if (offsets_fit &&
        (y + kBriefHalfPatch < height - 1 || x + kBriefHalfPatch + brief_kernels::kBytesPastPatch < width)) {
      features->descriptors[k] = tests(centre, step, offsets);
      continue;
    }
    // Bit i = I(p1) < I(p2), one test at a time.
    BriefDescriptor descriptor{};
    const auto& pattern = briefPattern();
    for (int i = 0; i < 256; ++i) {
      const uint8_t a = centre[pattern[i][1] * step + pattern[i][0]];
      const uint8_t b = centre[pattern[i][3] * step + pattern[i][2]];
      descriptor[i / 64] |= static_cast<uint64_t>(a < b) << (i % 64);
    }
    features->descriptors[k] = descriptor;
  }
}

namespace {

void checkFeatures(const FrameFeatures& previous, const FrameFeatures& current, const char* where) {
  if (previous.keypoints.size() != previous.descriptors.size() ||
      current.keypoints.size() != current.descriptors.size()) {
    throw std::invalid_argument(std::string("FeatureFrontEnd::") + where +
                                ": keypoints and descriptors differ in count (use describe())");
  }
}

/// Ratio test, distance limit and cross-check on the kernels' row and column bests.
/// `current_index` maps a column to the current keypoint's index (nullptr: the same).
void collectMatches(const FrontEndSettings& settings, int n_prev, const int* row_best,
                    const int* row_best_d, const int* row_second_d, const int* col_best,
                    const int* current_index, std::vector<FeatureMatch>* matches) {
  for (int i = 0; i < n_prev; ++i) {
    const int j = row_best[i];
    const int best = row_best_d[i];
    if (j == hamming::kNoMatch || best > settings.max_hamming) continue;
    // Ratio test; with a single candidate there is no second best and nothing to be ambiguous with.
    const int second = row_second_d[i];
    if (second != std::numeric_limits<int>::max() && !(best < settings.max_ratio * second)) {
      continue;
    }
    if (settings.cross_check && col_best[j] != i) continue;
    matches->push_back({i, current_index ? current_index[j] : j, best});
  }
}

}  // namespace

std::vector<FeatureMatch> FeatureFrontEnd::match(const FrameFeatures& previous,
                                                 const FrameFeatures& current) const {
  std::vector<FeatureMatch> matches;
  match(previous, current, &matches);
  return matches;
}

void FeatureFrontEnd::match(const FrameFeatures& previous, const FrameFeatures& current,
                            std::vector<FeatureMatch>* matches) const {
  checkSettings(settings_);
  checkFeatures(previous, current, "match");
  matches->clear();
  const int n_prev = static_cast<int>(previous.descriptors.size());
  const int n_cur = static_cast<int>(current.descriptors.size());
  if (n_prev == 0 || n_cur == 0) return;

  Workspace& w = work_;
  w.row_best.resize(n_prev);
  w.row_best_d.resize(n_prev);
  w.row_second_d.resize(n_prev);
  w.col_best.resize(n_cur);
  w.col_best_d.resize(n_cur);
  const hamming::SearchTables tables{w.row_best.data(), w.row_best_d.data(), w.row_second_d.data(),
                                     w.col_best.data(), w.col_best_d.data()};
  hamming::selectBruteForceKernel()(previous.descriptors.data(), n_prev, current.descriptors.data(), n_cur,
                                    tables);
  collectMatches(settings_, n_prev, w.row_best.data(), w.row_best_d.data(), w.row_second_d.data(),
                 w.col_best.data(), nullptr, matches);
}

void FeatureFrontEnd::predict(const CameraModel& camera, const Eigen::Matrix3d& rotation,
                              double uncertainty_rad,
                              const std::vector<Eigen::Vector3d>& previous_bearings,
                              MatchPrediction* prediction) const {
  checkSettings(settings_);
  if (!rotation.allFinite()) throw std::invalid_argument("FeatureFrontEnd::predict: non-finite rotation");
  if (!std::isfinite(uncertainty_rad) || uncertainty_rad < 0.0) {
    throw std::invalid_argument("FeatureFrontEnd::predict: uncertainty must be finite and >= 0");
  }
  const size_t n = previous_bearings.size();
  prediction->positions.resize(n);
  prediction->radii.resize(n);
  // b_prev ~ R b_cur, so a far point seen along b_prev is seen along R^T b_prev now.
  const Eigen::Matrix3d to_current = rotation.transpose();
  const double focal = std::max(camera.fx(), camera.fy());
  const double base = settings_.guided_radius_px + uncertainty_rad * focal;
  const double width = camera.width(), height = camera.height();
  for (size_t i = 0; i < n; ++i) {
    const Eigen::Vector2d p = camera.project(to_current * previous_bearings[i]);
    // sqrt of the sum of squares, not std::hypot: no overflow is possible at pixel scale, and
    // hypot's care for it cost as much as the projection.
    const double dx = p.x() - camera.cx(), dy = p.y() - camera.cy();
    const double radius = base + settings_.guided_radius_growth * std::sqrt(dx * dx + dy * dy);
    // Outside the image by more than the radius, behind the camera or not projectable: no search.
    const bool usable = p.allFinite() && p.x() > -radius && p.y() > -radius &&
                        p.x() < width - 1 + radius && p.y() < height - 1 + radius;
    prediction->positions[i] = usable ? cv::Point2f(static_cast<float>(p.x()), static_cast<float>(p.y()))
                                      : cv::Point2f(0.f, 0.f);
    prediction->radii[i] = usable ? static_cast<float>(radius) : -1.0f;
  }
}

void FeatureFrontEnd::matchGuided(const FrameFeatures& previous, const FrameFeatures& current,
                                  const MatchPrediction& prediction,
                                  std::vector<FeatureMatch>* matches) const {
  checkSettings(settings_);
  checkFeatures(previous, current, "matchGuided");
  if (prediction.positions.size() != previous.keypoints.size() ||
      prediction.radii.size() != previous.keypoints.size()) {
    throw std::invalid_argument(
        "FeatureFrontEnd::matchGuided: the prediction must hold one position and radius per "
        "previous keypoint (use predict())");
  }
  matches->clear();
  const int n_prev = static_cast<int>(previous.descriptors.size());
  const int n_cur = static_cast<int>(current.descriptors.size());
  if (n_prev == 0 || n_cur == 0) return;

  // Grid index of the current keypoints. The cell size only trades grid rows visited against
  // keypoints tested; the result does not depend on it.
  Workspace& w = work_;
  constexpr float kCellSize = 16.0f;
  const hamming::GuidedGrid grid = hamming::sortIntoGrid(
      current.keypoints, current.descriptors, kCellSize,
      {&w.grid_start, &w.grid_cursor, &w.grid_items, &w.grid_inside, &w.grid_points, &w.grid_descriptors});

  w.row_best.resize(n_prev);
  w.row_best_d.resize(n_prev);
  w.row_second_d.resize(n_prev);
  w.col_best.resize(n_cur);
  w.col_best_d.resize(n_cur);
  const hamming::SearchTables tables{w.row_best.data(), w.row_best_d.data(), w.row_second_d.data(),
                                     w.col_best.data(), w.col_best_d.data()};
  hamming::selectGuidedKernel()(previous.descriptors.data(), n_prev, prediction.positions.data(),
                                prediction.radii.data(), grid, tables);
  collectMatches(settings_, n_prev, w.row_best.data(), w.row_best_d.data(), w.row_second_d.data(),
                 w.col_best.data(), w.grid_items.data(), matches);
}

namespace {

/// Aligns the (2 kRefineHalfWindow + 1)^2 patch of `previous_gray` around the previous corner `p`
/// with `current_gray` around the whole pixel (qx, qy) (inverse-compositional Lucas-Kanade, at
/// most kMaxShift px per axis; see refineMatches()). On success *position is where p's content
/// lies in the current image. False when the patch or its search area leaves the image, the patch
/// has no corner structure, or the alignment leaves the search box. `patch` is working space.
bool alignCorner(const cv::Mat& previous_gray, const cv::Mat& current_gray, const cv::Point2f& p, int qx, int qy,
                 patch_alignment::TemplateKernel build_template, patch_alignment::CorrelationKernel correlate,
                 patch_alignment::PatchTemplate* patch, cv::Point2d* position) {
  using patch_alignment::kMaxShift;
  using patch_alignment::kStride;
  constexpr int h = kRefineHalfWindow;
  // A few more steps than inverse-compositional Lucas-Kanade usually needs: once the shift stays
  // in one pixel cell a step costs no image access (alignPatch).
  constexpr int kIterations = 10;
  constexpr double kConverged = 0.01;  // px: an update this small ends the iterations
  const int width = current_gray.cols, height = current_gray.rows;
  const int px = static_cast<int>(std::lround(p.x)), py = static_cast<int>(std::lround(p.y));
  // The template and its central differences read one pixel around the patch and a row's
  // padding to the right; the current patch moves by up to kMaxShift, plus one for the bilinear
  // neighbour.
  if (px - h - 1 < 0 || py - h - 1 < 0 || px - h + kStride >= width || py + h + 1 >= height ||
      qx - h - kMaxShift < 0 || qy - h - kMaxShift < 0 || qx - h + kMaxShift + 1 + kStride > width ||
      qy + h + kMaxShift + 1 >= height) {
    return false;
  }
  build_template(previous_gray.ptr<uint8_t>(py - h) + px - h, previous_gray.step[0], patch);
  double dx = 0.0, dy = 0.0;
  if (!patch_alignment::alignPatch(*patch, current_gray.ptr<uint8_t>(qy - h) + qx - h, current_gray.step[0],
                                   correlate, kIterations, kConverged, &dx, &dy)) {
    return false;
  }
  // p sits at the rounded template centre plus its own fraction.
  *position = cv::Point2d(qx + dx + (p.x - px), qy + dy + (p.y - py));
  return true;
}

}  // namespace

void FeatureFrontEnd::refineMatches(const cv::Mat& previous_gray, const cv::Mat& current_gray,
                                    const FrameFeatures& previous, const FrameFeatures& current,
                                    std::vector<FeatureMatch>* matches) const {
  checkSettings(settings_);
  checkFeatures(previous, current, "refineMatches");
  for (FeatureMatch& m : *matches) m.offset = cv::Point2f(0.f, 0.f);
  if (!settings_.subpixel_refinement || matches->empty()) return;
  checkImage(previous_gray, "refineMatches");
  checkImage(current_gray, "refineMatches");
  if (previous_gray.size() != current_gray.size()) {
    throw std::invalid_argument("FeatureFrontEnd::refineMatches: the images differ in size");
  }
  const patch_alignment::TemplateKernel build_template = patch_alignment::templateKernel();
  const patch_alignment::CorrelationKernel correlate = patch_alignment::correlationKernel();
  patch_alignment::PatchTemplate patch;
  Workspace& w = work_;
  orderByRow(matches->size(), previous_gray.rows,
             [&](size_t k) { return pixelRow(previous.keypoints[(*matches)[k].previous]); }, &w.row_start,
             &w.row_order);
  for (const int k : w.row_order) {
    FeatureMatch& m = (*matches)[k];
    const cv::Point2f p = previous.keypoints[m.previous], q = current.keypoints[m.current];
    cv::Point2d aligned;
    if (alignCorner(previous_gray, current_gray, p, static_cast<int>(std::lround(q.x)),
                    static_cast<int>(std::lround(q.y)), build_template, correlate, &patch, &aligned)) {
      m.offset = cv::Point2f(static_cast<float>(aligned.x - q.x), static_cast<float>(aligned.y - q.y));
    }
  }
}

namespace {

/// Zero-mean normalised cross-correlation of the kRefineHalfWindow patch of `previous` centred on
/// the pixel (px, py) with the patch of `current` centred on (x, y), sampled bilinearly (to
/// 1/patch_alignment::kBilinearOne px); -1 when either patch is flat. The caller has checked that
/// both patches and the row and column after the current one lie inside their images.
double patchCorrelation(const cv::Mat& previous, int px, int py, const cv::Mat& current, double x, double y,
                        patch_alignment::MomentsKernel moments) {
  constexpr int h = kRefineHalfWindow;
  const double left = x - h, top = y - h;
  const int x0 = static_cast<int>(std::floor(left)), y0 = static_cast<int>(std::floor(top));
  const int ax = static_cast<int>(std::lround((left - x0) * patch_alignment::kBilinearOne));
  const int ay = static_cast<int>(std::lround((top - y0) * patch_alignment::kBilinearOne));
  return patch_alignment::zeroMeanCorrelation(moments(previous.ptr<uint8_t>(py - h) + px - h, previous.step[0],
                                                      current.ptr<uint8_t>(y0) + x0, current.step[0], ax, ay));
}

}  // namespace

namespace {

// Fewer matches than this say nothing about how a region moved.
constexpr size_t kMinTrackMoves = 3;

/// The cell of the cols x rows bucketing grid over an image of `size` that holds `p` (positions
/// outside the image count as the nearest cell).
int trackCell(const cv::Point2f& p, const cv::Size& size, int cols, int rows) {
  const int cx = std::clamp(static_cast<int>(p.x * cols / size.width), 0, cols - 1);
  const int cy = std::clamp(static_cast<int>(p.y * rows / size.height), 0, rows - 1);
  return cy * cols + cx;
}

}  // namespace

void FeatureFrontEnd::groupMovesByCell(const FrameFeatures& previous, const FrameFeatures& current,
                                       const std::vector<FeatureMatch>& matches, const cv::Size& size) const {
  Workspace& w = work_;
  const int cols = settings_.grid_cols, rows = settings_.grid_rows, cells = cols * rows;
  const size_t n_previous = previous.keypoints.size();
  w.matched.assign(n_previous, 0);
  w.track_cell_start.assign(cells + 1, 0);
  for (const FeatureMatch& m : matches) {
    if (m.previous < 0 || static_cast<size_t>(m.previous) >= n_previous || m.current < 0 ||
        static_cast<size_t>(m.current) >= current.keypoints.size()) {
      throw std::invalid_argument("FeatureFrontEnd::trackUnmatched: a match refers to no keypoint (" +
                                  std::to_string(m.previous) + " -> " + std::to_string(m.current) + ")");
    }
    w.matched[m.previous] = 1;
    ++w.track_cell_start[trackCell(previous.keypoints[m.previous], size, cols, rows) + 1];
  }
  for (int c = 0; c < cells; ++c) w.track_cell_start[c + 1] += w.track_cell_start[c];
  w.track_cell_cursor.assign(w.track_cell_start.begin(), w.track_cell_start.end() - 1);
  w.track_moves.resize(matches.size());
  for (const FeatureMatch& m : matches) {
    const cv::Point2f p = previous.keypoints[m.previous];
    w.track_moves[w.track_cell_cursor[trackCell(p, size, cols, rows)]++] = current.keypoints[m.current] + m.offset - p;
  }
}

void FeatureFrontEnd::medianMovesByCell() const {
  Workspace& w = work_;
  const int cols = settings_.grid_cols, rows = settings_.grid_rows;
  // Median displacement per cell: its own matches, else those of the 3 x 3 cells around it, else
  // all of them (a median per axis: robust to the wrong matches among them).
  const auto medianMove = [&](int c0x, int c1x, int c0y, int c1y) -> std::pair<bool, cv::Point2f> {
    w.median_x.clear();
    w.median_y.clear();
    for (int cy = std::max(0, c0y); cy <= std::min(rows - 1, c1y); ++cy) {
      for (int cx = std::max(0, c0x); cx <= std::min(cols - 1, c1x); ++cx) {
        const int c = cy * cols + cx;
        for (int k = w.track_cell_start[c]; k < w.track_cell_start[c + 1]; ++k) {
          w.median_x.push_back(w.track_moves[k].x);
          w.median_y.push_back(w.track_moves[k].y);
        }
      }
    }
    const size_t count = w.median_x.size();
    if (count < kMinTrackMoves) return {false, {}};
    // The upper median of an even count.
    return {true, cv::Point2f(static_cast<float>(passes::selectKth(w.median_x.data(), count, count / 2)),
                              static_cast<float>(passes::selectKth(w.median_y.data(), count, count / 2)))};
  };
  const cv::Point2f global_move = medianMove(0, cols - 1, 0, rows - 1).second;
  w.cell_moves.resize(cols * rows);
  for (int cy = 0; cy < rows; ++cy) {
    for (int cx = 0; cx < cols; ++cx) {
      auto own = medianMove(cx, cx, cy, cy);
      if (!own.first) own = medianMove(cx - 1, cx + 1, cy - 1, cy + 1);
      w.cell_moves[cy * cols + cx] = own.first ? own.second : global_move;
    }
  }
}

void FeatureFrontEnd::trackUnmatched(const cv::Mat& previous_gray, const cv::Mat& current_gray,
                                     const FrameFeatures& previous, const FrameFeatures& current,
                                     const std::vector<FeatureMatch>& matches,
                                     std::vector<TrackedCorner>* tracks) const {
  checkSettings(settings_);
  checkFeatures(previous, current, "trackUnmatched");
  tracks->clear();
  if (!settings_.track_unmatched || matches.size() < kMinTrackMoves) return;
  checkImage(previous_gray, "trackUnmatched");
  checkImage(current_gray, "trackUnmatched");
  if (previous_gray.size() != current_gray.size()) {
    throw std::invalid_argument("FeatureFrontEnd::trackUnmatched: the images differ in size");
  }
  Workspace& w = work_;
  const cv::Size size = current_gray.size();
  groupMovesByCell(previous, current, matches, size);
  medianMovesByCell();

  const patch_alignment::TemplateKernel build_template = patch_alignment::templateKernel();
  const patch_alignment::CorrelationKernel correlate = patch_alignment::correlationKernel();
  const patch_alignment::MomentsKernel moments = patch_alignment::momentsKernel();
  patch_alignment::PatchTemplate patch;
  // Tracked in row order (cached rows), listed in corner order.
  const size_t n_previous = previous.keypoints.size();
  w.track_found.assign(n_previous, 0);
  w.track_positions.resize(n_previous);
  orderByRow(n_previous, previous_gray.rows, [&](size_t k) { return pixelRow(previous.keypoints[k]); },
             &w.row_start, &w.row_order);
  for (const int i : w.row_order) {
    if (w.matched[i]) continue;
    const cv::Point2f p = previous.keypoints[i];
    const cv::Point2f predicted = p + w.cell_moves[trackCell(p, size, settings_.grid_cols, settings_.grid_rows)];
    // The whole pixel the search starts from: the prediction less the corner's own fraction, which
    // alignCorner adds back.
    const int qx = static_cast<int>(std::lround(predicted.x - (p.x - std::lround(p.x))));
    const int qy = static_cast<int>(std::lround(predicted.y - (p.y - std::lround(p.y))));
    cv::Point2d aligned;
    if (!alignCorner(previous_gray, current_gray, p, qx, qy, build_template, correlate, &patch, &aligned)) continue;
    const int px = static_cast<int>(std::lround(p.x)), py = static_cast<int>(std::lround(p.y));
    if (patchCorrelation(previous_gray, px, py, current_gray, aligned.x - (p.x - px), aligned.y - (p.y - py),
                         moments) < settings_.min_track_correlation) {
      continue;
    }
    w.track_found[i] = 1;
    w.track_positions[i] = cv::Point2f(static_cast<float>(aligned.x), static_cast<float>(aligned.y));
  }
  for (size_t i = 0; i < n_previous; ++i) {
    if (w.track_found[i]) tracks->push_back({static_cast<int>(i), w.track_positions[i]});
  }
}

}  // namespace visual_gyro
