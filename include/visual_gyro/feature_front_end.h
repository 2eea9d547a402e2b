// Feature front end: FAST corners spread over the image, BRIEF-256 descriptors, Hamming matching
// between consecutive frames.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "visual_gyro/camera_model.h"
#include "visual_gyro/setting_field.h"

namespace visual_gyro {

/// A 256-bit BRIEF descriptor.
using BriefDescriptor = std::array<uint64_t, 4>;

/// How consecutive frames are matched.
enum class MatchingMode {
  kGuided,  ///< around where the rotation prior predicts each corner (global without a prior)
  kGlobal,  ///< every descriptor against every other
};
/// The setting's text of a mode: "guided" or "global".
const char* matchingModeName(MatchingMode mode);

/// Settings of the front end. Ranges, units and docs: frontEndSettingFields().
struct FrontEndSettings {
  int fast_threshold = 20;      ///< FAST intensity threshold (grey levels)
  /// Adaptive detection: when the corners at fast_threshold cannot fill max_features (or always,
  /// with track_unmatched), every grid cell with fewer corners than its share is detected again
  /// with this lower threshold (grey levels; >= fast_threshold turns it off).
  int min_fast_threshold = 5;
  int max_features = 1500;      ///< at most this many corners per frame
  int grid_cols = 8;            ///< bucketing grid: corners are spread over cols x rows cells
  int grid_rows = 6;
  double smoothing_sigma = 2.0;  ///< Gaussian smoothing before BRIEF [px]
  double max_ratio = 0.8;        ///< ratio test: best / second-best distance must be below
  int max_hamming = 64;          ///< matches with a larger Hamming distance are dropped
  bool cross_check = true;       ///< keep only mutual best matches
  /// kGuided: compare each previous descriptor only with current ones near where the rotation
  /// prior predicts it (global matching when there is no prior or guided finds too few);
  /// kGlobal: every descriptor against every other.
  MatchingMode matching = MatchingMode::kGuided;
  /// Guided search radius around the predicted position [px] before the parallax and
  /// prior-uncertainty terms.
  double guided_radius_px = 20.0;
  /// Radius growth per pixel of distance between the prediction and the principal point
  /// (covers the radial parallax of near points under forward or backward motion) [px/px].
  double guided_radius_growth = 0.1;
  /// Guided matching with fewer matches than this falls back to global matching.
  int guided_min_matches = 30;
  /// Sub-pixel match positions: each match's current corner is moved by a translational
  /// Lucas-Kanade alignment of the previous corner's patch (refineMatches()). Off: integer
  /// FAST positions (cheaper, less accurate on blurred images; the estimator then uses its
  /// covariance model for integer positions).
  bool subpixel_refinement = true;
  /// Tracking of unmatched corners: each previous corner that found no descriptor match is looked
  /// for by patch alignment where its cell's matches say it moved (trackUnmatched()).
  bool track_unmatched = true;
  /// A tracked corner is kept when the zero-mean normalised cross-correlation of its previous and
  /// current 11 x 11 patches reaches this.
  double min_track_correlation = 0.8;
  /// A pair that gives fewer matches than this (descriptor matches and tracks) at full resolution
  /// is matched again on both images at half resolution (heavy motion blur leaves few corners at
  /// full resolution and many at half); the pipeline keeps the half-resolution estimate when the
  /// full-resolution one is invalid, or when it has at least as many inliers and a smaller
  /// covariance. 0: never (VisualGyro::processFrame).
  int half_resolution_below = 100;
};

/// Every front-end setting with its range, unit and doc (see setting_field.h).
const std::vector<SettingField<FrontEndSettings>>& frontEndSettingFields();

/// "" when every setting is in its range, else what is wrong.
std::string validateFrontEndSettings(const FrontEndSettings& settings);

/// BRIEF sampling pattern: 256 point pairs in a 31x31 patch centred on the corner (offsets in
/// [-15, 15]). Drawn once from an isotropic Gaussian (sigma = 31 / 5, Calonder et al. 2010 "G II")
/// with a fixed splitmix64/Box-Muller sequence (seed 0x62726965665F5F31), clamped to the patch, so it
/// is identical on every platform. pairs[i] = {x1, y1, x2, y2}; bit i is 1 when I(p1) < I(p2).
const std::vector<std::array<int8_t, 4>>& briefPattern();
/// Half size of the BRIEF patch (15): keypoints closer than this to the border are dropped.
constexpr int kBriefHalfPatch = 15;

/// Features of one frame.
struct FrameFeatures {
  std::vector<cv::Point2f> keypoints;          ///< pixel coordinates
  std::vector<BriefDescriptor> descriptors;    ///< one per keypoint
};

/// One match: index into the previous and current frame's keypoints.
struct FeatureMatch {
  int previous = -1;
  int current = -1;
  int distance = 0;  ///< Hamming distance
  /// Sub-pixel correction set by refineMatches(): the matched current position is
  /// current keypoint + offset (zero when not refined).
  cv::Point2f offset{0.f, 0.f};
};

/// A previous corner found in the current image by patch alignment (trackUnmatched()), without a
/// current keypoint of its own.
struct TrackedCorner {
  int previous = -1;      ///< index into the previous frame's keypoints
  cv::Point2f position;   ///< where its patch lies in the current image [px]
};

/// Half size of the patch that refineMatches() aligns (an 11 x 11 window).
constexpr int kRefineHalfWindow = 5;

/// Number of differing bits.
int hammingDistance(const BriefDescriptor& a, const BriefDescriptor& b);

/// Where each previous keypoint is expected in the current image, and how far from there its match
/// may lie. radii[i] < 0: keypoint i cannot be predicted (leaves the view); it is not matched.
struct MatchPrediction {
  std::vector<cv::Point2f> positions;  ///< predicted pixel in the current image
  std::vector<float> radii;            ///< search radius [px]
};

/// FAST + grid bucketing + BRIEF + matching. Its working buffers are reused from call to call (no
/// allocation once the frame size and counts have settled), so one instance must not be used
/// from several threads at once.
class FeatureFrontEnd {
 public:
  explicit FeatureFrontEnd(const FrontEndSettings& settings = FrontEndSettings());

  /// FAST corners (non-max suppressed), strongest first within each grid cell, at most
  /// max_features in all, none closer than kBriefHalfPatch + 1 to the border. `gray` is CV_8UC1.
  /// Throws std::invalid_argument for an empty or non-8-bit image.
  /// When the corners at fast_threshold cannot fill max_features, or always when track_unmatched
  /// is on, cells with fewer corners than their share (max_features / cells) are detected again at
  /// min_fast_threshold, so dim and low-contrast regions still get corners.
  std::vector<cv::Point2f> detect(const cv::Mat& gray) const;
  /// detect() into `keypoints` (its capacity is reused).
  void detect(const cv::Mat& gray, std::vector<cv::Point2f>* keypoints) const;
  /// BRIEF-256 of each keypoint on the smoothed image; keypoints too near the border are removed
  /// (so keypoints and descriptors stay aligned).
  FrameFeatures describe(const cv::Mat& gray, const std::vector<cv::Point2f>& keypoints) const;
  /// describe() into `features` (its capacity is reused).
  void describe(const cv::Mat& gray, const std::vector<cv::Point2f>& keypoints,
                FrameFeatures* features) const;
  /// Brute-force Hamming matching previous -> current with ratio test, distance limit and
  /// cross-check.
  std::vector<FeatureMatch> match(const FrameFeatures& previous, const FrameFeatures& current) const;
  /// match() into `matches` (its capacity is reused).
  void match(const FrameFeatures& previous, const FrameFeatures& current,
             std::vector<FeatureMatch>* matches) const;

  /// Predicts each previous keypoint in the current image under the rotation `rotation`
  /// (b_prev ~ R b_cur, camera optical frame): the infinite homography, through the camera model
  /// so distortion is handled. Radius = guided_radius_px + guided_radius_growth * |prediction -
  /// principal point| + uncertainty_rad * focal length. `previous_bearings` are the unit bearings
  /// of the previous keypoints. Throws std::invalid_argument for a non-finite rotation or
  /// uncertainty.
  void predict(const CameraModel& camera, const Eigen::Matrix3d& rotation, double uncertainty_rad,
               const std::vector<Eigen::Vector3d>& previous_bearings,
               MatchPrediction* prediction) const;
  /// Guided matching: previous keypoint i is compared only with the current keypoints within
  /// prediction.radii[i] of prediction.positions[i] (found through a grid index). The ratio test
  /// and the cross-check keep their meaning among these candidates: best against second best in
  /// the window, and mutual best over the previous keypoints whose windows hold the current one.
  void matchGuided(const FrameFeatures& previous, const FrameFeatures& current,
                   const MatchPrediction& prediction, std::vector<FeatureMatch>* matches) const;

  /// Sub-pixel refinement of matches (when settings().subpixel_refinement; otherwise every offset
  /// is set to zero). For each match, the (2 kRefineHalfWindow + 1)^2 patch of `previous_gray`
  /// around the previous keypoint is aligned with `current_gray` near the current keypoint by
  /// inverse-compositional Lucas-Kanade (translation, brightness offset removed, bilinear sampling,
  /// at most 10 iterations), so that current keypoint + offset is where the previous keypoint's
  /// content lies, to a fraction of a pixel. A match keeps offset zero when the patch has no
  /// corner structure (aperture problem), lies within kRefineHalfWindow + 3 px of the border, or
  /// the alignment moves it by more than two pixels along x or y (it left the detected corner's
  /// neighbourhood). Both images are CV_8UC1 of one size (std::invalid_argument otherwise).
  void refineMatches(const cv::Mat& previous_gray, const cv::Mat& current_gray,
                     const FrameFeatures& previous, const FrameFeatures& current,
                     std::vector<FeatureMatch>* matches) const;

  /// Tracking of the previous corners that no match holds (when settings().track_unmatched;
  /// otherwise `tracks` is emptied). Each is predicted where the matches starting in its grid cell
  /// moved (the median displacement; the 3 x 3 cells around it, or all matches, when its cell has
  /// fewer than three), its patch aligned there as in refineMatches(), and kept when the aligned
  /// patches correlate by at least min_track_correlation. This needs no corner in the current
  /// image, so low-contrast corners that FAST finds in only one of the two frames still count.
  /// Nothing is tracked with fewer than three matches. Images as in refineMatches(); a match whose
  /// indices refer to no keypoint throws std::invalid_argument.
  void trackUnmatched(const cv::Mat& previous_gray, const cv::Mat& current_gray,
                      const FrameFeatures& previous, const FrameFeatures& current,
                      const std::vector<FeatureMatch>& matches, std::vector<TrackedCorner>* tracks) const;

  const FrontEndSettings& settings() const { return settings_; }
  void setSettings(const FrontEndSettings& settings) { settings_ = settings; }

 private:
  /// Reused buffers (see the class comment).
  struct Workspace {
    // FAST corners of one detection as (x, y, score) and the detector's working rows.
    std::vector<cv::Point3i> corners;
    std::vector<uint8_t> fast_scratch;
    // Detected corners as sort keys (strength above position; see candidateKey in the .cpp).
    std::vector<uint64_t> candidates, sort_scratch;
    // Grid cell of each pixel column and row, for the grid they were built for.
    std::vector<int> cell_of_x, cell_of_y;
    cv::Size grid_size;
    std::vector<int> cell_count;
    std::vector<uint8_t> redetect, chosen;
    // Cells the last detection found short of their share at fast_threshold, for the detection
    // key it was made with (image size, grid, both thresholds, share): only a guide to where the
    // strong pass can be skipped, never a change to the corners.
    std::vector<uint8_t> short_cells;
    std::array<int, 7> short_cells_key{};
    cv::Mat smoothed;
    std::vector<uint16_t> smoothing;  // the Gaussian's fixed-point rows
    // Describing: each kept keypoint's row. Describing, refining and tracking visit points in
    // image-row order: the row starts and that order.
    std::vector<int> describe_rows, row_start, row_order;
    // OpenCV's fixed-point Gaussian weights (centre first) for gaussian_sigma, and whether the
    // package's filter reproduces cv::GaussianBlur with them (checked once per sigma).
    std::array<uint16_t, 7> gaussian_weights{};
    double gaussian_sigma = -1.0;
    bool gaussian_exact = false;
    std::vector<int> row_best, row_best_d, row_second_d, col_best, col_best_d;
    // Current keypoints sorted by grid cell (guided matching): cell starts, original indices,
    // positions and descriptors in sorted order.
    std::vector<int> grid_start, grid_items, grid_cursor, grid_inside;
    std::vector<cv::Point2f> grid_points;
    std::vector<BriefDescriptor> grid_descriptors;
    // Tracking: matched flag per previous keypoint, the matches' displacements sorted by the cell
    // of their previous keypoint (cell starts), the median displacement per cell, median scratch.
    std::vector<uint8_t> matched;
    std::vector<int> track_cell_start, track_cell_cursor;
    std::vector<uint8_t> track_found;           // tracked, per previous keypoint
    std::vector<cv::Point2f> track_positions;  // where, when tracked
    std::vector<cv::Point2f> track_moves, cell_moves;
    std::vector<double> median_x, median_y;
  };

  /// One detection's image and grid geometry (defined in the .cpp).
  struct DetectGrid;
  /// The geometry of a detection on a width x height image; (re)builds the workspace's
  /// pixel-to-cell lookup when the size or the grid changed.
  DetectGrid detectGrid(int width, int height) const;
  /// Appends the corners from work_.corners[from] on that keep the border distance and lie in grid
  /// row cy's cells cx0 .. cx1 (every cell: cy < 0) to the candidates, counted per cell; returns
  /// how many of them reach fast_threshold.
  int addCorners(const DetectGrid& grid, size_t from, int cy, int cx0, int cx1) const;
  /// The strong pass when the last detection's short cells are known: FAST at fast_threshold on
  /// the runs of cells not guessed short (a cell guessed short gets its strong corners from
  /// redetectShortCells()).
  void detectCellsGuessedFull(const cv::Mat& gray, const DetectGrid& grid) const;
  /// Adaptive pass: every cell with fewer candidates than its share is detected again at
  /// min_fast_threshold, its strong-pass corners replaced by those (only their strong ones when
  /// they fill its share).
  void redetectShortCells(const cv::Mat& gray, const DetectGrid& grid) const;
  /// Bucketing of the candidates into `keypoints`: each cell's share of its strongest corners,
  /// then the strongest left anywhere up to max_features, strongest first.
  void selectCorners(const DetectGrid& grid, std::vector<cv::Point2f>* keypoints) const;
  /// trackUnmatched()'s first step: marks the matched previous keypoints (work_.matched) and
  /// groups the matches' displacements [px] by the grid cell of their previous keypoint
  /// (work_.track_moves, cell starts in work_.track_cell_start) on images of `size`. Throws
  /// std::invalid_argument for a match whose indices refer to no keypoint.
  void groupMovesByCell(const FrameFeatures& previous, const FrameFeatures& current,
                        const std::vector<FeatureMatch>& matches, const cv::Size& size) const;
  /// trackUnmatched()'s second step: each cell's predicted displacement (work_.cell_moves), the
  /// median of its own matches', else of the 3 x 3 cells around it, else of all.
  void medianMovesByCell() const;

  FrontEndSettings settings_;
  mutable Workspace work_;
};

}  // namespace visual_gyro
