#include "visual_gyro_nodelet.h"

#include <algorithm>

#include <image_transport/camera_common.h>
#include <pluginlib/class_list_macros.hpp>

#include "compressed_input.h"
#include "reconfigure_settings.h"
#include "ros_conversions.h"

namespace visual_gyro {

namespace conv = ros_conversions;

namespace {

bool sameCamera(const CameraModel& a, const CameraModel& b) {
  return a.fx() == b.fx() && a.fy() == b.fy() && a.cx() == b.cx() && a.cy() == b.cy() &&
         a.width() == b.width() && a.height() == b.height() &&
         a.distortionModel() == b.distortionModel() && a.distortion() == b.distortion();
}

OutputSettings outputSettings(const VisualGyroConfig& config) {
  OutputSettings s;
  s.method = config.method;
  s.stamp_at_midpoint = config.stamp_at_midpoint;
  s.publish_invalid = config.publish_invalid;
  s.invalid_variance = config.invalid_variance;
  return s;
}

}  // namespace

VisualGyroNodelet::VisualGyroNodelet() = default;

VisualGyroNodelet::~VisualGyroNodelet() {
  // A manager that unloads this nodelet during one of its callbacks destroys it on that worker
  // thread once the callback returns, when the nodelet's other queue may be gone already; so only
  // the queue of the callback that held it (the single-threaded one: every input and connect
  // callback is there) and the service queue owned here may be touched. Callbacks on the nodelet's
  // queues hold it alive, so none runs from here on; the service thread's do not, so it is joined
  // first. Then every source of callbacks stops before the members it reads go.
  service_running_ = false;
  if (service_thread_.joinable()) service_thread_.join();
  diagnostic_timer_.stop();
  shutdownInputs();
  probe_.reset();
  outputs_.reset();
  reconfigure_server_.reset();
  updater_.reset();
}

void VisualGyroNodelet::shutdownInputs() {
  camera_sub_.shutdown();
  image_sub_.shutdown();
  compressed_sync_.reset();
  compressed_camera_sub_.unsubscribe();
  compressed_info_sub_.unsubscribe();
  compressed_image_sub_.shutdown();
  ground_truth_sub_.shutdown();
  subscribed_ = false;
}

void VisualGyroNodelet::onInit() {
  ros::NodeHandle& nh = getNodeHandle();
  ros::NodeHandle& pnh = getPrivateNodeHandle();
  params_ = NodeParameters::read(pnh);  // refused values are logged there and replaced by their defaults
  health_.start(ros::WallTime::now().toSec());
  outputs_.reset(new OutputPublisher(params_, &health_));

  it_.reset(new image_transport::ImageTransport(nh));
  if (params_.image_transport == "compressed") {
    const std::vector<std::string> loadable = it_->getLoadableTransports();
    decode_compressed_ = std::find(loadable.begin(), loadable.end(), "compressed") == loadable.end();
    NODELET_INFO("visual_gyro: compressed input through %s",
                 decode_compressed_ ? "the nodelet's own OpenCV decoding (image_transport's compressed plugin is "
                                      "not installed)"
                                    : "image_transport's compressed plugin");
  }
  probe_.reset(new InputProbe(nh, pnh, it_.get(), decode_compressed_));

  // On the service queue, spun by a thread of this nodelet (see the destructor): a change is
  // accepted while a frame is being processed. The server reads the initial values from the
  // private parameters (config/visual_gyro.yaml) and calls reconfigureCb once before returning.
  ros::NodeHandle service_nh(nh), service_pnh(pnh);
  service_nh.setCallbackQueue(&service_queue_);
  service_pnh.setCallbackQueue(&service_queue_);
  reconfigure_server_.reset(new dynamic_reconfigure::Server<Config>(reconfigure_mutex_, service_pnh));
  Config min, max;
  reconfigure_settings::ranges(&min, &max);
  reconfigure_server_->setConfigMin(min);
  reconfigure_server_->setConfigMax(max);
  reconfigure_server_->setCallback(
      boost::bind(&VisualGyroNodelet::reconfigureCb, this, boost::placeholders::_1, boost::placeholders::_2));

  updater_.reset(new diagnostic_updater::Updater(nh, pnh, getName()));
  updater_->setHardwareID("visual_gyro");
  updater_->add("visual_gyro", this, &VisualGyroNodelet::diagnose);
  // A wall timer on the service queue: diagnostics keep coming at 1 Hz when the (simulated) clock
  // stops, and while a slow frame is processed.
  diagnostic_timer_ = service_nh.createWallTimer(ros::WallDuration(1.0), [this](const ros::WallTimerEvent&) {
    {
      std::lock_guard<std::mutex> lock(connect_mutex_);
      probe_->update(subscribed_ && params_.use_camera_info, false);
    }
    updater_->force_update();
  });

  // Advertise under the connect lock so connectCb never sees a half-made set of publishers.
  {
    std::lock_guard<std::mutex> lock(connect_mutex_);
    outputs_->advertise(nh, pnh, boost::bind(&VisualGyroNodelet::connectCb, this));
  }
  connectCb();  // ~publish_tf subscribes at once
  service_running_ = true;
  service_thread_ = std::thread([this] {
    while (service_running_ && ros::ok()) service_queue_.callAvailable(ros::WallDuration(0.05));
  });
  NODELET_INFO("visual_gyro: %s input '%s'%s, backend request '%s', output frame '%s'",
               params_.use_camera_info ? "camera" : "image (intrinsics from parameters)",
               nh.resolveName("image").c_str(), params_.publish_tf ? ", TF broadcast on" : "",
               params_.backend.c_str(), params_.output_frame.empty() ? "(camera frame)" : params_.output_frame.c_str());
}

void VisualGyroNodelet::connectCb() {
  std::lock_guard<std::mutex> lock(connect_mutex_);
  const bool needed = outputs_->wanted();
  if (!needed && subscribed_) {
    shutdownInputs();
    probe_->update(false, false);
    reset_pending_ = true;  // the next image after a pause starts afresh
    NODELET_DEBUG("visual_gyro: no subscribers left, unsubscribed from the camera");
  } else if (needed && !subscribed_) {
    // A transport whose plugin cannot be loaded throws; uncaught, it would take down the whole
    // nodelet manager and every nodelet in it.
    try {
      ros::NodeHandle& nh = getNodeHandle();
      image_transport::TransportHints hints("raw", ros::TransportHints(), getPrivateNodeHandle());
      const std::string compressed_topic = nh.resolveName("image") + "/compressed";
      const int queue = params_.queue_size;
      if (decode_compressed_ && params_.use_camera_info) {
        compressed_camera_sub_.subscribe(nh, compressed_topic, queue);
        compressed_info_sub_.subscribe(nh, image_transport::getCameraInfoTopic(nh.resolveName("image")), queue);
        compressed_sync_.reset(new message_filters::TimeSynchronizer<sensor_msgs::CompressedImage, sensor_msgs::CameraInfo>(
            compressed_camera_sub_, compressed_info_sub_, std::max(queue, 5)));
        compressed_sync_->registerCallback(boost::bind(&VisualGyroNodelet::compressedCameraCb, this,
                                                       boost::placeholders::_1, boost::placeholders::_2));
      } else if (decode_compressed_) {
        compressed_image_sub_ = nh.subscribe(compressed_topic, queue, &VisualGyroNodelet::compressedImageCb, this);
      } else if (params_.use_camera_info) {
        camera_sub_ = it_->subscribeCamera("image", queue, &VisualGyroNodelet::cameraCb, this, hints);
      } else {
        image_sub_ = it_->subscribe("image", queue, &VisualGyroNodelet::imageCb, this, hints);
      }
      ground_truth_sub_ = nh.subscribe("ground_truth", 10, &VisualGyroNodelet::groundTruthCb, this);
      subscribed_ = true;
      // Until the first synchronized pair, count what arrives on each topic.
      probe_->update(params_.use_camera_info, true);
      NODELET_DEBUG("visual_gyro: subscribed to %s", nh.resolveName("image").c_str());
    } catch (const image_transport::TransportLoadException& e) {
      NODELET_ERROR_THROTTLE(10.0, "visual_gyro: cannot subscribe to the images (%s); no output until ~image_transport is fixed",
                             e.what());
      health_.setSettingsProblem(std::string("image transport: ") + e.what());
    }
  }
}

void VisualGyroNodelet::reconfigureCb(Config& config, uint32_t /*level*/) {
  std::lock_guard<std::mutex> lock(config_mutex_);
  // Before the first accepted configuration the values in force are the defaults.
  const std::string refused =
      reconfigure_settings::refuseInvalid(have_config_ ? config_ : Config::__getDefault__(), &config);
  if (!refused.empty())
    NODELET_ERROR("visual_gyro: rejected settings change %s; keeping the previous value", refused.c_str());
  VisualGyroSettings settings;
  const std::string problem = reconfigure_settings::pipelineSettings(config, params_.backend, &settings);
  if (problem.empty()) {
    config_ = config;
    settings_ = settings;
    have_config_ = true;
    ++config_version_;
    health_.setSettingsProblem("");
    // Refused start-up parameters stay listed: they cannot change while running.
    health_.setRejectedChange(refused.empty() || params_.refused.empty() ? refused + params_.refused
                                                                         : refused + "; " + params_.refused);
  } else if (have_config_) {
    NODELET_ERROR("visual_gyro: rejected settings (%s); keeping the previous settings", problem.c_str());
    health_.setRejectedChange(problem);
    config = config_;  // the server publishes and stores the settings still in use
  } else {
    // No previous settings to keep: nothing is published until valid ones arrive.
    NODELET_ERROR("visual_gyro: unusable settings (%s); no output until they are fixed", problem.c_str());
    health_.setSettingsProblem(problem);
  }
}

void VisualGyroNodelet::cameraCb(const sensor_msgs::ImageConstPtr& image,
                                 const sensor_msgs::CameraInfoConstPtr& info) {
  const ros::WallTime start = ros::WallTime::now();
  probe_->pairArrived();
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
    health_.skipped("camera_info_size");
    return;
  }
  processImage(*image, camera, start);
}

void VisualGyroNodelet::imageCb(const sensor_msgs::ImageConstPtr& image) {
  const ros::WallTime start = ros::WallTime::now();
  health_.imageIn(image->header.stamp.toSec());
  CameraModel camera;
  std::string why;
  if (!params_.cameraFor(static_cast<int>(image->width), static_cast<int>(image->height), &camera, &why)) {
    skipForCamera(why, "camera_parameters");
    return;
  }
  processImage(*image, camera, start);
}

sensor_msgs::ImageConstPtr VisualGyroNodelet::decodeCompressed(const sensor_msgs::CompressedImage& image) {
  try {
    return compressed_input::decode(image);
  } catch (const std::exception& e) {
    health_.imageIn(image.header.stamp.toSec());
    NODELET_ERROR_THROTTLE(10.0, "visual_gyro: %s; frame skipped", e.what());
    health_.skipped("undecodable");
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
  health_.skipped(reason);
}

void VisualGyroNodelet::resetState(const std::string& cause) {
  if (pipeline_) pipeline_->reset();
  have_previous_ = false;
  outputs_->reset();
  health_.reset(cause);
}

void VisualGyroNodelet::processImage(const sensor_msgs::Image& image, const CameraModel& camera,
                                     ros::WallTime wall_start) {
  std::lock_guard<std::mutex> frame_lock(frame_mutex_);
  Config config;
  VisualGyroSettings settings;
  uint64_t config_version = 0;
  {
    std::lock_guard<std::mutex> config_lock(config_mutex_);
    if (!have_config_) {
      health_.skipped("settings");
      return;
    }
    config = config_;
    settings = settings_;
    config_version = config_version_;
  }
  const double stamp = image.header.stamp.toSec();
  if (image.header.stamp.isZero()) {
    NODELET_ERROR_THROTTLE(10.0, "visual_gyro: image has a zero stamp; frame skipped (stamps must be set)");
    health_.skipped("zero_stamp");
    return;
  }
  if (reset_pending_.exchange(false)) resetState("inputs re-subscribed");
  // The node's own stamp policy, not a copy of the pipeline's checks: a stamp jumping back (a bag
  // played in a loop) or a gap above ~max_gap (a node parameter) resets the state so that the
  // pipeline takes the frame as a first one, and a repeated stamp is reported as equal_stamp before
  // the image is converted or the camera looked at. Whatever passes here still meets the
  // pipeline's checks (FrameStatus kStampRejected, kTimeStepTooSmall), reported below.
  if (have_previous_) {
    if (stamp == previous_stamp_) {
      NODELET_WARN_THROTTLE(10.0, "visual_gyro: image stamp %.6f equals the previous one; frame skipped", stamp);
      health_.skipped("equal_stamp");
      return;
    }
    if (stamp < previous_stamp_) {
      NODELET_WARN_THROTTLE(10.0, "visual_gyro: time jumped back by %.3f s (%.3f -> %.3f): resetting",
                            previous_stamp_ - stamp, previous_stamp_, stamp);
      resetState("time jumped back");
    } else if (stamp - previous_stamp_ > config.max_gap) {
      NODELET_WARN_THROTTLE(10.0, "visual_gyro: gap of %.3f s between images exceeds ~max_gap (%.3f s): resetting",
                            stamp - previous_stamp_, config.max_gap);
      resetState("gap of " + std::to_string(stamp - previous_stamp_) + " s above max_gap " +
                 std::to_string(config.max_gap) + " s");
    }
  }

  cv::Mat gray;
  try {
    gray = conv::toGray(image, params_.mono16_bit_depth);
  } catch (const std::exception& e) {
    NODELET_ERROR_THROTTLE(10.0, "visual_gyro: %s; frame skipped", e.what());
    health_.skipped(conv::isSupportedEncoding(image.encoding) ? "malformed_image" : "encoding " + image.encoding);
    return;
  }
  if (!preparePipeline(camera, settings, config_version)) return;

  const bool had_previous = have_previous_;
  const double previous_stamp = previous_stamp_;
  const FrameResult result = pipeline_->processFrame(gray, stamp);
  // Skipped frames leave the pipeline's state untouched.
  if (result.skipped()) {
    if (result.status == FrameStatus::kTimeStepTooSmall) {
      NODELET_WARN_THROTTLE(10.0, "visual_gyro: %s", result.reason.c_str());
      health_.skipped("min_dt");
    } else {
      NODELET_ERROR_THROTTLE(10.0, "visual_gyro: frame rejected (%s): %s", frameStatusName(result.status),
                             result.reason.c_str());
      health_.skipped(frameStatusName(result.status));
    }
    return;
  }
  if (result.status == FrameStatus::kFrozenImage || result.status == FrameStatus::kNoTexture) {
    NODELET_WARN_THROTTLE(10.0, "visual_gyro: %s; no estimate", result.reason.c_str());
    if (result.status == FrameStatus::kNoTexture) health_.noTexture(result.reason);
  } else {
    // A frozen or textureless image leaves the previous one (and its stamp) in the pipeline; so
    // does the node.
    have_previous_ = true;
    previous_stamp_ = stamp;
  }
  health_.processed();
  reportCalibrationFit(result);

  FrameOutput frame;
  frame.image_header = image.header;
  frame.had_previous = had_previous;
  frame.previous_stamp = previous_stamp;
  frame.result = &result;
  frame.valid = had_previous && result.hasEstimate();
  frame.backend = pipeline_->backend();
  frame.wall_start = wall_start;
  if (!outputs_->publish(frame, outputSettings(config))) health_.skipped("tf");
}

void VisualGyroNodelet::reportCalibrationFit(const FrameResult& result) {
  // The verdict lasts until an estimate's residuals no longer show it (or the camera changes);
  // logged once.
  if (!result.calibration_mismatch.empty()) {
    if (health_.calibrationMismatch().empty()) {
      NODELET_WARN("visual_gyro: calibration does not fit the images, covariance inflated: %s",
                   result.calibration_mismatch.c_str());
    }
    health_.setCalibrationMismatch(result.calibration_mismatch);
  } else if (result.hasEstimate()) {
    health_.setCalibrationMismatch("");
  }
}

bool VisualGyroNodelet::preparePipeline(const CameraModel& camera, const VisualGyroSettings& settings,
                                        uint64_t config_version) {
  // A camera that failed before fails again: say so without rebuilding (the checks cost time).
  if (have_failed_camera_ && sameCamera(camera, failed_camera_)) {
    skipForCamera(health_.cameraProblem(), "camera");
    return false;
  }
  // (Re)build the pipeline when the camera changes; the backend is chosen once.
  if (!pipeline_ || !have_camera_ || !sameCamera(camera, camera_)) {
    try {
      if (!pipeline_) {
        WarningSink warn = [this](const std::string& message) {
          backend_warning_ = message;
          health_.setBackend(std::nullopt, backend_warning_);  // not chosen yet
          NODELET_WARN("visual_gyro: %s", message.c_str());
        };
        pipeline_.reset(new VisualGyro(camera, settings, warn));
        applied_config_version_ = config_version;
        health_.setBackend(pipeline_->backend(), backend_warning_);
        NODELET_INFO("visual_gyro: camera %dx%d fx %.2f fy %.2f, method '%s', backend '%s' (requested '%s')",
                     camera.width(), camera.height(), camera.fx(), camera.fy(), methodName(settings.estimator.method),
                     backendName(pipeline_->backend()), params_.backend.c_str());
      } else {
        pipeline_->setCamera(camera);
        NODELET_INFO_THROTTLE(10.0, "visual_gyro: camera changed (%dx%d fx %.2f); state reset", camera.width(),
                              camera.height(), camera.fx());
      }
      if (have_previous_) resetState("camera_info changed");
      health_.setCalibrationMismatch("");
      camera_ = camera;
      have_camera_ = true;
      have_failed_camera_ = false;
      health_.setCameraProblem("");
    } catch (const std::exception& e) {
      failed_camera_ = camera;
      have_failed_camera_ = true;
      have_camera_ = false;
      skipForCamera(std::string("cannot use this camera: ") + e.what(), "camera");
      return false;
    }
  }
  // A live change accepted since the last frame.
  if (applied_config_version_ != config_version) {
    try {
      pipeline_->setSettings(settings);
    } catch (const std::exception& e) {
      NODELET_ERROR("visual_gyro: settings not applied: %s", e.what());
    }
    applied_config_version_ = config_version;
  }
  return true;
}

void VisualGyroNodelet::groundTruthCb(const geometry_msgs::PoseStampedConstPtr& pose) {
  outputs_->groundTruth(*pose);
}

void VisualGyroNodelet::diagnose(diagnostic_updater::DiagnosticStatusWrapper& status) {
  NodeDiagnostics::Context context;
  context.subscribed = subscribed_.load();
  context.image_topic = getNodeHandle().resolveName("image");
  context.info_topic = image_transport::getCameraInfoTopic(context.image_topic);
  context.backend_requested = params_.backend;
  {
    std::lock_guard<std::mutex> lock(config_mutex_);
    context.method = have_config_ ? config_.method : std::string();
    context.max_gap = have_config_ ? config_.max_gap : 0.0;
  }
  const std::pair<uint64_t, uint64_t> probed = probe_->take();
  health_.probedInput(probed.first, probed.second);
  health_.fill(status, ros::WallTime::now().toSec(), context);
}

}  // namespace visual_gyro

PLUGINLIB_EXPORT_CLASS(visual_gyro::VisualGyroNodelet, nodelet::Nodelet)
