// Loading KITTI odometry and EuRoC ASL folders, and their ground-truth rotations.
//
// Gyro ground truth (EuRoC): the IMU's readings are integrated as they are; the gyro bias is NOT
// removed. EuRoC's ADIS16448 reads about (-0.002, 0.021, 0.078) rad/s while the drone stands
// still, so on a static stretch trueRotation() is ~0.2 deg per 50 ms frame, not zero, and
// trueAngularVelocity() returns the bias rotated into the camera frame.
#include "visual_gyro/sequence.h"
#include "visual_gyro/geometry.h"

#include <Eigen/Geometry>
#include <Eigen/SVD>
#include <algorithm>
#include <array>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>
#include <stdexcept>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

namespace visual_gyro {
namespace {

namespace fs = std::filesystem;

[[noreturn]] void fail(const fs::path& file, const std::string& what, int line = 0) {
  std::string message = "loadSequence: " + file.string();
  if (line > 0) message += ":" + std::to_string(line);
  throw std::runtime_error(message + ": " + what);
}

std::string trim(const std::string& s) {
  const size_t b = s.find_first_not_of(" \t\r\n");
  if (b == std::string::npos) return "";
  const size_t e = s.find_last_not_of(" \t\r\n");
  return s.substr(b, e - b + 1);
}

/// Parses every number of `text` separated by blanks or commas; false on any other token.
bool parseNumbers(const std::string& text, std::vector<double>* values) {
  values->clear();
  std::string token;
  std::string s = text;
  std::replace(s.begin(), s.end(), ',', ' ');
  std::istringstream words(s);
  while (words >> token) {
    char* end = nullptr;
    errno = 0;
    const double v = std::strtod(token.c_str(), &end);
    if (end == token.c_str() || *end != '\0' || errno == ERANGE || !std::isfinite(v)) return false;
    values->push_back(v);
  }
  return true;
}

std::vector<std::string> readLines(const fs::path& file) {
  std::ifstream in(file);
  if (!in) fail(file, "cannot open");
  std::vector<std::string> lines;
  std::string line;
  while (std::getline(in, line)) lines.push_back(line);
  return lines;
}

/// Nearest rotation matrix (SVD): KITTI's poses carry 6-7 digits, enough to be a little off SO(3).
Eigen::Matrix3d orthonormalize(const Eigen::Matrix3d& m) {
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(m, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d d = Eigen::Matrix3d::Identity();
  d(2, 2) = (svd.matrixU() * svd.matrixV().transpose()).determinant() < 0 ? -1.0 : 1.0;
  return svd.matrixU() * d * svd.matrixV().transpose();
}

bool isRotation(const Eigen::Matrix3d& m, double tolerance) {
  return m.allFinite() && (m.transpose() * m - Eigen::Matrix3d::Identity()).norm() < tolerance &&
         m.determinant() > 0;
}

// Extensions of the image files a KITTI-layout folder may hold (lower case): PNG as KITTI's own,
// and the formats phones and other datasets write, all of which OpenCV reads.
constexpr std::array<const char*, 8> kImageExtensions = {".png", ".jpg", ".jpeg", ".pgm", ".ppm", ".bmp", ".tif", ".tiff"};

std::vector<std::string> sortedImages(const fs::path& dir) {
  std::vector<std::string> paths;
  for (const auto& entry : fs::directory_iterator(dir)) {
    if (!entry.is_regular_file()) continue;
    std::string ext = entry.path().extension().string();
    std::transform(ext.begin(), ext.end(), ext.begin(), ::tolower);
    if (std::find(kImageExtensions.begin(), kImageExtensions.end(), ext) != kImageExtensions.end())
      paths.push_back(entry.path().string());
  }
  std::sort(paths.begin(), paths.end());
  return paths;
}

void readImageSize(const std::string& path, int* width, int* height) {
  const cv::Mat image = cv::imread(path, cv::IMREAD_GRAYSCALE);
  if (image.empty()) fail(path, "cannot read the image");
  *width = image.cols;
  *height = image.rows;
}

// ---------------------------------------------------------------------------------------------
// KITTI
// ---------------------------------------------------------------------------------------------

Sequence loadKitti(const fs::path& root) {
  Sequence seq;
  seq.layout = "kitti";
  fs::path image_dir = root / "image_l";
  if (!fs::is_directory(image_dir)) image_dir = root / "image_0";
  seq.image_paths = sortedImages(image_dir);
  if (seq.image_paths.empty()) {
    std::string accepted;
    for (const char* ext : kImageExtensions) accepted += (accepted.empty() ? "" : " ") + std::string(ext);
    fail(image_dir, "no images (" + accepted + ")");
  }

  // calib.txt: the first line with a 3x4 matrix ("P0: ..." or bare numbers) is the left camera.
  const fs::path calib = root / "calib.txt";
  if (!fs::is_regular_file(calib)) fail(calib, "missing (KITTI layout needs calib.txt)");
  const auto calib_lines = readLines(calib);
  Eigen::Matrix3d K;
  bool found = false;
  for (size_t n = 0; n < calib_lines.size() && !found; ++n) {
    std::string line = trim(calib_lines[n]);
    if (line.empty() || line[0] == '#') continue;
    const size_t colon = line.find(':');
    if (colon != std::string::npos) line = line.substr(colon + 1);
    std::vector<double> v;
    if (!parseNumbers(line, &v) || v.size() != 12)
      fail(calib, "expected a 3x4 projection matrix (12 numbers, optional 'P0:' prefix)", static_cast<int>(n) + 1);
    K << v[0], v[1], v[2], v[4], v[5], v[6], v[8], v[9], v[10];
    if (!(K(0, 0) > 0 && K(1, 1) > 0) || std::abs(K(2, 2) - 1.0) > 1e-6)
      fail(calib, "left 3x3 block is not an intrinsic matrix", static_cast<int>(n) + 1);
    found = true;
  }
  if (!found) fail(calib, "no projection matrix");
  int width = 0, height = 0;
  readImageSize(seq.image_paths.front(), &width, &height);
  seq.camera = CameraModel(K(0, 0), K(1, 1), K(0, 2), K(1, 2), width, height);
  const std::string why = seq.camera.validate();
  if (!why.empty()) fail(calib, "unusable intrinsics: " + why);

  const fs::path poses = root / "poses.txt";
  if (fs::exists(poses)) {
    const auto lines = readLines(poses);
    for (size_t n = 0; n < lines.size(); ++n) {
      if (trim(lines[n]).empty()) continue;
      std::vector<double> v;
      if (!parseNumbers(lines[n], &v) || v.size() != 12)
        fail(poses, "expected 12 numbers (3x4 row-major [R|t])", static_cast<int>(n) + 1);
      Eigen::Matrix3d R;
      R << v[0], v[1], v[2], v[4], v[5], v[6], v[8], v[9], v[10];
      if (!isRotation(R, 1e-3)) fail(poses, "rotation part is not a rotation matrix", static_cast<int>(n) + 1);
      seq.orientations.push_back(orthonormalize(R));
      seq.positions.emplace_back(v[3], v[7], v[11]);
    }
    if (seq.orientations.size() != seq.image_paths.size())
      fail(poses, std::to_string(seq.orientations.size()) + " poses for " + std::to_string(seq.image_paths.size()) +
                      " images");
    seq.truth = "kitti_poses";
    seq.truth_sigma_deg = Eigen::Vector3d(kKittiPosesTiltSigmaDeg, kKittiPosesHeadingSigmaDeg, kKittiPosesTiltSigmaDeg);
    const fs::path sigma = root / kTruthSigmaFile;
    if (fs::exists(sigma)) {
      std::vector<double> v;
      const auto sigma_lines = readLines(sigma);
      std::string text;
      for (const std::string& line : sigma_lines) text += line + " ";
      const bool parsed = parseNumbers(text, &v) && (v.size() == 1 || v.size() == 3);
      if (!parsed || !std::all_of(v.begin(), v.end(), [](double x) { return std::isfinite(x) && x >= 0.0; }))
        fail(sigma, "expected the truth's error [deg] (>= 0): one number for every camera axis, or three (x y z)");
      seq.truth_sigma_deg = v.size() == 1 ? Eigen::Vector3d::Constant(v[0]) : Eigen::Vector3d(v[0], v[1], v[2]);
    }
  }

  const fs::path times = root / "times.txt";
  if (fs::exists(times)) {
    const auto lines = readLines(times);
    for (size_t n = 0; n < lines.size(); ++n) {
      if (trim(lines[n]).empty()) continue;
      std::vector<double> v;
      if (!parseNumbers(lines[n], &v) || v.size() != 1)
        fail(times, "expected one time stamp [s]", static_cast<int>(n) + 1);
      if (!seq.stamps.empty() && v[0] <= seq.stamps.back())
        fail(times, "time stamps must increase", static_cast<int>(n) + 1);
      seq.stamps.push_back(v[0]);
    }
    if (seq.stamps.size() != seq.image_paths.size())
      fail(times, std::to_string(seq.stamps.size()) + " stamps for " + std::to_string(seq.image_paths.size()) +
                      " images");
  } else {
    // KITTI's cameras are triggered at 10 Hz.
    for (size_t k = 0; k < seq.image_paths.size(); ++k) seq.stamps.push_back(0.1 * static_cast<double>(k));
  }
  return seq;
}

// ---------------------------------------------------------------------------------------------
// EuRoC ASL
// ---------------------------------------------------------------------------------------------

/// Minimal reader for the flat YAML of EuRoC's sensor.yaml: "key: value" lines, lists in
/// brackets (possibly over several lines), and T_BS's nested "data:" list.
class SimpleYaml {
 public:
  explicit SimpleYaml(const fs::path& file) : file_(file) {
    std::ifstream in(file);
    if (!in) fail(file, "cannot open");
    std::string line;
    while (std::getline(in, line)) {
      // Comments: '#' to the end of the line ("%YAML:1.0" is a directive, not a key).
      const size_t hash = line.find('#');
      if (hash != std::string::npos) line = line.substr(0, hash);
      lines_.push_back(line);
    }
  }

  /// Line index of "key:" at the start of a line (after indentation), at or after `from`; -1 if absent.
  int find(const std::string& key, int from = 0) const {
    for (int n = from; n < static_cast<int>(lines_.size()); ++n) {
      const std::string t = trim(lines_[n]);
      if (t.compare(0, key.size() + 1, key + ":") == 0) return n;
    }
    return -1;
  }

  /// The scalar after "key:".
  std::string scalar(const std::string& key) const {
    const int n = find(key);
    if (n < 0) fail(file_, "missing key '" + key + "'");
    const std::string t = trim(lines_[n]);
    std::string value = trim(t.substr(key.size() + 1));
    if (value.size() >= 2 && (value.front() == '"' || value.front() == '\'')) value = value.substr(1, value.size() - 2);
    return value;
  }

  /// The bracketed list after "key:" (searching from line `from`).
  std::vector<double> list(const std::string& key, int from = 0) const {
    const int n = find(key, from);
    if (n < 0) fail(file_, "missing key '" + key + "'");
    std::string text = trim(lines_[n]).substr(key.size() + 1);
    int m = n;
    while (text.find(']') == std::string::npos && ++m < static_cast<int>(lines_.size())) {
      // A continuation line holds numbers only; a new key or list means this one was never closed.
      if (lines_[m].find_first_of(":[") != std::string::npos)
        fail(file_, "'" + key + "' list is not closed (missing ']')", n + 1);
      text += " " + lines_[m];
    }
    if (text.find('[') != std::string::npos && text.find(']') == std::string::npos)
      fail(file_, "'" + key + "' list is not closed (missing ']')", n + 1);
    const size_t open = text.find('['), close = text.find(']');
    if (open == std::string::npos || close == std::string::npos || close < open)
      fail(file_, "'" + key + "' is not a [ ... ] list", n + 1);
    std::vector<double> values;
    if (!parseNumbers(text.substr(open + 1, close - open - 1), &values))
      fail(file_, "'" + key + "' holds something that is not a number", n + 1);
    return values;
  }

  int lineOf(const std::string& key) const { return find(key) + 1; }

 private:
  fs::path file_;
  std::vector<std::string> lines_;
};

DistortionModel eurocDistortion(const std::string& name, const fs::path& file, int line) {
  DistortionModel model;
  if (!parseDistortionModel(name, &model)) fail(file, "unsupported distortion_model '" + name + "'", line);
  return model;
}

/// Reads EuRoC's ground truth (timestamp_ns, p_RS_R x y z [m], q_RS w x y z, then optionally
/// velocity and biases: 8 or more columns), the body pose in the world, and fills the camera's
/// orientation and position at every image stamp (slerp / linear interpolation between the two
/// nearest samples), expressed in the first image's camera frame like KITTI's poses. Images outside
/// the file's time span get NaN poses (no truth for their pairs).
void readEurocPoses(const fs::path& file, const Eigen::Vector3d& t_bs, Sequence* seq) {
  struct PoseSample {
    double stamp;
    Eigen::Vector3d position;
    Eigen::Quaterniond orientation;
  };
  std::vector<PoseSample> samples;
  const auto lines = readLines(file);
  for (size_t n = 0; n < lines.size(); ++n) {
    const std::string line = trim(lines[n]);
    if (line.empty() || line[0] == '#') continue;
    const size_t comma = line.find(',');
    std::vector<double> v;
    char* end = nullptr;
    errno = 0;
    // The stamp has 19 digits: parse it as an integer, not through a double.
    const long long ns = comma == std::string::npos ? 0 : std::strtoll(line.substr(0, comma).c_str(), &end, 10);
    if (comma == std::string::npos || errno != 0 || !parseNumbers(line.substr(comma + 1), &v) || v.size() < 7)
      fail(file, "expected 'timestamp_ns,px,py,pz,qw,qx,qy,qz[,...]'", static_cast<int>(n) + 1);
    PoseSample sample{static_cast<double>(ns) * 1e-9, Eigen::Vector3d(v[0], v[1], v[2]),
                      Eigen::Quaterniond(v[3], v[4], v[5], v[6])};
    const double norm = sample.orientation.norm();
    if (!sample.position.allFinite() || !std::isfinite(norm) || std::abs(norm - 1.0) > 1e-2)
      fail(file, "position not finite or quaternion not of unit norm", static_cast<int>(n) + 1);
    sample.orientation.normalize();
    if (!samples.empty() && sample.stamp <= samples.back().stamp)
      fail(file, "time stamps must increase", static_cast<int>(n) + 1);
    samples.push_back(sample);
  }
  if (samples.size() < 2) fail(file, "fewer than two poses");
  const double nan = std::numeric_limits<double>::quiet_NaN();
  std::vector<Eigen::Matrix3d> world_from_camera;
  std::vector<Eigen::Vector3d> camera_in_world;
  for (double t : seq->stamps) {
    if (t < samples.front().stamp || t > samples.back().stamp) {
      world_from_camera.push_back(Eigen::Matrix3d::Constant(nan));
      camera_in_world.push_back(Eigen::Vector3d::Constant(nan));
      continue;
    }
    auto it = std::lower_bound(samples.begin(), samples.end(), t,
                               [](const PoseSample& s, double value) { return s.stamp < value; });
    if (it == samples.begin()) ++it;
    const PoseSample& a = *(it - 1);
    const PoseSample& b = *it;
    const double f = (t - a.stamp) / (b.stamp - a.stamp);
    const Eigen::Matrix3d R_wb = a.orientation.slerp(f, b.orientation).toRotationMatrix();
    const Eigen::Vector3d p_wb = (1.0 - f) * a.position + f * b.position;
    world_from_camera.push_back(R_wb * seq->body_from_camera);
    camera_in_world.push_back(p_wb + R_wb * t_bs);
  }
  // Relative to the first image with a pose, so the sequence starts at identity like KITTI's.
  size_t first = 0;
  while (first < world_from_camera.size() && !world_from_camera[first].allFinite()) ++first;
  if (first == world_from_camera.size()) fail(file, "does not cover any image stamp");
  const Eigen::Matrix3d R0 = world_from_camera[first];
  const Eigen::Vector3d p0 = camera_in_world[first];
  seq->orientations.clear();
  seq->positions.clear();
  for (size_t k = 0; k < world_from_camera.size(); ++k) {
    seq->orientations.push_back(R0.transpose() * world_from_camera[k]);
    seq->positions.push_back(R0.transpose() * (camera_in_world[k] - p0));
  }
  seq->truth = "poses";
  seq->truth_sigma_deg = Eigen::Vector3d::Constant(kEurocPosesSigmaDeg);
}

Sequence loadEuroc(const fs::path& root) {
  Sequence seq;
  seq.layout = "euroc";
  const fs::path cam = root / "cam0";
  const fs::path csv = cam / "data.csv";
  if (!fs::is_regular_file(csv)) fail(csv, "missing (EuRoC layout needs cam0/data.csv)");
  const auto lines = readLines(csv);
  for (size_t n = 0; n < lines.size(); ++n) {
    const std::string line = trim(lines[n]);
    if (line.empty() || line[0] == '#') continue;
    const size_t comma = line.find(',');
    if (comma == std::string::npos) fail(csv, "expected 'timestamp_ns,filename'", static_cast<int>(n) + 1);
    const std::string stamp_text = trim(line.substr(0, comma)), file = trim(line.substr(comma + 1));
    char* end = nullptr;
    errno = 0;
    const long long ns = std::strtoll(stamp_text.c_str(), &end, 10);
    if (stamp_text.empty() || *end != '\0' || errno != 0 || file.empty())
      fail(csv, "expected 'timestamp_ns,filename'", static_cast<int>(n) + 1);
    const double stamp = static_cast<double>(ns) * 1e-9;
    if (!seq.stamps.empty() && stamp <= seq.stamps.back())
      fail(csv, "time stamps must increase", static_cast<int>(n) + 1);
    seq.stamps.push_back(stamp);
    seq.image_paths.push_back((cam / "data" / file).string());
  }
  if (seq.image_paths.empty()) fail(csv, "no images listed");

  const fs::path yaml_path = cam / "sensor.yaml";
  if (!fs::is_regular_file(yaml_path)) fail(yaml_path, "missing");
  const SimpleYaml yaml(yaml_path);
  const auto intrinsics = yaml.list("intrinsics");
  if (intrinsics.size() != 4) fail(yaml_path, "intrinsics must be [fu, fv, cu, cv]", yaml.lineOf("intrinsics"));
  const auto resolution = yaml.list("resolution");
  if (resolution.size() != 2 || resolution[0] < 1 || resolution[1] < 1)
    fail(yaml_path, "resolution must be [width, height]", yaml.lineOf("resolution"));
  const DistortionModel model =
      eurocDistortion(yaml.find("distortion_model") >= 0 ? yaml.scalar("distortion_model") : "none", yaml_path,
                      yaml.lineOf("distortion_model"));
  std::vector<double> distortion;
  if (model != DistortionModel::kNone) distortion = yaml.list("distortion_coefficients");
  const int tbs = yaml.find("T_BS");
  if (tbs < 0) fail(yaml_path, "missing key 'T_BS'");
  const auto tbs_data = yaml.list("data", tbs);
  if (tbs_data.size() != 16) fail(yaml_path, "T_BS data must hold 16 numbers (4x4 row-major)", tbs + 1);
  Eigen::Matrix3d R_bs;
  R_bs << tbs_data[0], tbs_data[1], tbs_data[2], tbs_data[4], tbs_data[5], tbs_data[6], tbs_data[8], tbs_data[9],
      tbs_data[10];
  if (!isRotation(R_bs, 1e-4)) fail(yaml_path, "T_BS rotation is not orthonormal", tbs + 1);
  seq.body_from_camera = orthonormalize(R_bs);
  const Eigen::Vector3d t_bs(tbs_data[3], tbs_data[7], tbs_data[11]);
  seq.camera = CameraModel(intrinsics[0], intrinsics[1], intrinsics[2], intrinsics[3],
                           static_cast<int>(resolution[0]), static_cast<int>(resolution[1]), model, distortion);
  const std::string why = seq.camera.validate();
  if (!why.empty()) fail(yaml_path, "unusable camera: " + why);

  const fs::path imu = root / "imu0" / "data.csv";
  if (fs::exists(imu)) {
    const auto imu_lines = readLines(imu);
    for (size_t n = 0; n < imu_lines.size(); ++n) {
      const std::string line = trim(imu_lines[n]);
      if (line.empty() || line[0] == '#') continue;
      std::vector<double> v;
      // The stamp has 19 digits: parse it as an integer, not through a double.
      const size_t comma = line.find(',');
      char* end = nullptr;
      errno = 0;
      const long long ns = comma == std::string::npos ? 0 : std::strtoll(line.substr(0, comma).c_str(), &end, 10);
      if (comma == std::string::npos || errno != 0 || !parseNumbers(line.substr(comma + 1), &v) || v.size() < 3)
        fail(imu, "expected 'timestamp_ns,wx,wy,wz[,ax,ay,az]'", static_cast<int>(n) + 1);
      GyroSample sample;
      sample.stamp = static_cast<double>(ns) * 1e-9;
      sample.angular_velocity = Eigen::Vector3d(v[0], v[1], v[2]);
      if (!seq.gyro.empty() && sample.stamp <= seq.gyro.back().stamp)
        fail(imu, "time stamps must increase", static_cast<int>(n) + 1);
      seq.gyro.push_back(sample);
    }
  }
  if (!seq.gyro.empty()) seq.truth = "gyro";

  // Poses are preferred to the gyro: they carry no bias.
  const fs::path ground_truth = root / "state_groundtruth_estimate0" / "data.csv";
  if (fs::exists(ground_truth)) readEurocPoses(ground_truth, t_bs, &seq);
  return seq;
}

/// Gyro rate at time t [rad/s, body frame], linear between samples (callers stay inside).
Eigen::Vector3d gyroAt(const std::vector<GyroSample>& gyro, double t) {
  auto it = std::upper_bound(gyro.begin(), gyro.end(), t,
                             [](double value, const GyroSample& s) { return value < s.stamp; });
  if (it == gyro.begin()) return gyro.front().angular_velocity;
  if (it == gyro.end()) return gyro.back().angular_velocity;
  const GyroSample& b = *it;
  const GyroSample& a = *(it - 1);
  const double f = (t - a.stamp) / (b.stamp - a.stamp);
  return (1.0 - f) * a.angular_velocity + f * b.angular_velocity;
}

/// Walks [t0, t1] piece by piece between gyro samples, calling fn(dt, mean rate of the piece).
/// False when the gyro does not cover the interval.
template <typename Fn>
bool forEachGyroPiece(const std::vector<GyroSample>& gyro, double t0, double t1, Fn fn) {
  if (gyro.size() < 2 || !(t1 > t0) || t0 < gyro.front().stamp || t1 > gyro.back().stamp) return false;
  auto it = std::upper_bound(gyro.begin(), gyro.end(), t0,
                             [](double value, const GyroSample& s) { return value < s.stamp; });
  double a = t0;
  Eigen::Vector3d wa = gyroAt(gyro, t0);
  while (a < t1) {
    const double b = (it != gyro.end() && it->stamp < t1) ? it->stamp : t1;
    const Eigen::Vector3d wb = (b == t1) ? gyroAt(gyro, t1) : it->angular_velocity;
    if (b > a) fn(b - a, 0.5 * (wa + wb));  // trapezoid: exact for a rate linear in time
    a = b;
    wa = wb;
    if (it != gyro.end() && b == it->stamp) ++it;
  }
  return true;
}

}  // namespace

bool Sequence::trueRotation(size_t k, Eigen::Matrix3d* rotation) const {
  if (rotation == nullptr || k == 0 || k >= image_paths.size()) return false;
  if (hasPoses()) {
    if (k >= orientations.size()) return false;
    // Images outside the ground truth's time span have NaN poses.
    if (!orientations[k - 1].allFinite() || !orientations[k].allFinite()) return false;
    *rotation = orientations[k - 1].transpose() * orientations[k];
    return true;
  }
  if (!hasGyro() || k >= stamps.size()) return false;
  // R_{k-1}^T R_k = product of exp(omega_c dt) over the pieces, in time order (dR/dt = R [w]x).
  const Eigen::Matrix3d R_cb = body_from_camera.transpose();
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
  if (!forEachGyroPiece(gyro, stamps[k - 1], stamps[k],
                        [&](double dt, const Eigen::Vector3d& w_body) { R = R * so3Exp(R_cb * w_body * dt); }))
    return false;
  *rotation = R;
  return true;
}

bool Sequence::trueAngularVelocity(size_t k, Eigen::Vector3d* omega) const {
  if (omega == nullptr || k == 0 || k >= image_paths.size() || k >= stamps.size()) return false;
  const double dt = stamps[k] - stamps[k - 1];
  if (!(dt > 0)) return false;
  if (hasGyro() && !hasPoses()) {
    Eigen::Vector3d integral = Eigen::Vector3d::Zero();
    if (!forEachGyroPiece(gyro, stamps[k - 1], stamps[k],
                          [&](double piece, const Eigen::Vector3d& w_body) { integral += piece * w_body; }))
      return false;
    *omega = body_from_camera.transpose() * (integral / dt);
    return true;
  }
  Eigen::Matrix3d R;
  if (!trueRotation(k, &R)) return false;
  const Eigen::AngleAxisd aa(R);
  *omega = aa.angle() * aa.axis() / dt;
  return true;
}

cv::Size scaledImageSize(int width, int height, double factor) {
  if (!(factor > 0.0 && factor <= 1.0))
    throw std::invalid_argument("image scale must be in (0, 1], got " + std::to_string(factor));
  if (width < 1 || height < 1)
    throw std::invalid_argument("image size must be positive, got " + std::to_string(width) + "x" +
                                std::to_string(height));
  const auto side = [factor](int length) { return std::max(1, static_cast<int>(std::lround(factor * length))); };
  return cv::Size(side(width), side(height));
}

CameraModel scaledCamera(const CameraModel& camera, double factor) {
  const cv::Size size = scaledImageSize(camera.width(), camera.height(), factor);
  // The ratio the rounded size realises, not `factor` itself: an area resize to that size maps
  // output pixel centre x' to input (x' + 0.5) w / w' - 0.5, and the model must follow it.
  const double sx = static_cast<double>(size.width) / camera.width();
  const double sy = static_cast<double>(size.height) / camera.height();
  return CameraModel(camera.fx() * sx, camera.fy() * sy, (camera.cx() + 0.5) * sx - 0.5,
                     (camera.cy() + 0.5) * sy - 0.5, size.width, size.height, camera.distortionModel(),
                     camera.distortion());
}

cv::Mat scaledImage(const cv::Mat& image, double factor) {
  if (image.empty()) throw std::invalid_argument("scaledImage: empty image");
  const cv::Size size = scaledImageSize(image.cols, image.rows, factor);
  if (size == image.size()) return image.clone();
  cv::Mat out;
  cv::resize(image, out, size, 0.0, 0.0, cv::INTER_AREA);
  return out;
}

void scaleSequence(Sequence* sequence, double factor) {
  if (sequence->image_scale != 1.0)
    throw std::invalid_argument("scaleSequence: the sequence is already downscaled (by " +
                                std::to_string(sequence->image_scale) + ")");
  sequence->camera = scaledCamera(sequence->camera, factor);
  sequence->image_scale = factor;
}

cv::Mat readImage(const Sequence& sequence, size_t k) {
  if (k >= sequence.image_paths.size())
    throw std::runtime_error("readImage: image " + std::to_string(k) + " of " +
                             std::to_string(sequence.image_paths.size()));
  const cv::Mat gray = cv::imread(sequence.image_paths[k], cv::IMREAD_GRAYSCALE);
  if (gray.empty()) throw std::runtime_error("cannot read image " + sequence.image_paths[k]);
  return sequence.image_scale == 1.0 ? gray : scaledImage(gray, sequence.image_scale);
}

Sequence loadSequence(const std::string& folder) {
  const fs::path root(folder);
  if (folder.empty() || !fs::is_directory(root)) fail(root, "no such folder");
  Sequence seq;
  if (fs::is_directory(root / "cam0")) {
    seq = loadEuroc(root);
  } else if (fs::is_directory(root / "image_l") || fs::is_directory(root / "image_0")) {
    seq = loadKitti(root);
  } else {
    fail(root, "neither the KITTI layout (image_l/ or image_0/, calib.txt) nor the EuRoC layout (cam0/)");
  }
  fs::path name_path = root.filename().empty() ? root.parent_path() : root;
  seq.name = fs::weakly_canonical(name_path).filename().string();
  return seq;
}

}  // namespace visual_gyro
