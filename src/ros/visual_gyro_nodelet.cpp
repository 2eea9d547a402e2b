#include "visual_gyro_nodelet.h"

#include <algorithm>
#include <cmath>
#include <sstream>

#include <geometry_msgs/TransformStamped.h>
#include <pluginlib/class_list_macros.hpp>
#include <sensor_msgs/Imu.h>

#include "ros_conversions.h"
#include "visual_gyro/RotationEstimate.h"

namespace visual_gyro {

namespace conv = ros_conversions;

namespace {

constexpr double kRadToDeg = 180.0 / M_PI;

/// Yaw [deg] continued from `previous` (no jump of 360 between plot points).
double unwrapDeg(double yaw_deg, double previous) {
  while (yaw_deg - previous > 180.0) yaw_deg -= 360.0;
  while (yaw_deg - previous < -180.0) yaw_deg += 360.0;
  return yaw_deg;
}

bool sameCamera(const CameraModel& a, const CameraModel& b) {
  return a.fx() == b.fx() && a.fy() == b.fy() && a.cx() == b.cx() && a.cy() == b.cy() &&
         a.width() == b.width() && a.height() == b.height() &&
         a.distortionModel() == b.distortionModel() && a.distortion() == b.distortion();
}

visualization_msgs::Marker makeLineStrip(const std::string& ns, int id, float r, float g, float b) {
  visualization_msgs::Marker m;
  m.ns = ns;
  m.id = id;
  m.type = visualization_msgs::Marker::LINE_STRIP;
  m.action = visualization_msgs::Marker::ADD;
  m.pose.orientation.w = 1.0;
  m.scale.x = 0.02;  // line width [m]
  m.color.r = r;
  m.color.g = g;
  m.color.b = b;
  m.color.a = 1.0f;
  m.frame_locked = false;
  return m;
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
  pnh.param<std::string>("backend", backend_request_, "auto");
  pnh.param<std::string>("output_frame", output_frame_, "");
  pnh.param<std::string>("world_frame", world_frame_, "visual_gyro_world");
  pnh.param("publish_tf", publish_tf_, false);
  pnh.param<std::string>("tf_child_frame", tf_child_frame_, "visual_gyro_camera");
  pnh.param("plot_time_scale", plot_time_scale_, 0.2);
  pnh.param("plot_yaw_scale", plot_yaw_scale_, 0.05);
  pnh.param("plot_points", plot_points_, 3000);
  pnh.param("ground_truth_tolerance", ground_truth_tolerance_, 0.005);
  plot_points_ = std::max(plot_points_, 2);
  pnh.param("fx", param_fx_, 0.0);
  pnh.param("fy", param_fy_, -1.0);
  pnh.param("cx", param_cx_, -1.0);
  pnh.param("cy", param_cy_, -1.0);
  pnh.param<std::string>("distortion_model", param_distortion_model_, "none");
  pnh.param("D", param_distortion_, std::vector<double>());

  it_.reset(new image_transport::ImageTransport(nh));
  tf_buffer_.reset(new tf2_ros::Buffer());
  tf_listener_.reset(new tf2_ros::TransformListener(*tf_buffer_, nh));
  if (publish_tf_) tf_broadcaster_.reset(new tf2_ros::TransformBroadcaster());

  plot_estimate_ = makeLineStrip("yaw_estimate", 0, 0.1f, 0.9f, 0.1f);
  plot_truth_ = makeLineStrip("yaw_ground_truth", 1, 0.9f, 0.2f, 0.1f);

  // The server reads the initial values from the private parameters (config/visual_gyro.yaml)
  // and calls reconfigureCb once before returning.
  reconfigure_server_.reset(new dynamic_reconfigure::Server<Config>(reconfigure_mutex_, pnh));
  reconfigure_server_->setCallback(
      boost::bind(&VisualGyroNodelet::reconfigureCb, this, boost::placeholders::_1, boost::placeholders::_2));

  updater_.reset(new diagnostic_updater::Updater(nh, pnh, getName()));
  updater_->setHardwareID("visual_gyro");
  updater_->add("visual_gyro", this, &VisualGyroNodelet::diagnose);
  window_start_ = ros::WallTime::now();
  // A wall timer: diagnostics keep coming at 1 Hz when the (simulated) clock stops.
  diagnostic_timer_ = nh.createWallTimer(ros::WallDuration(1.0), [this](const ros::WallTimerEvent&) {
    updater_->force_update();
  });

  // Advertise under the connect lock so connectCb never sees a half-made set of publishers.
  {
    std::lock_guard<std::mutex> lock(connect_mutex_);
    ros::SubscriberStatusCallback cb = boost::bind(&VisualGyroNodelet::connectCb, this);
    imu_pub_ = pnh.advertise<sensor_msgs::Imu>("imu", 10, cb, cb);
    rotation_pub_ = pnh.advertise<visual_gyro::RotationEstimate>("rotation", 10, cb, cb);
    orientation_pub_ = pnh.advertise<geometry_msgs::PoseStamped>("orientation", 10, cb, cb);
    yaw_plot_pub_ = pnh.advertise<visualization_msgs::Marker>("yaw_plot", 10, cb, cb);
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
    ground_truth_sub_.shutdown();
    subscribed_ = false;
    {
      std::lock_guard<std::mutex> state_lock(state_mutex_);
      reset_pending_ = true;  // the next image after a pause starts afresh
    }
    NODELET_DEBUG("visual_gyro: no subscribers left, unsubscribed from the camera");
  } else if (needed && !subscribed_) {
    ros::NodeHandle& nh = getNodeHandle();
    image_transport::TransportHints hints("raw", ros::TransportHints(), getPrivateNodeHandle());
    if (use_camera_info_) {
      camera_sub_ = it_->subscribeCamera("image", 1, &VisualGyroNodelet::cameraCb, this, hints);
    } else {
      image_sub_ = it_->subscribe("image", 1, &VisualGyroNodelet::imageCb, this, hints);
    }
    ground_truth_sub_ = nh.subscribe("ground_truth", 10, &VisualGyroNodelet::groundTruthCb, this);
    subscribed_ = true;
    NODELET_DEBUG("visual_gyro: subscribed to %s", nh.resolveName("image").c_str());
  }
}

void VisualGyroNodelet::reconfigureCb(Config& config, uint32_t /*level*/) {
  std::lock_guard<std::mutex> lock(state_mutex_);
  const VisualGyroSettings settings = settingsFromConfig(config);
  std::string problem = validateFrontEndSettings(settings.front_end);
  if (problem.empty()) problem = validateSettings(settings.estimator);
  if (!problem.empty()) {
    NODELET_ERROR("visual_gyro: rejected settings (%s); keeping the previous ones", problem.c_str());
    if (have_config_) config = config_;
    return;
  }
  config_ = config;
  have_config_ = true;
  if (pipeline_) {
    try {
      pipeline_->setSettings(settings);
    } catch (const std::exception& e) {
      NODELET_ERROR("visual_gyro: settings not applied: %s", e.what());
    }
  }
}

VisualGyroSettings VisualGyroNodelet::settingsFromConfig(const Config& c) const {
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
  e.backend = backend_request_;
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
  s.run_estimator = true;
  return s;
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
  std::lock_guard<std::mutex> lock(state_mutex_);
  ++window_.images;
  ++total_images_;
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
  ++window_.images;
  ++total_images_;
  CameraModel camera;
  std::string why;
  if (!cameraFromParameters(static_cast<int>(image->width), static_cast<int>(image->height), &camera, &why)) {
    skipForCamera(why, "camera_parameters");
    return;
  }
  processImage(*image, camera, start);
}

void VisualGyroNodelet::skipForCamera(const std::string& why, const std::string& reason) {
  NODELET_ERROR_THROTTLE(10.0, "visual_gyro: %s; frame skipped", why.c_str());
  camera_error_ = why;
  skip(reason);
}

void VisualGyroNodelet::skip(const std::string& reason) {
  ++skipped_[reason];
  ++window_.skipped;
  last_skip_reason_ = reason;
}

void VisualGyroNodelet::resetState() {
  if (pipeline_) pipeline_->reset();
  have_previous_ = false;
  integrated_.setIdentity();
  plot_started_ = false;
  plot_estimate_.points.clear();
  plot_truth_.points.clear();
  have_truth_reference_ = false;
  truth_last_stamp_ = -1.0;
  ++resets_;
}

void VisualGyroNodelet::processImage(const sensor_msgs::Image& image, const CameraModel& camera,
                                     ros::WallTime wall_start) {
  const double stamp = image.header.stamp.toSec();
  if (image.header.stamp.isZero()) {
    NODELET_ERROR_THROTTLE(10.0, "visual_gyro: image has a zero stamp; frame skipped (stamps must be set)");
    skip("zero_stamp");
    return;
  }
  if (reset_pending_) {
    resetState();
    reset_pending_ = false;
  }
  if (have_previous_) {
    if (stamp == previous_stamp_) {
      NODELET_WARN_THROTTLE(10.0, "visual_gyro: image stamp %.6f equals the previous one; frame skipped", stamp);
      skip("equal_stamp");
      return;
    }
    if (stamp < previous_stamp_) {
      NODELET_WARN("visual_gyro: time jumped back by %.3f s (%.3f -> %.3f): resetting",
                   previous_stamp_ - stamp, previous_stamp_, stamp);
      resetState();
    } else if (stamp - previous_stamp_ > config_.max_gap) {
      NODELET_WARN("visual_gyro: gap of %.3f s between images exceeds ~max_gap (%.3f s): resetting",
                   stamp - previous_stamp_, config_.max_gap);
      resetState();
    }
  }

  cv::Mat gray;
  try {
    gray = conv::toGray(image, &mono16_max_);
  } catch (const std::exception& e) {
    NODELET_ERROR_THROTTLE(10.0, "visual_gyro: %s; frame skipped", e.what());
    skip(conv::isSupportedEncoding(image.encoding) ? "malformed_image" : "encoding " + image.encoding);
    return;
  }

  // (Re)build the pipeline when the camera changes; the backend is chosen once.
  if (!pipeline_ || !have_camera_ || !sameCamera(camera, camera_)) {
    try {
      if (!pipeline_) {
        VisualGyroSettings settings = settingsFromConfig(config_);
        WarningSink warn = [this](const std::string& message) {
          last_warning_ = message;
          NODELET_WARN("visual_gyro: %s", message.c_str());
        };
        pipeline_.reset(new VisualGyro(camera, settings, warn));
        backend_used_ = pipeline_->backendName();
        NODELET_INFO("visual_gyro: camera %dx%d fx %.2f fy %.2f, method '%s', backend '%s' (requested '%s')",
                     camera.width(), camera.height(), camera.fx(), camera.fy(),
                     settings.estimator.method.c_str(), backend_used_.c_str(), backend_request_.c_str());
      } else {
        pipeline_->setCamera(camera);
        NODELET_INFO("visual_gyro: camera changed (%dx%d fx %.2f); state reset", camera.width(),
                     camera.height(), camera.fx());
      }
      if (have_previous_) resetState();
      camera_ = camera;
      have_camera_ = true;
      camera_error_.clear();
    } catch (const std::exception& e) {
      NODELET_ERROR_THROTTLE(10.0, "visual_gyro: cannot use this camera: %s; frame skipped", e.what());
      camera_error_ = e.what();
      have_camera_ = false;
      skip("camera");
      return;
    }
  }

  const bool had_previous = have_previous_;
  const double prev_stamp = previous_stamp_;
  FrameResult result = pipeline_->processFrame(gray, stamp);
  // Early rejections leave the pipeline's state untouched and its total time at zero.
  if (!(result.rotation.times.total > 0.0)) {
    NODELET_ERROR_THROTTLE(10.0, "visual_gyro: frame rejected: %s", result.error.c_str());
    skip("rejected");
    return;
  }
  have_previous_ = true;
  previous_stamp_ = stamp;
  ++window_.processed;

  const std::string& camera_frame = image.header.frame_id;
  Eigen::Matrix3d to_output = Eigen::Matrix3d::Identity();
  const bool have_output_frame = outputRotation(camera_frame, &to_output);
  const std::string frame_id = output_frame_.empty() ? camera_frame : output_frame_;
  const RotationResult& rot = result.rotation;
  const bool valid = had_previous && result.has_estimate;
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
    msg->detect_ms = rot.times.detect;
    msg->describe_ms = rot.times.describe;
    msg->match_ms = rot.times.match;
    msg->estimate_ms = rot.times.estimate;
    msg->total_ms = rot.times.total;
    msg->valid = valid;
    msg->status = valid ? "" : (result.error.empty() ? "invalid estimate" : result.error);

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
      ++window_.imus;
      ++total_imus_;
    }
    rotation_pub_.publish(msg);
    ++window_.rotations;
    ++total_rotations_;
    window_.latency_sum_ms += latency_ms;
    window_.latency_max_ms = std::max(window_.latency_max_ms, latency_ms);
    window_.matches_sum += rot.matches_used;
    if (rot.hypotheses_accepted > 0)
      window_.vote_ratio_sum += static_cast<double>(rot.winning_votes) / rot.hypotheses_accepted;
    ++window_.estimates;
    if (!valid) {
      ++window_.invalid;
      ++total_invalid_;
      last_invalid_reason_ = msg->status;
    }
  }

  // Integrated orientation: the first frame after a reset is the identity.
  const Eigen::Quaterniond q_out(to_output * integrated_ * to_output.transpose());
  geometry_msgs::PoseStampedPtr pose(new geometry_msgs::PoseStamped);
  pose->header.stamp = header.stamp;
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
  updateYawPlot(stamp, header);
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
      NODELET_INFO("visual_gyro: rotation %s -> %s is now [%.4f %.4f %.4f %.4f] (x y z w)",
                   camera_frame.c_str(), output_frame_.c_str(), t.transform.rotation.x,
                   t.transform.rotation.y, t.transform.rotation.z, t.transform.rotation.w);
      // A different output rotation makes the integrated orientation discontinuous: restart it.
      if (have_cached_tf_) {
        integrated_.setIdentity();
        plot_started_ = false;
        plot_estimate_.points.clear();
        plot_truth_.points.clear();
        have_truth_reference_ = false;
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
  const Eigen::Quaterniond q = conv::fromMsg(pose->pose.orientation);
  if (!ground_truth_buffer_.empty() && stamp < ground_truth_buffer_.back().first) ground_truth_buffer_.clear();
  ground_truth_buffer_.emplace_back(stamp, q);
  while (ground_truth_buffer_.size() > 200) ground_truth_buffer_.pop_front();
  if (!plot_started_) return;
  if (!have_truth_reference_ && std::abs(stamp - plot_t0_) <= ground_truth_tolerance_) {
    have_truth_reference_ = true;
    truth_reference_ = q;
    truth_last_yaw_deg_ = 0.0;
  }
  if (have_truth_reference_) {
    addGroundTruthPoint(stamp, q);
    if (yaw_plot_pub_.getNumSubscribers() > 0 && plot_truth_.points.size() >= 2) yaw_plot_pub_.publish(plot_truth_);
  }
}

void VisualGyroNodelet::addGroundTruthPoint(double stamp, const Eigen::Quaterniond& orientation) {
  if (stamp < plot_t0_ - ground_truth_tolerance_ || stamp <= truth_last_stamp_) return;
  const Eigen::Matrix3d relative =
      truth_reference_.toRotationMatrix().transpose() * orientation.toRotationMatrix();
  const double yaw = unwrapDeg(yawPitchRoll(relative)[0] * kRadToDeg, truth_last_yaw_deg_);
  truth_last_yaw_deg_ = yaw;
  truth_last_stamp_ = stamp;
  geometry_msgs::Point p;
  p.x = (stamp - plot_t0_) * plot_time_scale_;
  p.y = yaw * plot_yaw_scale_;
  plot_truth_.points.push_back(p);
  if (static_cast<int>(plot_truth_.points.size()) > plot_points_) plot_truth_.points.erase(plot_truth_.points.begin());
  plot_truth_.header.stamp.fromSec(stamp);
  plot_truth_.header.frame_id = world_frame_;
}

void VisualGyroNodelet::updateYawPlot(double stamp, const std_msgs::Header& header) {
  bool truth_from_buffer = false;
  if (!plot_started_) {
    plot_started_ = true;
    plot_t0_ = stamp;
    plot_last_yaw_deg_ = 0.0;
    plot_estimate_.points.clear();
    plot_truth_.points.clear();
    have_truth_reference_ = false;
    truth_last_stamp_ = -1.0;
    // The ground truth may have arrived before the image: take the reference from the buffer.
    for (const auto& entry : ground_truth_buffer_) {
      if (!have_truth_reference_ && std::abs(entry.first - stamp) <= ground_truth_tolerance_) {
        have_truth_reference_ = true;
        truth_reference_ = entry.second;
        truth_last_yaw_deg_ = 0.0;
      }
      if (have_truth_reference_) {
        addGroundTruthPoint(entry.first, entry.second);
        truth_from_buffer = true;
      }
    }
  }
  const double yaw = unwrapDeg(yawPitchRoll(integrated_)[0] * kRadToDeg, plot_last_yaw_deg_);
  plot_last_yaw_deg_ = yaw;
  geometry_msgs::Point p;
  p.x = (stamp - plot_t0_) * plot_time_scale_;
  p.y = yaw * plot_yaw_scale_;
  plot_estimate_.points.push_back(p);
  if (static_cast<int>(plot_estimate_.points.size()) > plot_points_) plot_estimate_.points.erase(plot_estimate_.points.begin());
  plot_estimate_.header.stamp = header.stamp;
  plot_estimate_.header.frame_id = world_frame_;
  if (yaw_plot_pub_.getNumSubscribers() == 0) return;
  if (plot_estimate_.points.size() >= 2) yaw_plot_pub_.publish(plot_estimate_);
  // The ground-truth line is published by groundTruthCb as it grows; here only when the buffer
  // (truth that came before the image) filled it.
  if (truth_from_buffer && plot_truth_.points.size() >= 2) yaw_plot_pub_.publish(plot_truth_);
}

void VisualGyroNodelet::diagnose(diagnostic_updater::DiagnosticStatusWrapper& status) {
  std::lock_guard<std::mutex> lock(state_mutex_);
  const ros::WallTime now = ros::WallTime::now();
  const double span = std::max((now - window_start_).toSec(), 1e-3);
  const Window w = window_;
  window_ = Window();
  window_start_ = now;

  const double mean_latency = w.rotations > 0 ? w.latency_sum_ms / w.rotations : 0.0;
  const double mean_matches = w.estimates > 0 ? w.matches_sum / w.estimates : 0.0;
  const double mean_vote_ratio = w.estimates > 0 ? w.vote_ratio_sum / w.estimates : 0.0;
  status.add("Subscribed", subscribed_.load() ? "yes" : "no (no output subscribers)");
  status.add("Input rate [Hz]", w.images / span);
  status.add("Output rate ~rotation [Hz]", w.rotations / span);
  status.add("Output rate ~imu [Hz]", w.imus / span);
  status.add("Latency mean [ms]", mean_latency);
  status.add("Latency max [ms]", w.latency_max_ms);
  status.add("Matches (mean)", mean_matches);
  status.add("Winning vote ratio (mean)", mean_vote_ratio);
  status.add("Method", have_config_ ? config_.method : std::string("?"));
  status.add("Backend requested", backend_request_);
  status.add("Backend", backend_used_.empty() ? std::string("(not started: no image yet)") : backend_used_);
  if (!last_warning_.empty()) status.add("Backend warning", last_warning_);
  status.add("Images received", total_images_);
  status.add("Estimates published", total_rotations_);
  status.add("Imu published", total_imus_);
  status.add("Invalid estimates", total_invalid_);
  status.add("Resets", resets_);
  uint64_t skipped_total = 0;
  for (const auto& entry : skipped_) {
    status.add("Skipped: " + entry.first, entry.second);
    skipped_total += entry.second;
  }
  status.add("Skipped frames", skipped_total);
  if (!camera_error_.empty()) status.add("Camera problem", camera_error_);

  if (!camera_error_.empty() && w.processed == 0 && w.images > 0) {
    status.summary(diagnostic_msgs::DiagnosticStatus::ERROR, "camera unusable: " + camera_error_);
  } else if (w.skipped > 0) {
    status.summaryf(diagnostic_msgs::DiagnosticStatus::WARN, "%llu frame(s) skipped (last: %s)",
                    static_cast<unsigned long long>(w.skipped), last_skip_reason_.c_str());
  } else if (w.estimates > 0 && 2 * w.invalid > w.estimates) {
    status.summaryf(diagnostic_msgs::DiagnosticStatus::WARN, "%llu of %llu estimates invalid (last: %s)",
                    static_cast<unsigned long long>(w.invalid), static_cast<unsigned long long>(w.estimates),
                    last_invalid_reason_.c_str());
  } else if (!subscribed_) {
    status.summary(diagnostic_msgs::DiagnosticStatus::OK, "idle: no output subscribers");
  } else if (w.images == 0) {
    status.summary(diagnostic_msgs::DiagnosticStatus::OK, "subscribed, waiting for images");
  } else {
    status.summaryf(diagnostic_msgs::DiagnosticStatus::OK, "%.1f Hz, %.1f ms latency, backend %s",
                    w.rotations / span, mean_latency, backend_used_.c_str());
  }
}

}  // namespace visual_gyro

PLUGINLIB_EXPORT_CLASS(visual_gyro::VisualGyroNodelet, nodelet::Nodelet)
