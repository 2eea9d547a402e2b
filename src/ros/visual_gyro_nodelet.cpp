#include "visual_gyro_nodelet.h"

#include <algorithm>
#include <cmath>
#include <sstream>

#include <geometry_msgs/TransformStamped.h>
#include <image_transport/camera_common.h>
#include <pluginlib/class_list_macros.hpp>
#include <sensor_msgs/Imu.h>

#include "compressed_input.h"
#include "ros_conversions.h"
#include "visual_gyro/RotationEstimate.h"

namespace visual_gyro {

namespace conv = ros_conversions;

namespace {

bool sameCamera(const CameraModel& a, const CameraModel& b) {
  return a.fx() == b.fx() && a.fy() == b.fy() && a.cx() == b.cx() && a.cy() == b.cy() &&
         a.width() == b.width() && a.height() == b.height() &&
         a.distortionModel() == b.distortionModel() && a.distortion() == b.distortion();
}

}  // namespace

VisualGyroNodelet::VisualGyroNodelet() = default;

VisualGyroNodelet::~VisualGyroNodelet() {
  diagnostic_timer_.stop();
}

void VisualGyroNodelet::onInit() {
  ros::NodeHandle& nh = getNodeHandle();
  ros::NodeHandle& pnh = getPrivateNodeHandle();

  pnh.param("use_camera_info", use_camera_info_, true);
  pnh.param<std::string>("image_transport", transport_, "raw");
  pnh.param("queue_size", queue_size_, 1);
  queue_size_ = std::max(queue_size_, 1);
  pnh.param<std::string>("backend", backend_request_, "auto");
  pnh.param<std::string>("output_frame", output_frame_, "");
  pnh.param<std::string>("world_frame", world_frame_, "visual_gyro_world");
  pnh.param("publish_tf", publish_tf_, false);
  pnh.param<std::string>("tf_child_frame", tf_child_frame_, "visual_gyro_camera");
  YawPlotSettings plot;
  plot.frame_id = world_frame_;
  pnh.param("plot_window", plot.window, plot.window);
  pnh.param("plot_width", plot.width, plot.width);
  pnh.param("plot_height", plot.height, plot.height);
  pnh.param("plot_points", plot.max_points, plot.max_points);
  pnh.param("ground_truth_tolerance", plot.truth_tolerance, plot.truth_tolerance);
  yaw_plot_ = YawPlot(plot);
  pnh.param("fx", param_fx_, 0.0);
  pnh.param("fy", param_fy_, -1.0);
  pnh.param("cx", param_cx_, -1.0);
  pnh.param("cy", param_cy_, -1.0);
  pnh.param<std::string>("distortion_model", param_distortion_model_, "none");
  pnh.param("D", param_distortion_, std::vector<double>());
  pnh.param("mono16_bit_depth", mono16_bit_depth_, 0);
  if (mono16_bit_depth_ != 0 && (mono16_bit_depth_ < 8 || mono16_bit_depth_ > 16)) {
    parameter_problem_ = "~mono16_bit_depth must be 0 (per frame) or 8..16, got " + std::to_string(mono16_bit_depth_);
    NODELET_ERROR("visual_gyro: %s; no output until it is fixed", parameter_problem_.c_str());
  }

  it_.reset(new image_transport::ImageTransport(nh));
  if (transport_ == "compressed") {
    const std::vector<std::string> loadable = it_->getLoadableTransports();
    decode_compressed_ = std::find(loadable.begin(), loadable.end(), "compressed") == loadable.end();
    NODELET_INFO("visual_gyro: compressed input through %s",
                 decode_compressed_ ? "the nodelet's own OpenCV decoding (image_transport's compressed plugin is "
                                      "not installed)"
                                    : "image_transport's compressed plugin");
  }
  tf_buffer_.reset(new tf2_ros::Buffer());
  tf_listener_.reset(new tf2_ros::TransformListener(*tf_buffer_, nh));
  if (publish_tf_) tf_broadcaster_.reset(new tf2_ros::TransformBroadcaster());

  // The server reads the initial values from the private parameters (config/visual_gyro.yaml)
  // and calls reconfigureCb once before returning.
  reconfigure_server_.reset(new dynamic_reconfigure::Server<Config>(reconfigure_mutex_, pnh));
  reconfigure_server_->setCallback(
      boost::bind(&VisualGyroNodelet::reconfigureCb, this, boost::placeholders::_1, boost::placeholders::_2));

  updater_.reset(new diagnostic_updater::Updater(nh, pnh, getName()));
  updater_->setHardwareID("visual_gyro");
  updater_->add("visual_gyro", this, &VisualGyroNodelet::diagnose);
  health_ = NodeDiagnostics(ros::WallTime::now().toSec());
  // A wall timer: diagnostics keep coming at 1 Hz when the (simulated) clock stops.
  diagnostic_timer_ = nh.createWallTimer(ros::WallDuration(1.0), [this](const ros::WallTimerEvent&) {
    updateProbe(false);
    updater_->force_update();
  });

  // Advertise under the connect lock so connectCb never sees a half-made set of publishers.
  {
    std::lock_guard<std::mutex> lock(connect_mutex_);
    ros::SubscriberStatusCallback cb = boost::bind(&VisualGyroNodelet::connectCb, this);
    imu_pub_ = pnh.advertise<sensor_msgs::Imu>("imu", 10, cb, cb);
    rotation_pub_ = pnh.advertise<visual_gyro::RotationEstimate>("rotation", 10, cb, cb);
    orientation_pub_ = pnh.advertise<geometry_msgs::PoseStamped>("orientation", 10, cb, cb);
    yaw_plot_pub_ = pnh.advertise<visualization_msgs::MarkerArray>("yaw_plot", 10, cb, cb);
  }
  connectCb();  // ~publish_tf subscribes at once
  NODELET_INFO("visual_gyro: %s input '%s'%s, backend request '%s', output frame '%s'",
               use_camera_info_ ? "camera" : "image (intrinsics from parameters)",
               nh.resolveName("image").c_str(), publish_tf_ ? ", TF broadcast on" : "",
               backend_request_.c_str(), output_frame_.empty() ? "(camera frame)" : output_frame_.c_str());
}

void VisualGyroNodelet::connectCb() {
  std::lock_guard<std::mutex> lock(connect_mutex_);
  const bool needed = publish_tf_ || imu_pub_.getNumSubscribers() > 0 ||
                      rotation_pub_.getNumSubscribers() > 0 ||
                      orientation_pub_.getNumSubscribers() > 0 ||
                      yaw_plot_pub_.getNumSubscribers() > 0;
  if (!needed && subscribed_) {
    camera_sub_.shutdown();
    image_sub_.shutdown();
    compressed_sync_.reset();
    compressed_camera_sub_.unsubscribe();
    compressed_info_sub_.unsubscribe();
    compressed_image_sub_.shutdown();
    ground_truth_sub_.shutdown();
    probe_image_sub_.shutdown();
    probe_compressed_sub_.shutdown();
    probe_info_sub_.shutdown();
    probing_ = false;
    subscribed_ = false;
    {
      std::lock_guard<std::mutex> state_lock(state_mutex_);
      reset_pending_ = true;  // the next image after a pause starts afresh
    }
    NODELET_DEBUG("visual_gyro: no subscribers left, unsubscribed from the camera");
  } else if (needed && !subscribed_) {
    // A transport whose plugin cannot be loaded throws; uncaught, it would take down the whole
    // nodelet manager and every nodelet in it.
    try {
      ros::NodeHandle& nh = getNodeHandle();
      image_transport::TransportHints hints("raw", ros::TransportHints(), getPrivateNodeHandle());
      const std::string compressed_topic = nh.resolveName("image") + "/compressed";
      if (decode_compressed_ && use_camera_info_) {
        compressed_camera_sub_.subscribe(nh, compressed_topic, queue_size_);
        compressed_info_sub_.subscribe(nh, image_transport::getCameraInfoTopic(nh.resolveName("image")), queue_size_);
        compressed_sync_.reset(new message_filters::TimeSynchronizer<sensor_msgs::CompressedImage, sensor_msgs::CameraInfo>(
            compressed_camera_sub_, compressed_info_sub_, std::max(queue_size_, 5)));
        compressed_sync_->registerCallback(boost::bind(&VisualGyroNodelet::compressedCameraCb, this,
                                                       boost::placeholders::_1, boost::placeholders::_2));
      } else if (decode_compressed_) {
        compressed_image_sub_ = nh.subscribe(compressed_topic, queue_size_, &VisualGyroNodelet::compressedImageCb, this);
      } else if (use_camera_info_) {
        camera_sub_ = it_->subscribeCamera("image", queue_size_, &VisualGyroNodelet::cameraCb, this, hints);
      } else {
        image_sub_ = it_->subscribe("image", queue_size_, &VisualGyroNodelet::imageCb, this, hints);
      }
      ground_truth_sub_ = nh.subscribe("ground_truth", 10, &VisualGyroNodelet::groundTruthCb, this);
      subscribed_ = true;
      // Until the first synchronized pair, count what arrives on each topic.
      updateProbeLocked(true);
      NODELET_DEBUG("visual_gyro: subscribed to %s", nh.resolveName("image").c_str());
    } catch (const image_transport::TransportLoadException& e) {
      NODELET_ERROR_THROTTLE(10.0, "visual_gyro: cannot subscribe to the images (%s); no output until ~image_transport is fixed",
                             e.what());
      std::lock_guard<std::mutex> state_lock(state_mutex_);
      health_.setSettingsProblem(std::string("image transport: ") + e.what());
    }
  }
}

void VisualGyroNodelet::updateProbe(bool force_start) {
  std::lock_guard<std::mutex> lock(connect_mutex_);
  updateProbeLocked(force_start);
}

void VisualGyroNodelet::updateProbeLocked(bool force_start) {
  // Probe callbacks only touch atomics: they never wait for the state mutex, so shutting them
  // down here cannot deadlock with a running camera callback.
  const bool paired = paired_images_.exchange(0) > 0;
  const bool wanted = subscribed_ && use_camera_info_ && (force_start || !paired);
  if (wanted && !probing_) {
    ros::NodeHandle& nh = getNodeHandle();
    image_transport::TransportHints hints("raw", ros::TransportHints(), getPrivateNodeHandle());
    const boost::function<void(const sensor_msgs::ImageConstPtr&)> on_image =
        [this](const sensor_msgs::ImageConstPtr&) { ++probe_images_; };
    const boost::function<void(const sensor_msgs::CameraInfoConstPtr&)> on_info =
        [this](const sensor_msgs::CameraInfoConstPtr&) { ++probe_infos_; };
    if (decode_compressed_) {
      // The same topic the camera subscription reads: the image_transport plugin is missing, so
      // the probe cannot go through image_transport either.
      const boost::function<void(const sensor_msgs::CompressedImageConstPtr&)> on_compressed =
          [this](const sensor_msgs::CompressedImageConstPtr&) { ++probe_images_; };
      probe_compressed_sub_ =
          nh.subscribe<sensor_msgs::CompressedImage>(nh.resolveName("image") + "/compressed", 1, on_compressed);
    } else {
      probe_image_sub_ = it_->subscribe("image", 1, on_image, ros::VoidPtr(), hints);
    }
    probe_info_sub_ = nh.subscribe<sensor_msgs::CameraInfo>(
        image_transport::getCameraInfoTopic(nh.resolveName("image")), 1, on_info);
    probing_ = true;
  } else if (!wanted && probing_) {
    probe_image_sub_.shutdown();
    probe_compressed_sub_.shutdown();
    probe_info_sub_.shutdown();
    probing_ = false;
  }
}

void VisualGyroNodelet::reconfigureCb(Config& config, uint32_t /*level*/) {
  std::lock_guard<std::mutex> lock(state_mutex_);
  VisualGyroSettings settings;
  std::string problem = settingsFromConfig(config, &settings);
  if (problem.empty()) problem = validateVisualGyroSettings(settings);
  if (!problem.empty()) {
    if (have_config_) {
      NODELET_ERROR("visual_gyro: rejected settings (%s); keeping the previous ones", problem.c_str());
      config = config_;
    } else {
      // No previous settings to keep: nothing is published until valid ones arrive.
      NODELET_ERROR("visual_gyro: unusable settings (%s); no output until they are fixed", problem.c_str());
      health_.setSettingsProblem(problem);
    }
    return;
  }
  config_ = config;
  have_config_ = true;
  health_.setSettingsProblem("");
  if (pipeline_) {
    try {
      pipeline_->setSettings(settings);
    } catch (const std::exception& e) {
      NODELET_ERROR("visual_gyro: settings not applied: %s", e.what());
    }
  }
}

std::string VisualGyroNodelet::settingsFromConfig(const Config& config, VisualGyroSettings* settings) const {
  // Every pipeline setting the cfg declares goes through the settings table by name; the others
  // (node behaviour) are read from config_ where they are used.
  *settings = VisualGyroSettings();
  std::string problem = applySetting(settings, "backend", backend_request_);
  for (const auto& description : Config::__getParamDescriptions__()) {
    if (findSetting(description->name) == nullptr) continue;
    boost::any value;
    description->getValue(config, value);
    std::string text;
    if (description->type == "int") {
      text = std::to_string(boost::any_cast<int>(value));
    } else if (description->type == "double") {
      text = SettingField<VisualGyroSettings>::formatNumber(boost::any_cast<double>(value));
    } else if (description->type == "bool") {
      text = boost::any_cast<bool>(value) ? "true" : "false";
    } else {
      text = boost::any_cast<std::string>(value);
    }
    const std::string why = applySetting(settings, description->name, text);
    if (problem.empty()) problem = why;
  }
  settings->run_estimator = true;
  return problem;
}

bool VisualGyroNodelet::cameraFromParameters(int width, int height, CameraModel* camera,
                                             std::string* why) const {
  // Read once at start (onInit): a parameter-server round trip per frame would add milliseconds.
  const double fx = param_fx_;
  const double fy = param_fy_ > 0.0 ? param_fy_ : fx;
  const double cx = param_cx_ >= 0.0 ? param_cx_ : (width - 1) / 2.0;
  const double cy = param_cy_ >= 0.0 ? param_cy_ : (height - 1) / 2.0;
  DistortionModel model = DistortionModel::kNone;
  if (!parseDistortionModel(param_distortion_model_, &model)) {
    *why = "~distortion_model '" + param_distortion_model_ +
           "' is not supported (none, plumb_bob, radtan, equidistant)";
    return false;
  }
  if (!(fx > 0.0)) {
    *why = "~use_camera_info is false but ~fx is not set (give ~fx, ~fy, ~cx, ~cy)";
    return false;
  }
  std::vector<double> d = param_distortion_;
  bool all_zero = true;
  for (double v : d) all_zero = all_zero && v == 0.0;
  if (all_zero) {
    d.clear();
    model = DistortionModel::kNone;
  }
  *camera = CameraModel(fx, fy, cx, cy, width, height, model, d);
  return true;
}

void VisualGyroNodelet::cameraCb(const sensor_msgs::ImageConstPtr& image,
                                 const sensor_msgs::CameraInfoConstPtr& info) {
  const ros::WallTime start = ros::WallTime::now();
  ++paired_images_;
  std::lock_guard<std::mutex> lock(state_mutex_);
  health_.imageIn(image->header.stamp.toSec());
  CameraModel camera;
  std::string why;
  if (!conv::cameraModelFromInfo(*info, &camera, &why)) {
    skipForCamera(why, "camera_info");
    return;
  }
  if (camera.width() != static_cast<int>(image->width) || camera.height() != static_cast<int>(image->height)) {
    NODELET_ERROR_THROTTLE(10.0, "visual_gyro: camera_info is for %dx%d images but the image is %ux%u; frame skipped",
                           camera.width(), camera.height(), image->width, image->height);
    skip("camera_info_size");
    return;
  }
  processImage(*image, camera, start);
}

void VisualGyroNodelet::imageCb(const sensor_msgs::ImageConstPtr& image) {
  const ros::WallTime start = ros::WallTime::now();
  std::lock_guard<std::mutex> lock(state_mutex_);
  health_.imageIn(image->header.stamp.toSec());
  CameraModel camera;
  std::string why;
  if (!cameraFromParameters(static_cast<int>(image->width), static_cast<int>(image->height), &camera, &why)) {
    skipForCamera(why, "camera_parameters");
    return;
  }
  processImage(*image, camera, start);
}

sensor_msgs::ImageConstPtr VisualGyroNodelet::decodeCompressed(const sensor_msgs::CompressedImage& image) {
  try {
    return compressed_input::decode(image);
  } catch (const std::exception& e) {
    std::lock_guard<std::mutex> lock(state_mutex_);
    health_.imageIn(image.header.stamp.toSec());
    NODELET_ERROR_THROTTLE(10.0, "visual_gyro: %s; frame skipped", e.what());
    skip("undecodable");
    return nullptr;
  }
}

void VisualGyroNodelet::compressedCameraCb(const sensor_msgs::CompressedImageConstPtr& image,
                                           const sensor_msgs::CameraInfoConstPtr& info) {
  if (const sensor_msgs::ImageConstPtr decoded = decodeCompressed(*image)) cameraCb(decoded, info);
}

void VisualGyroNodelet::compressedImageCb(const sensor_msgs::CompressedImageConstPtr& image) {
  if (const sensor_msgs::ImageConstPtr decoded = decodeCompressed(*image)) imageCb(decoded);
}

void VisualGyroNodelet::skipForCamera(const std::string& why, const std::string& reason) {
  NODELET_ERROR_THROTTLE(10.0, "visual_gyro: %s; frame skipped", why.c_str());
  health_.setCameraProblem(why);
  skip(reason);
}

void VisualGyroNodelet::skip(const std::string& reason) {
  health_.skipped(reason);
}

void VisualGyroNodelet::resetState(const std::string& cause) {
  if (pipeline_) pipeline_->reset();
  have_previous_ = false;
  integrated_.setIdentity();
  yaw_plot_.reset();
  health_.reset(cause);
}

void VisualGyroNodelet::processImage(const sensor_msgs::Image& image, const CameraModel& camera,
                                     ros::WallTime wall_start) {
  const double stamp = image.header.stamp.toSec();
  if (!health_.settingsProblem().empty() || !parameter_problem_.empty()) {
    skip("settings");
    return;
  }
  if (image.header.stamp.isZero()) {
    NODELET_ERROR_THROTTLE(10.0, "visual_gyro: image has a zero stamp; frame skipped (stamps must be set)");
    skip("zero_stamp");
    return;
  }
  if (reset_pending_) {
    resetState("inputs re-subscribed");
    reset_pending_ = false;
  }
  if (have_previous_) {
    if (stamp == previous_stamp_) {
      NODELET_WARN_THROTTLE(10.0, "visual_gyro: image stamp %.6f equals the previous one; frame skipped", stamp);
      skip("equal_stamp");
      return;
    }
    if (stamp < previous_stamp_) {
      NODELET_WARN_THROTTLE(10.0, "visual_gyro: time jumped back by %.3f s (%.3f -> %.3f): resetting",
                            previous_stamp_ - stamp, previous_stamp_, stamp);
      resetState("time jumped back");
    } else if (stamp - previous_stamp_ > config_.max_gap) {
      NODELET_WARN_THROTTLE(10.0, "visual_gyro: gap of %.3f s between images exceeds ~max_gap (%.3f s): resetting",
                            stamp - previous_stamp_, config_.max_gap);
      resetState("gap of " + std::to_string(stamp - previous_stamp_) + " s above max_gap " +
                 std::to_string(config_.max_gap) + " s");
    }
  }

  cv::Mat gray;
  try {
    gray = conv::toGray(image, mono16_bit_depth_);
  } catch (const std::exception& e) {
    NODELET_ERROR_THROTTLE(10.0, "visual_gyro: %s; frame skipped", e.what());
    skip(conv::isSupportedEncoding(image.encoding) ? "malformed_image" : "encoding " + image.encoding);
    return;
  }

  // A camera that failed before fails again: say so without rebuilding (the checks cost time).
  if (have_failed_camera_ && sameCamera(camera, failed_camera_)) {
    skipForCamera(health_.cameraProblem(), "camera");
    return;
  }
  // (Re)build the pipeline when the camera changes; the backend is chosen once.
  if (!pipeline_ || !have_camera_ || !sameCamera(camera, camera_)) {
    try {
      if (!pipeline_) {
        VisualGyroSettings settings;
        const std::string problem = settingsFromConfig(config_, &settings);
        if (!problem.empty()) throw std::invalid_argument("settings: " + problem);
        WarningSink warn = [this](const std::string& message) {
          last_warning_ = message;
          NODELET_WARN("visual_gyro: %s", message.c_str());
        };
        pipeline_.reset(new VisualGyro(camera, settings, warn));
        backend_used_ = pipeline_->backendName();
        NODELET_INFO("visual_gyro: camera %dx%d fx %.2f fy %.2f, method '%s', backend '%s' (requested '%s')",
                     camera.width(), camera.height(), camera.fx(), camera.fy(),
                     methodName(settings.estimator.method), backend_used_.c_str(), backend_request_.c_str());
      } else {
        pipeline_->setCamera(camera);
        NODELET_INFO_THROTTLE(10.0, "visual_gyro: camera changed (%dx%d fx %.2f); state reset", camera.width(),
                              camera.height(), camera.fx());
      }
      if (have_previous_) resetState("camera_info changed");
      camera_ = camera;
      have_camera_ = true;
      have_failed_camera_ = false;
      health_.setCameraProblem("");
    } catch (const std::exception& e) {
      failed_camera_ = camera;
      have_failed_camera_ = true;
      have_camera_ = false;
      skipForCamera(std::string("cannot use this camera: ") + e.what(), "camera");
      return;
    }
  }

  const bool had_previous = have_previous_;
  const double prev_stamp = previous_stamp_;
  FrameResult result = pipeline_->processFrame(gray, stamp);
  // Skipped frames leave the pipeline's state untouched.
  if (result.skipped()) {
    if (result.status == FrameStatus::kTimeStepTooSmall) {
      NODELET_WARN_THROTTLE(10.0, "visual_gyro: %s", result.reason.c_str());
      skip("min_dt");
    } else {
      NODELET_ERROR_THROTTLE(10.0, "visual_gyro: frame rejected (%s): %s", frameStatusName(result.status),
                             result.reason.c_str());
      skip("rejected");
    }
    return;
  }
  if (result.status == FrameStatus::kFrozenImage) {
    NODELET_WARN_THROTTLE(10.0, "visual_gyro: %s; no estimate", result.reason.c_str());
  } else {
    // A frozen image leaves the previous one (and its stamp) in the pipeline; so does the node.
    have_previous_ = true;
    previous_stamp_ = stamp;
  }
  health_.processed();

  const std::string& camera_frame = image.header.frame_id;
  Eigen::Matrix3d to_output = Eigen::Matrix3d::Identity();
  const bool have_output_frame = outputRotation(camera_frame, &to_output);
  const std::string frame_id = output_frame_.empty() ? camera_frame : output_frame_;
  const RotationResult& rot = result.rotation;
  const bool valid = had_previous && result.hasEstimate();
  if (valid) integrated_ = integrated_ * rot.rotation;

  if (!have_output_frame) {
    skip("tf");
    return;  // outputRotation warned
  }

  std_msgs::Header header = image.header;
  header.frame_id = frame_id;
  if (had_previous && config_.stamp_at_midpoint) header.stamp.fromSec(0.5 * (prev_stamp + stamp));

  if (had_previous) {
    const Eigen::Matrix3d rotation_out = to_output * rot.rotation * to_output.transpose();
    const Eigen::Vector3d omega_out = to_output * result.angular_velocity;
    const Eigen::Matrix3d rotation_cov_out = to_output * rot.covariance * to_output.transpose();
    const Eigen::Matrix3d omega_cov_out =
        to_output * result.angular_velocity_covariance * to_output.transpose();

    visual_gyro::RotationEstimatePtr msg(new visual_gyro::RotationEstimate);
    msg->header = header;
    msg->previous_stamp.fromSec(prev_stamp);
    msg->dt = stamp - prev_stamp;
    msg->rotation = conv::toMsg(Eigen::Quaterniond(rotation_out));
    msg->yaw = rot.yaw;
    msg->pitch = rot.pitch;
    msg->roll = rot.roll;
    msg->angular_velocity.x = omega_out.x();
    msg->angular_velocity.y = omega_out.y();
    msg->angular_velocity.z = omega_out.z();
    conv::toRowMajor(rotation_cov_out, &msg->rotation_covariance);
    conv::toRowMajor(omega_cov_out, &msg->angular_velocity_covariance);
    msg->features = static_cast<uint32_t>(std::max(result.features, 0));
    msg->matches = static_cast<uint32_t>(std::max(rot.matches_used, 0));
    msg->hypotheses = static_cast<uint32_t>(std::max(rot.hypotheses_drawn, 0));
    msg->hypotheses_accepted = static_cast<uint32_t>(std::max(rot.hypotheses_accepted, 0));
    msg->winning_votes = static_cast<uint32_t>(std::max(rot.winning_votes, 0));
    msg->inliers = static_cast<uint32_t>(std::max(rot.inliers, 0));
    msg->method = config_.method;
    msg->backend = rot.backend.empty() ? backend_used_ : rot.backend;
    if (!rot.backend.empty()) backend_used_ = rot.backend;
    msg->detect_ms = result.times.detect;
    msg->describe_ms = result.times.describe;
    msg->match_ms = result.times.match;
    msg->estimate_ms = result.times.estimate;
    msg->total_ms = result.times.total;
    msg->valid = valid;
    msg->status = valid ? "" : std::string(frameStatusName(result.status)) + ": " + result.reason;

    const bool publish_imu = valid || config_.publish_invalid;
    sensor_msgs::ImuPtr imu;
    if (publish_imu) {
      imu.reset(new sensor_msgs::Imu);
      imu->header = header;
      imu->orientation.w = 1.0;
      imu->orientation_covariance[0] = -1.0;          // REP 145: no orientation
      imu->linear_acceleration_covariance[0] = -1.0;  // REP 145: no acceleration
      imu->angular_velocity = msg->angular_velocity;
      if (valid) {
        conv::toRowMajor(omega_cov_out, &imu->angular_velocity_covariance);
      } else {
        // An untrustworthy estimate: zero rate with a covariance large enough that a filter
        // barely moves.
        imu->angular_velocity.x = imu->angular_velocity.y = imu->angular_velocity.z = 0.0;
        conv::toRowMajor(Eigen::Matrix3d::Identity() * config_.invalid_variance,
                         &imu->angular_velocity_covariance);
      }
    }

    const double latency_ms = (ros::WallTime::now() - wall_start).toSec() * 1e3;
    msg->latency_ms = latency_ms;
    if (imu) {
      imu_pub_.publish(imu);
      health_.imuPublished();
    }
    rotation_pub_.publish(msg);
    const double vote_ratio =
        rot.hypotheses_accepted > 0 ? static_cast<double>(rot.winning_votes) / rot.hypotheses_accepted : 0.0;
    health_.estimatePublished(valid, msg->status, latency_ms, rot.matches_used, vote_ratio);
  }

  // Integrated orientation: the first frame after a reset is the identity. It is the camera's
  // orientation when this image was taken, so it carries the image's stamp (not the midpoint).
  const Eigen::Quaterniond q_out(to_output * integrated_ * to_output.transpose());
  geometry_msgs::PoseStampedPtr pose(new geometry_msgs::PoseStamped);
  pose->header.stamp = image.header.stamp;
  pose->header.frame_id = world_frame_;
  pose->pose.orientation = conv::toMsg(q_out);
  orientation_pub_.publish(pose);
  if (tf_broadcaster_) {
    geometry_msgs::TransformStamped t;
    t.header = pose->header;
    t.child_frame_id = tf_child_frame_;
    t.transform.rotation = pose->pose.orientation;
    tf_broadcaster_->sendTransform(t);
  }
  yaw_plot_.addEstimate(stamp, integrated_);
  publishYawPlot(stamp);
}

bool VisualGyroNodelet::outputRotation(const std::string& camera_frame, Eigen::Matrix3d* rotation) {
  if (output_frame_.empty() || output_frame_ == camera_frame) {
    rotation->setIdentity();
    return true;
  }
  const std::string key = output_frame_ + "<-" + camera_frame;
  const ros::WallTime now = ros::WallTime::now();
  // Camera mounts are static: look the transform up once, then re-check once a second so a
  // corrected calibration is picked up.
  if (have_cached_tf_ && key == cached_tf_key_ && (now - cached_tf_time_).toSec() < 1.0) {
    *rotation = cached_output_rotation_;
    return true;
  }
  try {
    const geometry_msgs::TransformStamped t =
        tf_buffer_->lookupTransform(output_frame_, camera_frame, ros::Time(0));
    const Eigen::Matrix3d r = conv::fromMsg(t.transform.rotation).toRotationMatrix();
    if (!have_cached_tf_ || key != cached_tf_key_ || !r.isApprox(cached_output_rotation_, 1e-9)) {
      NODELET_INFO_THROTTLE(10.0, "visual_gyro: rotation %s -> %s is now [%.4f %.4f %.4f %.4f] (x y z w)",
                   camera_frame.c_str(), output_frame_.c_str(), t.transform.rotation.x,
                   t.transform.rotation.y, t.transform.rotation.z, t.transform.rotation.w);
      // A different output rotation makes the integrated orientation discontinuous: restart it.
      if (have_cached_tf_) {
        integrated_.setIdentity();
        yaw_plot_.reset();
      }
    }
    cached_tf_key_ = key;
    cached_output_rotation_ = r;
    cached_tf_time_ = now;
    have_cached_tf_ = true;
    *rotation = r;
    return true;
  } catch (const tf2::TransformException& e) {
    if (have_cached_tf_ && key == cached_tf_key_) {
      *rotation = cached_output_rotation_;
      return true;
    }
    NODELET_WARN_THROTTLE(10.0, "visual_gyro: no transform %s -> %s yet (%s); outputs held back",
                          camera_frame.c_str(), output_frame_.c_str(), e.what());
    return false;
  }
}

void VisualGyroNodelet::groundTruthCb(const geometry_msgs::PoseStampedConstPtr& pose) {
  std::lock_guard<std::mutex> lock(state_mutex_);
  const double stamp = pose->header.stamp.toSec();
  yaw_plot_.addTruth(stamp, conv::fromMsg(pose->pose.orientation));
  // Truth that arrives after its image would otherwise wait for the next image to be drawn.
  if (!yaw_plot_.empty()) publishYawPlot(stamp);
}

void VisualGyroNodelet::publishYawPlot(double stamp) {
  if (yaw_plot_pub_.getNumSubscribers() == 0 || yaw_plot_.empty()) return;
  visualization_msgs::MarkerArrayPtr markers(new visualization_msgs::MarkerArray(yaw_plot_.markers(stamp)));
  yaw_plot_pub_.publish(markers);
}

void VisualGyroNodelet::diagnose(diagnostic_updater::DiagnosticStatusWrapper& status) {
  NodeDiagnostics::Context context;
  context.subscribed = subscribed_.load();
  context.image_topic = getNodeHandle().resolveName("image");
  context.info_topic = image_transport::getCameraInfoTopic(context.image_topic);
  std::lock_guard<std::mutex> lock(state_mutex_);
  health_.probedInput(probe_images_.exchange(0), probe_infos_.exchange(0));
  if (!parameter_problem_.empty()) health_.setSettingsProblem(parameter_problem_);
  context.method = have_config_ ? config_.method : std::string();
  context.backend_requested = backend_request_;
  context.backend_used = backend_used_;
  context.backend_warning = last_warning_;
  health_.fill(status, ros::WallTime::now().toSec(), context);
}

}  // namespace visual_gyro

PLUGINLIB_EXPORT_CLASS(visual_gyro::VisualGyroNodelet, nodelet::Nodelet)
