#include "baselines.h"

#include <cmath>
#include <cstdlib>
#include <memory>
#include <stdexcept>

#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>
#include <opencv2/core/eigen.hpp>

#ifdef VISUAL_GYRO_WITH_OPENGV
#include <opengv/relative_pose/CentralRelativeAdapter.hpp>
#include <opengv/sac/Ransac.hpp>
#include <opengv/sac_problems/relative_pose/CentralRelativePoseSacProblem.hpp>
#include <opengv/sac_problems/relative_pose/EigensolverSacProblem.hpp>
#include <opengv/sac_problems/relative_pose/RotationOnlySacProblem.hpp>
#endif

namespace visual_gyro {
namespace eval {
namespace {

const char* const kOpenCvNames[] = {"essential5", "fundamental8"};
const char* const kOpenGvNames[] = {"opengv_rotation_only", "opengv_eigensolver", "opengv_5pt"};

BaselineResult invalid(FrameStatus status, const std::string& why) {
  BaselineResult result;
  result.status = status;
  result.error = why;
  return result;
}

bool finiteRotation(const Eigen::Matrix3d& r) {
  return r.allFinite() && std::abs(r.determinant() - 1.0) < 1e-3 &&
         (r.transpose() * r - Eigen::Matrix3d::Identity()).norm() < 1e-3;
}

// OpenCV's two-view functions take image points; with the camera matrix set to identity, the
// normalized coordinates (x/z, y/z) of the bearings are exactly the undistorted image points, so
// lens distortion (EuRoC) is already removed. Matches behind the camera cannot be expressed so and
// are left out (the callers' data never has them with a pinhole camera).
void normalizedPoints(const std::vector<Eigen::Vector3d>& previous,
                      const std::vector<Eigen::Vector3d>& current,
                      std::vector<cv::Point2d>* p_prev, std::vector<cv::Point2d>* p_cur) {
  p_prev->clear();
  p_cur->clear();
  for (size_t i = 0; i < previous.size(); ++i) {
    const Eigen::Vector3d& a = previous[i];
    const Eigen::Vector3d& b = current[i];
    if (!(a.z() > 1e-6 && b.z() > 1e-6) || !a.allFinite() || !b.allFinite()) continue;
    p_prev->emplace_back(a.x() / a.z(), a.y() / a.z());
    p_cur->emplace_back(b.x() / b.z(), b.y() / b.z());
  }
}

// recoverPose gives R_cv with X_cur = R_cv X_prev; our convention b_prev ~ R b_cur is its transpose.
BaselineResult poseFromEssential(const cv::Mat& essential, const std::vector<cv::Point2d>& p_prev,
                                 const std::vector<cv::Point2d>& p_cur, cv::Mat mask,
                                 const BaselineSettings& settings) {
  if (essential.empty() || essential.cols != 3 || essential.rows < 3) {
    return invalid(FrameStatus::kDegenerate, "no essential matrix found");
  }
  // With exactly five points OpenCV stacks several solutions; the first one is as good as any.
  cv::Mat e = essential.rowRange(0, 3).clone();
  cv::Mat r_cv, t_cv;
  // recoverPose's short form drops points triangulated beyond 50 baselines as "far"; under pure
  // rotation (EuRoC standing still, hand-held) every point is that far and the pose would be
  // rejected although its rotation is fine. A huge limit keeps only the cheirality test.
  cv::Mat points;
  const int inliers = cv::recoverPose(e, p_prev, p_cur, cv::Mat::eye(3, 3, CV_64F), r_cv, t_cv, 1e6, mask, points);
  if (inliers < settings.min_inliers) {
    return invalid(FrameStatus::kTooFewInliers, "recoverPose kept " + std::to_string(inliers) + " inliers (< " +
                                                    std::to_string(settings.min_inliers) + ")");
  }
  Eigen::Matrix3d r;
  cv::cv2eigen(r_cv, r);
  if (!finiteRotation(r)) return invalid(FrameStatus::kDegenerate, "recoverPose returned no rotation");
  BaselineResult result;
  result.valid = true;
  result.status = FrameStatus::kValid;
  result.rotation = r.transpose();
  result.inliers = inliers;
  return result;
}

BaselineResult runEssential5(const std::vector<Eigen::Vector3d>& previous,
                             const std::vector<Eigen::Vector3d>& current,
                             const BaselineSettings& settings) {
  std::vector<cv::Point2d> p_prev, p_cur;
  normalizedPoints(previous, current, &p_prev, &p_cur);
  if (p_prev.size() < 5 || static_cast<int>(p_prev.size()) < settings.min_inliers) {
    return invalid(FrameStatus::kTooFewMatches,
                   "too few matches for the 5-point method: " + std::to_string(p_prev.size()));
  }
  cv::Mat mask;
  cv::Mat essential = cv::findEssentialMat(p_prev, p_cur, 1.0, cv::Point2d(0, 0), cv::RANSAC,
                                           settings.confidence, settings.threshold_rad, mask);
  return poseFromEssential(essential, p_prev, p_cur, mask, settings);
}

BaselineResult runFundamental8(const std::vector<Eigen::Vector3d>& previous,
                               const std::vector<Eigen::Vector3d>& current,
                               const BaselineSettings& settings) {
  std::vector<cv::Point2d> p_prev, p_cur;
  normalizedPoints(previous, current, &p_prev, &p_cur);
  if (p_prev.size() < 8 || static_cast<int>(p_prev.size()) < settings.min_inliers) {
    return invalid(FrameStatus::kTooFewMatches,
                   "too few matches for the 8-point method: " + std::to_string(p_prev.size()));
  }
  cv::Mat mask;
  cv::Mat fundamental = cv::findFundamentalMat(p_prev, p_cur, cv::FM_RANSAC, settings.threshold_rad,
                                               settings.confidence, mask);
  if (fundamental.empty() || fundamental.rows < 3) {
    return invalid(FrameStatus::kDegenerate, "no fundamental matrix found");
  }
  // K = I, so E = F up to scale; project onto the essential manifold (two equal singular values,
  // one zero) before decomposing it.
  cv::Mat f = fundamental.rowRange(0, 3).clone();
  cv::SVD svd(f, cv::SVD::FULL_UV);
  const double s = 0.5 * (svd.w.at<double>(0) + svd.w.at<double>(1));
  if (!(s > 0.0)) return invalid(FrameStatus::kDegenerate, "degenerate fundamental matrix");
  cv::Mat w = (cv::Mat_<double>(3, 3) << 1, 0, 0, 0, 1, 0, 0, 0, 0);
  cv::Mat essential = svd.u * w * svd.vt;
  return poseFromEssential(essential, p_prev, p_cur, mask, settings);
}

#ifdef VISUAL_GYRO_WITH_OPENGV
namespace sac_rel = opengv::sac_problems::relative_pose;

void toOpenGv(const std::vector<Eigen::Vector3d>& in, opengv::bearingVectors_t* out) {
  out->clear();
  out->reserve(in.size());
  for (const auto& b : in) out->push_back(b.normalized());
}

// RANSAC, then OpenGV's own refinement on the inliers (what its examples do after the RANSAC).
template <typename Problem>
BaselineResult runOpenGvRansac(const std::shared_ptr<Problem>& problem, double threshold,
                               const BaselineSettings& settings,
                               Eigen::Matrix3d (*rotationOf)(const typename Problem::model_t&)) {
  opengv::sac::Ransac<Problem> ransac;
  ransac.sac_model_ = problem;
  ransac.threshold_ = threshold;
  ransac.max_iterations_ = settings.max_iterations;
  ransac.probability_ = settings.confidence;
  if (!ransac.computeModel(0)) return invalid(FrameStatus::kDegenerate, "OpenGV RANSAC found no model");
  const int inliers = static_cast<int>(ransac.inliers_.size());
  if (inliers < settings.min_inliers) {
    return invalid(FrameStatus::kTooFewInliers, "OpenGV RANSAC kept " + std::to_string(inliers) + " inliers (< " +
                                                    std::to_string(settings.min_inliers) + ")");
  }
  typename Problem::model_t refined;
  problem->optimizeModelCoefficients(ransac.inliers_, ransac.model_coefficients_, refined);
  Eigen::Matrix3d r = rotationOf(refined);
  if (!finiteRotation(r)) r = rotationOf(ransac.model_coefficients_);
  if (!finiteRotation(r)) return invalid(FrameStatus::kDegenerate, "OpenGV returned no rotation");
  BaselineResult result;
  result.valid = true;
  result.status = FrameStatus::kValid;
  result.rotation = r;  // R12 maps frame-2 (current) bearings into frame 1 (previous): ours
  result.inliers = inliers;
  return result;
}

Eigen::Matrix3d rotationOfRotation(const opengv::rotation_t& m) { return m; }
Eigen::Matrix3d rotationOfEigen(const opengv::eigensolverOutput_t& m) { return m.rotation; }
Eigen::Matrix3d rotationOfTransform(const opengv::transformation_t& m) { return m.block<3, 3>(0, 0); }

BaselineResult runOpenGv(const std::string& name, const std::vector<Eigen::Vector3d>& previous,
                         const std::vector<Eigen::Vector3d>& current,
                         const BaselineSettings& settings, const Eigen::Matrix3d& initial) {
  const size_t min_needed = name == "opengv_rotation_only" ? 3 : (name == "opengv_eigensolver" ? 10 : 5);
  if (previous.size() != current.size()) return invalid(FrameStatus::kBadBearings, "match lists differ in length");
  if (previous.size() < min_needed || static_cast<int>(previous.size()) < settings.min_inliers) {
    return invalid(FrameStatus::kTooFewMatches, "too few matches for " + name + ": " + std::to_string(previous.size()));
  }
  for (size_t i = 0; i < previous.size(); ++i) {
    if (!previous[i].allFinite() || !current[i].allFinite() || previous[i].norm() < 1e-9 ||
        current[i].norm() < 1e-9) {
      return invalid(FrameStatus::kBadBearings, "non-finite or zero bearing in the matches");
    }
  }
  opengv::bearingVectors_t b_prev, b_cur;
  toOpenGv(previous, &b_prev);
  toOpenGv(current, &b_cur);
  // OpenGV's scores are 1 - cos(angle) per view; the two-view problems add both views.
  const double one_view = 1.0 - std::cos(settings.threshold_rad);
  // Frame 1 = previous, frame 2 = current: R12 maps current bearings into the previous frame.
  opengv::relative_pose::CentralRelativeAdapter adapter(b_prev, b_cur, initial);
  // randomSeed = false: OpenGV's sampler then starts from a fixed seed, runs are reproducible.
  if (name == "opengv_rotation_only") {
    auto problem = std::make_shared<sac_rel::RotationOnlySacProblem>(adapter, false);
    return runOpenGvRansac(problem, one_view, settings, &rotationOfRotation);
  }
  if (name == "opengv_eigensolver") {
    // The eigensolver perturbs its start with rand(); seed it for reproducibility.
    std::srand(static_cast<unsigned>(settings.seed));
    auto problem = std::make_shared<sac_rel::EigensolverSacProblem>(adapter, 10, false);
    return runOpenGvRansac(problem, 2.0 * one_view, settings, &rotationOfEigen);
  }
  auto problem = std::make_shared<sac_rel::CentralRelativePoseSacProblem>(
      adapter, sac_rel::CentralRelativePoseSacProblem::STEWENIUS, false);
  return runOpenGvRansac(problem, 2.0 * one_view, settings, &rotationOfTransform);
}
#endif

}  // namespace

std::vector<std::string> baselineNames() {
  std::vector<std::string> names(std::begin(kOpenCvNames), std::end(kOpenCvNames));
#ifdef VISUAL_GYRO_WITH_OPENGV
  names.insert(names.end(), std::begin(kOpenGvNames), std::end(kOpenGvNames));
#endif
  return names;
}

bool isBaselineCompiled(const std::string& name) {
  for (const auto& n : baselineNames()) {
    if (n == name) return true;
  }
  return false;
}

bool isOpenGvBaseline(const std::string& name) {
  for (const char* n : kOpenGvNames) {
    if (name == n) return true;
  }
  return false;
}

BaselineResult runBaseline(const std::string& name, const std::vector<Eigen::Vector3d>& previous,
                           const std::vector<Eigen::Vector3d>& current,
                           const BaselineSettings& settings, const Eigen::Matrix3d& initial) {
  if (!isBaselineCompiled(name)) {
    throw std::invalid_argument(isOpenGvBaseline(name)
                                    ? "baseline '" + name + "' needs OpenGV, not compiled into this build"
                                    : "unknown baseline '" + name + "'");
  }
  if (previous.size() != current.size()) return invalid(FrameStatus::kBadBearings, "match lists differ in length");
  try {
    if (name == "essential5") return runEssential5(previous, current, settings);
    if (name == "fundamental8") return runFundamental8(previous, current, settings);
#ifdef VISUAL_GYRO_WITH_OPENGV
    return runOpenGv(name, previous, current, settings, initial);
#else
    (void)initial;
#endif
  } catch (const cv::Exception& e) {
    return invalid(FrameStatus::kEstimatorFailed, std::string("OpenCV: ") + e.what());
  } catch (const std::exception& e) {
    return invalid(FrameStatus::kEstimatorFailed, name + ": " + e.what());
  }
  return invalid(FrameStatus::kEstimatorFailed, "unreachable");
}

}  // namespace eval
}  // namespace visual_gyro
