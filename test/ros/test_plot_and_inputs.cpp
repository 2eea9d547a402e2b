// Unit tests (no ROS master) of the yaw plot's markers, the compressed-image encoding and
// decoding, and the filter-style integration of published rates used to choose the output stamps.
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <map>
#include <set>
#include <sstream>

#include <Eigen/Geometry>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <sensor_msgs/image_encodings.h>

#include "compressed_input.h"
#include "imu_integration.h"
#include "yaw_plot.h"

namespace {

using visual_gyro::PlotAxis;
using visual_gyro::YawPlot;
using visual_gyro::YawPlotSettings;
namespace ci = visual_gyro::compressed_input;
namespace ii = visual_gyro::imu_integration;

constexpr double kDegToRad = M_PI / 180.0;

Eigen::Matrix3d yawRotation(double yaw_deg) {
  return Eigen::AngleAxisd(yaw_deg * kDegToRad, Eigen::Vector3d::UnitY()).toRotationMatrix();
}

const visualization_msgs::Marker* find(const visualization_msgs::MarkerArray& array, const std::string& ns) {
  for (const auto& m : array.markers)
    if (m.ns == ns) return &m;
  return nullptr;
}

std::set<std::string> texts(const visualization_msgs::MarkerArray& array) {
  std::set<std::string> out;
  for (const auto& m : array.markers)
    if (m.type == visualization_msgs::Marker::TEXT_VIEW_FACING) out.insert(m.text);
  return out;
}

TEST(YawPlot, NiceSteps) {
  EXPECT_DOUBLE_EQ(YawPlot::niceStep(20.0, 5), 5.0);
  EXPECT_DOUBLE_EQ(YawPlot::niceStep(100.0, 4), 20.0);
  EXPECT_DOUBLE_EQ(YawPlot::niceStep(10.0, 4), 2.0);
  EXPECT_DOUBLE_EQ(YawPlot::niceStep(0.9, 4), 0.2);
  EXPECT_DOUBLE_EQ(YawPlot::niceStep(7.0, 4), 2.0);
  EXPECT_DOUBLE_EQ(YawPlot::niceStep(40.0, 4), 10.0);
}

TEST(YawPlot, AxesLabelsAndLegendOfATurn) {
  YawPlotSettings settings;
  settings.window = 20.0;
  YawPlot plot(settings);
  EXPECT_TRUE(plot.markers(1.0).markers.size() == 1u) << "an empty plot only clears";
  // A 98 degree right turn over 5 s at 10 Hz; the truth (camera -> world) turns the same way.
  const Eigen::Quaterniond start(Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitZ()));
  for (int k = 0; k <= 50; ++k) {
    const double t = 1.0 + 0.1 * k, yaw = 98.0 * k / 50.0;
    plot.addTruth(t, start * Eigen::Quaterniond(yawRotation(yaw)));  // truth first, as a bag may send it
    plot.addEstimate(t, yawRotation(yaw + 0.5 * std::sin(k)));
  }
  const PlotAxis time = plot.timeAxis();
  EXPECT_DOUBLE_EQ(time.min, 0.0);
  EXPECT_DOUBLE_EQ(time.max, 20.0);
  const PlotAxis yaw = plot.valueAxis(YawPlot::kYaw);
  EXPECT_LE(yaw.min, 0.0);
  EXPECT_GE(yaw.max, 98.0);
  EXPECT_LE(yaw.max - yaw.min, 150.0) << "the axis follows the data";
  const PlotAxis rate = plot.valueAxis(YawPlot::kRate);
  EXPECT_LE(rate.min, 19.6);
  EXPECT_GE(rate.max, 19.6);

  const visualization_msgs::MarkerArray array = plot.markers(6.0);
  ASSERT_FALSE(array.markers.empty());
  EXPECT_EQ(array.markers.front().action, visualization_msgs::Marker::DELETEALL);
  const auto* estimate = find(array, "yaw_estimate");
  const auto* truth = find(array, "yaw_ground_truth");
  ASSERT_TRUE(estimate && truth && find(array, "rate_estimate") && find(array, "rate_ground_truth"));
  EXPECT_EQ(estimate->points.size(), 51u);
  EXPECT_EQ(truth->points.size(), 51u);
  // The drawn points read back as the data through the axis.
  EXPECT_NEAR(plot.valueAt(YawPlot::kYaw, truth->points.back().y), 98.0, 1e-6);
  EXPECT_NEAR(plot.valueAt(YawPlot::kYaw, truth->points.front().y), 0.0, 1e-6);
  EXPECT_NEAR(truth->points.back().x, settings.left + 5.0 / 20.0 * settings.width, 1e-9);
  EXPECT_NEAR(plot.valueAt(YawPlot::kRate, find(array, "rate_ground_truth")->points.back().y), 19.6, 1e-6);
  // Every point of the noisy rate estimate lies inside its panel.
  for (const auto& p : find(array, "rate_estimate")->points) {
    EXPECT_GE(plot.valueAt(YawPlot::kRate, p.y), rate.min - 1e-9);
    EXPECT_LE(plot.valueAt(YawPlot::kRate, p.y), rate.max + 1e-9);
  }
  // Labels: axis titles with units, tick values, the legend.
  const std::set<std::string> labels = texts(array);
  for (const char* expected : {"integrated yaw [deg]", "yaw rate [deg/s]", "time [s]", "estimate", "ground truth",
                               "0", "5", "10", "15", "20"}) {
    EXPECT_TRUE(labels.count(expected)) << "no label '" << expected << "'";
  }
  EXPECT_TRUE(labels.count(std::to_string(static_cast<int>(yaw.max)))) << "no label at the top of the yaw axis";
  // rviz refuses markers with a zero scale, an unnormalised orientation or an invisible colour,
  // and a (namespace, id) pair twice in one array replaces the first.
  std::set<std::pair<std::string, int>> ids;
  for (const auto& m : array.markers) {
    if (m.action == visualization_msgs::Marker::DELETEALL) continue;
    EXPECT_TRUE(ids.insert({m.ns, m.id}).second) << m.ns << " " << m.id;
    EXPECT_EQ(m.header.frame_id, settings.frame_id);
    EXPECT_DOUBLE_EQ(m.pose.orientation.w, 1.0);
    EXPECT_GT(m.color.a, 0.0f);
    EXPECT_GT(m.scale.x, 0.0);
    if (m.type == visualization_msgs::Marker::TEXT_VIEW_FACING) {
      EXPECT_GT(m.scale.z, 0.0);
      EXPECT_FALSE(m.text.empty());
    }
    if (m.type == visualization_msgs::Marker::LINE_LIST) EXPECT_EQ(m.points.size() % 2, 0u);
  }
}

TEST(YawPlot, ScrollsOverLongRuns) {
  YawPlotSettings settings;
  settings.window = 10.0;
  YawPlot plot(settings);
  for (int k = 0; k <= 400; ++k) plot.addEstimate(100.0 + 0.1 * k, yawRotation(0.5 * k));  // 5 deg/s for 40 s
  const PlotAxis time = plot.timeAxis();
  EXPECT_NEAR(time.max, 40.0, 1e-9);
  EXPECT_NEAR(time.min, 30.0, 1e-9);
  const visualization_msgs::MarkerArray array = plot.markers(140.0);
  const auto* estimate = find(array, "yaw_estimate");
  ASSERT_TRUE(estimate);
  // Only the window is drawn (its first point clipped onto the left edge), cumulative yaw unwrapped.
  EXPECT_LE(estimate->points.size(), 102u);
  EXPECT_NEAR(estimate->points.front().x, settings.left, 1e-9);
  EXPECT_NEAR(estimate->points.back().x, settings.left + settings.width, 1e-9);
  EXPECT_NEAR(plot.valueAt(YawPlot::kYaw, estimate->points.back().y), 200.0, 1e-6);
  EXPECT_NEAR(plot.valueAt(YawPlot::kYaw, estimate->points.front().y), 150.0, 1e-6);
  const std::set<std::string> labels = texts(array);
  EXPECT_TRUE(labels.count("32") && labels.count("38")) << "time labels scroll with the window";
  EXPECT_FALSE(labels.count("28")) << "the start has scrolled out";
  EXPECT_FALSE(find(array, "yaw_ground_truth")) << "no truth line without truth";
  EXPECT_FALSE(labels.count("ground truth")) << "no truth legend without truth";
  plot.reset();
  EXPECT_TRUE(plot.empty());
}

TEST(YawPlot, TruthLineRestartsAfterALoop) {
  YawPlot plot;
  // A bag played twice: each pose comes just before its image, as make_bag writes them, so the
  // first pose of the second round arrives before the image that makes the nodelet reset.
  for (int round = 0; round < 2; ++round) {
    for (int k = 0; k <= 10; ++k) {
      const double t = 1.0 + 0.1 * k;
      plot.addTruth(t, Eigen::Quaterniond(yawRotation(2.0 * k)));
      if (round == 1 && k == 0) plot.reset();  // the image's stamp jumped back
      plot.addEstimate(t, yawRotation(2.0 * k));
    }
    EXPECT_EQ(plot.estimatePoints(), 11u) << "round " << round;
    EXPECT_EQ(plot.truthPoints(), 11u) << "round " << round;
  }
}

/// "name: value" lines of config/visual_gyro.yaml (comments dropped).
std::map<std::string, std::string> yamlValues() {
  std::map<std::string, std::string> values;
  std::ifstream in(std::string(VISUAL_GYRO_SOURCE_DIR) + "/config/visual_gyro.yaml");
  std::string line;
  while (std::getline(in, line)) {
    line = line.substr(0, line.find('#'));
    const size_t colon = line.find(':');
    if (colon == std::string::npos || line.empty() || line[0] == ' ') continue;
    std::string value = line.substr(colon + 1);
    value.erase(0, value.find_first_not_of(' '));
    value.erase(value.find_last_not_of(' ') + 1);
    values[line.substr(0, colon)] = value;
  }
  return values;
}

// The plot's defaults live in YawPlotSettings; the yaml the launch files load and the node-parameter
// table of doc/ros.md must say the same.
TEST(YawPlot, DefaultsAgreeWithYamlAndRosDoc) {
  const auto yaml = yamlValues();
  ASSERT_FALSE(yaml.empty()) << "cannot read config/visual_gyro.yaml";
  const YawPlotSettings defaults;
  EXPECT_DOUBLE_EQ(std::stod(yaml.at("plot_window")), defaults.window);
  EXPECT_DOUBLE_EQ(std::stod(yaml.at("plot_width")), defaults.width);
  EXPECT_DOUBLE_EQ(std::stod(yaml.at("plot_height")), defaults.height);
  EXPECT_EQ(std::stoi(yaml.at("plot_points")), defaults.max_points);
  EXPECT_DOUBLE_EQ(std::stod(yaml.at("ground_truth_tolerance")), defaults.truth_tolerance);
  EXPECT_EQ(yaml.at("world_frame"), defaults.frame_id);
  std::ifstream doc(std::string(VISUAL_GYRO_SOURCE_DIR) + "/doc/ros.md");
  ASSERT_TRUE(doc.good()) << "cannot read doc/ros.md";
  std::stringstream text;
  text << doc.rdbuf();
  const std::pair<const char*, double> rows[] = {{"plot_window", defaults.window},
                                                 {"plot_width", defaults.width},
                                                 {"plot_height", defaults.height},
                                                 {"plot_points", static_cast<double>(defaults.max_points)}};
  for (const auto& [name, value] : rows) {
    std::ostringstream row;
    row << "| `" << name << "` | " << value << " |";
    EXPECT_NE(text.str().find(row.str()), std::string::npos) << "doc/ros.md has no row " << row.str();
  }
}

std::string fileText(const std::string& relative) {
  std::ifstream in(std::string(VISUAL_GYRO_SOURCE_DIR) + "/" + relative);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

// The stamp default (chosen by measurement, doc/ros.md "Output stamps") is written in three places.
TEST(OutputStamps, MidpointDefaultAgreesInCfgYamlAndRosDoc) {
  EXPECT_EQ(yamlValues().at("stamp_at_midpoint"), "true");
  const std::string cfg = fileText("cfg/VisualGyro.cfg");
  const size_t at = cfg.find("gen.add(\"stamp_at_midpoint\"");
  ASSERT_NE(at, std::string::npos);
  const std::string line = cfg.substr(at, cfg.find('\n', at) - at);
  EXPECT_NE(line.find(", True)"), std::string::npos) << line;
  const std::string doc = fileText("doc/ros.md");
  ASSERT_FALSE(doc.empty()) << "cannot read doc/ros.md";
  EXPECT_NE(doc.find("| `stamp_at_midpoint` | true |"), std::string::npos);
  EXPECT_EQ(yamlValues().at("queue_size"), "1");
  EXPECT_NE(doc.find("| `queue_size` | 1 |"), std::string::npos);
}

TEST(CompressedInput, JpegAndPngRoundTrip) {
  cv::Mat gray(120, 160, CV_8UC1);
  for (int r = 0; r < gray.rows; ++r)
    for (int c = 0; c < gray.cols; ++c) gray.at<uint8_t>(r, c) = static_cast<uint8_t>((r * 7 + c * 3) % 256);
  cv::GaussianBlur(gray, gray, cv::Size(5, 5), 1.5);
  for (ci::Compression format : {ci::Compression::kPng, ci::Compression::kJpeg}) {
    sensor_msgs::CompressedImage message = ci::encodeGray(gray, format);
    message.header.stamp.fromSec(12.5);
    message.header.frame_id = "cam";
    const sensor_msgs::ImagePtr image = ci::decode(message);
    ASSERT_TRUE(image);
    EXPECT_EQ(image->encoding, sensor_msgs::image_encodings::MONO8);
    EXPECT_EQ(image->width, 160u);
    EXPECT_EQ(image->height, 120u);
    EXPECT_EQ(image->step, 160u);
    EXPECT_EQ(image->header.frame_id, "cam");
    EXPECT_DOUBLE_EQ(image->header.stamp.toSec(), 12.5);
    const cv::Mat decoded(120, 160, CV_8UC1, image->data.data());
    const double max_diff = cv::norm(decoded, gray, cv::NORM_INF);
    if (format == ci::Compression::kPng) {
      EXPECT_EQ(max_diff, 0.0) << "PNG is lossless";
      EXPECT_NE(message.format.find("png"), std::string::npos);
    } else {
      EXPECT_GT(max_diff, 0.0) << "JPEG is lossy";
      EXPECT_LT(cv::norm(decoded, gray, cv::NORM_L1) / gray.total(), 3.0) << "quality 90: small mean error";
      EXPECT_NE(message.format.find("jpeg"), std::string::npos);
    }
  }
}

TEST(CompressedInput, ColourAndBadData) {
  cv::Mat bgr(10, 12, CV_8UC3, cv::Scalar(10, 200, 30));
  sensor_msgs::CompressedImage message;
  ASSERT_TRUE(cv::imencode(".png", bgr, message.data));
  EXPECT_EQ(ci::decode(message)->encoding, sensor_msgs::image_encodings::BGR8);
  EXPECT_EQ(ci::decode(message)->step, 36u);

  sensor_msgs::CompressedImage empty;
  EXPECT_THROW(ci::decode(empty), std::invalid_argument);
  sensor_msgs::CompressedImage garbage;
  garbage.format = "jpeg";
  garbage.data = {1, 2, 3, 4, 5, 6, 7, 8};
  try {
    ci::decode(garbage);
    FAIL() << "garbage decoded";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("jpeg"), std::string::npos) << e.what();
  }
  EXPECT_THROW(ci::encodeGray(bgr, ci::Compression::kJpeg), std::invalid_argument);
  ci::Compression c;
  EXPECT_TRUE(ci::parseCompression("jpeg", &c) && c == ci::Compression::kJpeg);
  EXPECT_TRUE(ci::parseCompression("png", &c) && c == ci::Compression::kPng);
  EXPECT_FALSE(ci::parseCompression("webp", &c));
}

/// Truth of a yaw that accelerates (rate 10 + 20 t deg/s) sampled at 10 Hz, and the mean rate over
/// each frame interval as the node publishes it, stamped at the current image or at the midpoint.
void acceleratingTurn(bool midpoint, std::vector<ii::RateSample>* rates, std::vector<ii::TruthSample>* truth) {
  auto yaw = [](double t) { return 10.0 * t + 10.0 * t * t; };  // [deg]
  for (int k = 0; k <= 30; ++k) {
    const double t = 0.1 * k;
    truth->push_back({1.0 + t, yawRotation(yaw(t))});
    if (k == 0) continue;
    const double mean_rate = (yaw(t) - yaw(t - 0.1)) / 0.1 * kDegToRad;
    rates->push_back({1.0 + (midpoint ? t - 0.05 : t), Eigen::Vector3d(0.0, mean_rate, 0.0)});
  }
}

TEST(ImuIntegration, MidpointStampsFollowTheTruthCloser) {
  std::vector<ii::RateSample> current, midpoint;
  std::vector<ii::TruthSample> truth, unused;
  acceleratingTurn(false, &current, &truth);
  acceleratingTurn(true, &midpoint, &unused);
  const ii::IntegrationError at_current = ii::integrationError(current, truth, 0.01);
  const ii::IntegrationError at_midpoint = ii::integrationError(midpoint, truth, 0.01);
  ASSERT_EQ(at_current.series.size(), 301u);
  // Held from the current image's stamp, each rate acts one frame after the rotation it measured:
  // at the last image the integration still lacks that frame's whole rotation (10 + 20 * 2.95
  // deg/s over 0.1 s = 6.9 deg). From the midpoint it lacks half of it.
  EXPECT_NEAR(at_current.final_deg, 6.9, 0.01);
  EXPECT_NEAR(at_midpoint.final_deg, 3.45, 0.01);
  EXPECT_GT(at_current.rms_deg, 3.0);
  EXPECT_LT(at_midpoint.rms_deg, 0.6 * at_current.rms_deg);
  EXPECT_LT(at_midpoint.max_deg, 0.6 * at_current.max_deg);
}

TEST(ImuIntegration, ConstantRateIsExactFromItsStamp) {
  std::vector<ii::RateSample> rates;
  std::vector<ii::TruthSample> truth;
  for (int k = 0; k <= 10; ++k) truth.push_back({2.0 + 0.1 * k, yawRotation(30.0 * 0.1 * k)});
  rates.push_back({1.9, Eigen::Vector3d(0.0, 30.0 * kDegToRad, 0.0)});  // in effect from before the start
  const ii::IntegrationError error = ii::integrationError(rates, truth, 0.05);
  EXPECT_LT(error.max_deg, 1e-9);
  EXPECT_THROW(ii::integrationError(rates, {truth.front()}, 0.05), std::invalid_argument);
  EXPECT_THROW(ii::integrationError(rates, truth, 0.0), std::invalid_argument);
}

}  // namespace
