#include "reconfigure_settings.h"

#include <iomanip>
#include <limits>
#include <sstream>

#include <boost/any.hpp>

namespace visual_gyro {
namespace reconfigure_settings {

namespace {

std::string valueText(const Config::AbstractParamDescription& description, const Config& config, int digits) {
  boost::any value;
  description.getValue(config, value);
  std::ostringstream out;
  if (description.type == "double") {
    out << std::setprecision(digits) << boost::any_cast<double>(value);
  } else if (description.type == "int") {
    out << boost::any_cast<int>(value);
  } else if (description.type == "bool") {
    out << (boost::any_cast<bool>(value) ? "true" : "false");
  } else {
    out << boost::any_cast<std::string>(value);
  }
  return out.str();
}

}  // namespace

std::vector<std::pair<std::string, std::string>> entries(const Config& config) {
  std::vector<std::pair<std::string, std::string>> out;
  for (const auto& description : Config::__getParamDescriptions__())
    out.emplace_back(description->name,
                     valueText(*description, config, std::numeric_limits<double>::max_digits10));
  return out;
}

std::string describeChange(const Config& before, const Config& after) {
  std::string text;
  for (const auto& description : Config::__getParamDescriptions__()) {
    const std::string old_value = valueText(*description, before, 17);
    const std::string new_value = valueText(*description, after, 17);
    if (old_value == new_value) continue;
    if (!text.empty()) text += ", ";
    text += description->name + " " + valueText(*description, before, 6) + " -> " +
            valueText(*description, after, 6);
  }
  return text;
}

VisualGyroSettings pipelineSettings(const Config& c, const std::string& backend) {
  VisualGyroSettings s;
  s.front_end.fast_threshold = c.fast_threshold;
  s.front_end.max_features = c.max_features;
  s.front_end.grid_cols = c.grid_cols;
  s.front_end.grid_rows = c.grid_rows;
  s.front_end.smoothing_sigma = c.smoothing_sigma;
  s.front_end.max_ratio = c.max_ratio;
  s.front_end.max_hamming = c.max_hamming;
  s.front_end.cross_check = c.cross_check;
  s.front_end.min_fast_threshold = c.min_fast_threshold;
  s.front_end.matching = c.matching;
  s.front_end.guided_radius_px = c.guided_radius_px;
  s.front_end.guided_radius_growth = c.guided_radius_growth;
  s.front_end.guided_min_matches = c.guided_min_matches;
  EstimatorSettings& e = s.estimator;
  e.method = c.method;
  e.backend = backend;
  e.hypotheses = c.hypotheses;
  e.seed = static_cast<uint64_t>(c.seed);
  e.min_separation_deg = c.min_separation_deg;
  e.min_triangle_area_deg2 = c.min_triangle_area_deg2;
  e.centroid_subtraction = c.centroid_subtraction;
  e.yaw_bin_deg = c.yaw_bin_deg;
  e.yaw_window_deg = c.yaw_window_deg;
  e.rotation_bin_deg = c.rotation_bin_deg;
  e.rotation_window_deg = c.rotation_window_deg;
  e.wide_window_deg = c.wide_window_deg;
  e.max_angle_change_deg = c.max_angle_change_deg;
  e.candidates = c.candidates;
  e.inlier_threshold_deg = c.inlier_threshold_deg;
  e.use_prior = c.use_prior;
  e.refine_iterations = c.refine_iterations;
  e.min_matches = c.min_matches;
  e.min_votes = c.min_votes;
  e.min_inlier_ratio = c.min_inlier_ratio;
  e.min_covariance_rad2 = c.min_covariance_rad2;
  s.min_dt = c.min_dt;
  s.max_rate_dps = c.max_rate_dps;
  s.run_estimator = true;
  return s;
}

std::string validate(const VisualGyroSettings& settings) {
  std::string problem = validateFrontEndSettings(settings.front_end);
  if (problem.empty()) problem = validateSettings(settings.estimator);
  if (problem.empty()) problem = validatePlausibilitySettings(settings);
  return problem;
}

}  // namespace reconfigure_settings
}  // namespace visual_gyro
