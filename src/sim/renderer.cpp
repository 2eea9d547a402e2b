// Synthetic sequence renderer: per-pixel ray casting against textured rectangles.
//
// Scenes are built once per (preset, seed, frames, rate) and cached, so renderView() in a loop does
// not rebuild textures. Textures are procedural (value noise plus random filled rectangles and
// ellipses) and drawn with a private splitmix64 generator, so a seed gives the same images on every
// platform (std:: distributions are implementation-defined).
#include "visual_gyro/renderer.h"
#include "visual_gyro/geometry.h"
#include "visual_gyro/random.h"
#include "visual_gyro/sequence.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <memory>
#include <mutex>
#include <sstream>
#include <stdexcept>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

namespace visual_gyro {
namespace {

constexpr double kNearDepth = 0.02;      // [m] rays hitting closer than this are ignored
constexpr double kCameraHeight = 1.65;   // [m] drive/forward: ground is this far below (+y)
constexpr double kDriveSpeed = 10.0;     // [m/s] drive/forward: 1 m per frame at 10 Hz
constexpr double kTexelsPerRadian = 600.0;  // texel size = expected distance / this
constexpr int kSamples = 2;              // supersampling per axis

double deg(double degrees) { return degrees * kPi / 180.0; }

using Rng = SplitMix64;

uint64_t mixSeed(uint64_t a, uint64_t b) {
  Rng rng(a ^ (b * 0xD1B54A32D192ED03ull + 0x8CB92BA72F3D8DD7ull));
  rng.next();
  return rng.next();
}

// ---------------------------------------------------------------------------------------------
// Textures
// ---------------------------------------------------------------------------------------------

/// A periodic texture with its mip levels. Each level is stored with one extra row and column
/// (copies of the first) so a bilinear lookup never needs a second wrap.
struct Texture {
  double texel = 0.01;  ///< [m] size of one level-0 texel on the surface
  std::vector<cv::Mat> levels;  ///< CV_8UC1, (h + 1) x (w + 1)
  std::vector<int> widths, heights;
};

struct TextureStyle {
  double shape_density = 0.8;  ///< shape area / texture area
  double min_shape = 3.0;      ///< shape side range [texels]
  double max_shape = 80.0;
  double noise_amplitude = 35.0;  ///< grey levels of the coarse value noise
  double fine_amplitude = 5.0;    ///< grey levels of the texel-scale noise
  double mean_lo = 70.0, mean_hi = 180.0;  ///< background mean grey range
  double shape_contrast = 90.0;  ///< shapes: background mean +- this many grey levels
};

/// Adds one octave of periodic value noise (bicubic between lattice points `cell` texels apart).
void addNoiseOctave(cv::Mat* acc, int cell, double amplitude, Rng* rng) {
  const int lw = acc->cols / cell, lh = acc->rows / cell;
  cv::Mat lattice(lh, lw, CV_32F);
  for (int r = 0; r < lh; ++r)
    for (int c = 0; c < lw; ++c) lattice.at<float>(r, c) = static_cast<float>(rng->uniform(-1.0, 1.0) * amplitude);
  cv::Mat padded, up;
  cv::copyMakeBorder(lattice, padded, 2, 2, 2, 2, cv::BORDER_WRAP);
  cv::resize(padded, up, cv::Size(padded.cols * cell, padded.rows * cell), 0, 0, cv::INTER_CUBIC);
  *acc += up(cv::Rect(2 * cell, 2 * cell, acc->cols, acc->rows));
}

/// Draws a shape and its wrapped copies so the texture stays periodic.
template <typename DrawFn>
void drawWrapped(int width, int height, int x, int y, int extent, DrawFn draw) {
  for (int dy = -1; dy <= 1; ++dy) {
    for (int dx = -1; dx <= 1; ++dx) {
      const int ox = x + dx * width, oy = y + dy * height;
      if (ox + extent < 0 || oy + extent < 0 || ox - extent >= width || oy - extent >= height) continue;
      draw(ox, oy);
    }
  }
}

/// Smallest power of two >= value, clamped to [lo, hi]: power-of-two sizes make wrapping a bit mask.
int powerOfTwoAtLeast(double value, int lo, int hi) {
  int n = lo;
  while (n < hi && n < value) n *= 2;
  return n;
}

Texture makeTexture(double extent_u, double extent_v, double texel, const TextureStyle& style, uint64_t seed) {
  Rng rng(seed);
  const int w = powerOfTwoAtLeast(extent_u / texel, 64, 2048);
  const int h = powerOfTwoAtLeast(extent_v / texel, 64, 2048);
  const double mean = rng.uniform(style.mean_lo, style.mean_hi);
  cv::Mat acc(h, w, CV_32F, cv::Scalar(mean));
  const int cells[] = {64, 32, 16, 8};
  const double weights[] = {1.0, 0.6, 0.35, 0.2};
  for (int o = 0; o < 4; ++o) addNoiseOctave(&acc, cells[o], style.noise_amplitude * weights[o], &rng);

  // Filled rectangles and ellipses of random grey give the corners FAST needs; log-uniform sizes
  // give detail from a few texels to the size of a window.
  const double mean_side = (style.max_shape - style.min_shape) / std::log(style.max_shape / style.min_shape);
  const int count = static_cast<int>(style.shape_density * w * h / (mean_side * mean_side));
  for (int n = 0; n < count; ++n) {
    const int sw = static_cast<int>(rng.logUniform(style.min_shape, style.max_shape));
    const int sh = static_cast<int>(rng.logUniform(style.min_shape, style.max_shape));
    const int x = static_cast<int>(rng.uniform() * w), y = static_cast<int>(rng.uniform() * h);
    const cv::Scalar grey(mean + rng.uniform(-style.shape_contrast, style.shape_contrast));
    const bool ellipse = rng.uniform() < 0.3;
    const double angle = rng.uniform(0.0, 180.0);
    drawWrapped(w, h, x, y, std::max(sw, sh) + 1, [&](int ox, int oy) {
      if (ellipse) {
        cv::ellipse(acc, cv::Point(ox, oy), cv::Size(std::max(1, sw / 2), std::max(1, sh / 2)), angle, 0, 360, grey,
                    cv::FILLED, cv::LINE_8);
      } else {
        cv::rectangle(acc, cv::Rect(ox, oy, sw, sh), grey, cv::FILLED, cv::LINE_8);
      }
    });
  }
  addNoiseOctave(&acc, 2, style.fine_amplitude, &rng);

  Texture tex;
  tex.texel = texel;
  cv::Mat level;
  acc.convertTo(level, CV_8U);  // saturates to [0, 255]
  while (true) {
    cv::Mat padded;
    cv::copyMakeBorder(level, padded, 0, 1, 0, 1, cv::BORDER_WRAP);
    tex.levels.push_back(padded);
    tex.widths.push_back(level.cols);
    tex.heights.push_back(level.rows);
    if (level.cols % 2 != 0 || level.rows % 2 != 0 || std::min(level.cols, level.rows) <= 4) break;
    cv::Mat next;
    cv::resize(level, next, cv::Size(level.cols / 2, level.rows / 2), 0, 0, cv::INTER_AREA);
    level = next;
  }
  return tex;
}

inline int fastFloor(double x) {
  const int i = static_cast<int>(x);
  return i - (x < i);
}

/// Bilinear lookup at level `l`; (x, y) in level texels, wrapped (sizes are powers of two).
inline float sampleLevel(const Texture& tex, int l, double x, double y) {
  x -= 0.5;
  y -= 0.5;
  const int xi = fastFloor(x), yi = fastFloor(y);
  const float fx = static_cast<float>(x - xi), fy = static_cast<float>(y - yi);
  const int x0 = xi & (tex.widths[l] - 1), y0 = yi & (tex.heights[l] - 1);
  const cv::Mat& m = tex.levels[l];
  const uint8_t* r0 = m.ptr<uint8_t>(y0);
  const uint8_t* r1 = r0 + m.step[0];
  const float top = r0[x0] + fx * (r0[x0 + 1] - r0[x0]);
  const float bottom = r1[x0] + fx * (r1[x0 + 1] - r1[x0]);
  return top + fy * (bottom - top);
}

/// log2 to within 0.09 (exponent plus linear mantissa): plenty for picking mip levels, and
/// continuous, so the trilinear blend has no seams.
inline float roughLog2(float x) {
  int bits;
  std::memcpy(&bits, &x, sizeof(bits));
  const float exponent = static_cast<float>((bits >> 23) & 0xFF) - 127.0f;
  const float mantissa = static_cast<float>(bits & 0x7FFFFF) * (1.0f / 8388608.0f);
  return exponent + mantissa;
}

/// Trilinear lookup: (a, b) in metres on the surface, `footprint` = sample footprint in level-0
/// texels (chooses the mip level, as a GPU would).
inline float sampleTexture(const Texture& tex, double a, double b, float footprint) {
  const double inv = 1.0 / tex.texel;
  if (footprint <= 1.0f) return sampleLevel(tex, 0, a * inv, b * inv);
  const int top = static_cast<int>(tex.levels.size()) - 1;
  const float lambda = roughLog2(footprint);
  if (lambda >= top) return sampleLevel(tex, top, a * inv / (1 << top), b * inv / (1 << top));
  const int l0 = static_cast<int>(lambda);
  const float frac = lambda - l0;
  const double s0 = inv / (1 << l0);
  const float v0 = sampleLevel(tex, l0, a * s0, b * s0);
  const float v1 = sampleLevel(tex, l0 + 1, a * s0 * 0.5, b * s0 * 0.5);
  return v0 + frac * (v1 - v0);
}

// ---------------------------------------------------------------------------------------------
// Scene
// ---------------------------------------------------------------------------------------------

/// A textured rectangle: points origin + a * axis_u + b * axis_v, a in [0, length_u], b in
/// [0, length_v] [m]. (a, b) are also the texture coordinates, so texture scale is physical.
struct Plane {
  Eigen::Vector3d origin, axis_u, axis_v, normal;
  double length_u = 1.0, length_v = 1.0;
  int texture = 0;
  double offset_u = 0.0, offset_v = 0.0;  ///< [m] added to (a, b) for the lookup (shared textures)
  float gain = 1.0f;        ///< brightness factor (a crude stand-in for illumination)
  bool one_sided = false;   ///< box faces: seen only from the side the normal points to
};

struct Scene {
  std::vector<Plane> planes;
  std::vector<Texture> textures;
  bool has_sky = false;
  Texture sky;
  float background = 128.0f;
};

class SceneBuilder {
 public:
  SceneBuilder(Scene* scene, uint64_t seed) : scene_(scene), seed_(seed) {}

  /// Adds a rectangle with its own texture, or, with pool >= 0, one of that pool's textures once
  /// it holds kPoolSize (at a random offset), so long drives do not need memory per facade.
  void addPlane(const Eigen::Vector3d& origin, const Eigen::Vector3d& axis_u, const Eigen::Vector3d& axis_v,
                double length_u, double length_v, double expected_distance, const TextureStyle& style,
                bool one_sided = false, float gain = -1.0f, int pool = -1) {
    Plane p;
    p.origin = origin;
    p.axis_u = axis_u.normalized();
    p.axis_v = axis_v.normalized();
    p.normal = p.axis_u.cross(p.axis_v).normalized();
    p.length_u = length_u;
    p.length_v = length_v;
    p.one_sided = one_sided;
    const uint64_t tex_seed = mixSeed(seed_, scene_->planes.size() + 1);
    Rng rng(tex_seed);
    p.gain = gain > 0 ? gain : static_cast<float>(rng.uniform(0.75, 1.1));
    if (pool >= 0 && pools_[pool].size() >= kPoolSize) {
      p.texture = pools_[pool][rng.next() % kPoolSize];
      p.offset_u = rng.uniform(0.0, 200.0);
      p.offset_v = rng.uniform(0.0, 200.0);
    } else {
      const double texel = std::clamp(expected_distance / kTexelsPerRadian, 0.003, 0.5);
      scene_->textures.push_back(makeTexture(length_u, length_v, texel, style, rng.next()));
      p.texture = static_cast<int>(scene_->textures.size()) - 1;
      if (pool >= 0) pools_[pool].push_back(p.texture);
    }
    scene_->planes.push_back(p);
  }

  /// Axis-aligned box (in the frame rotated by `yaw` about +y) standing on y = floor_y (y down),
  /// centre (cx, cz); its four sides and top, one-sided with outward normals.
  void addBox(double cx, double cz, double floor_y, double size_x, double size_z, double height, double yaw,
              double expected_distance, const TextureStyle& style, int pool = -1) {
    const Eigen::Vector3d ex(std::cos(yaw), 0, -std::sin(yaw)), ez(std::sin(yaw), 0, std::cos(yaw));
    const Eigen::Vector3d down(0, 1, 0);
    const Eigen::Vector3d centre_top(cx, floor_y - height, cz);
    const Eigen::Vector3d c000 = centre_top - 0.5 * size_x * ex - 0.5 * size_z * ez;  // a top corner
    const Eigen::Vector3d middle = centre_top + 0.5 * height * down;
    auto face = [&](const Eigen::Vector3d& origin, const Eigen::Vector3d& u, const Eigen::Vector3d& v, double lu,
                    double lv) {
      addPlane(origin, u, v, lu, lv, expected_distance, style, true, -1.0f, pool);
      fixOutward(middle);
    };
    face(c000, ex, down, size_x, height);                  // -z side
    face(c000 + size_z * ez, ex, down, size_x, height);    // +z side
    face(c000, ez, down, size_z, height);                  // -x side
    face(c000 + size_x * ex, ez, down, size_z, height);    // +x side
    face(c000, ex, ez, size_x, size_z);                    // top
  }

 private:
  /// Flips the last plane's normal so that it points away from `inside`.
  void fixOutward(const Eigen::Vector3d& inside) {
    Plane& p = scene_->planes.back();
    if (p.normal.dot(p.origin + 0.5 * p.length_u * p.axis_u + 0.5 * p.length_v * p.axis_v - inside) < 0)
      p.normal = -p.normal;
  }

  static constexpr size_t kPoolSize = 24;
  Scene* scene_;
  uint64_t seed_;
  std::map<int, std::vector<int>> pools_;
};

// ---------------------------------------------------------------------------------------------
// Trajectories
// ---------------------------------------------------------------------------------------------


/// A sinusoid that is zero at t = 0 (so the first camera frame is the world frame).
double wave(double amplitude, double frequency_hz, double phase, double t) {
  return amplitude * (std::sin(2.0 * kPi * frequency_hz * t + phase) - std::sin(phase));
}

class Trajectory {
 public:
  Trajectory(RenderPreset preset, double duration, double hand_translation_m)
      : preset_(preset), hand_(hand_translation_m) {
    if (isRoom() || preset_ == RenderPreset::kDroneNear) return;
    // Drive: integrate the heading into positions once (midpoint rule, 2 ms steps), covering a
    // stretch before the first and after the last frame so the scene extends past them.
    t_min_ = -3.0;
    const double t_max = duration + 8.0;
    const int n = static_cast<int>(std::ceil((t_max - t_min_) / kStep)) + 1;
    table_.resize(n);
    table_[0] = Eigen::Vector3d::Zero();
    for (int i = 1; i < n; ++i) {
      const double yaw = heading(t_min_ + (i - 0.5) * kStep);
      table_[i] = table_[i - 1] + kDriveSpeed * kStep * Eigen::Vector3d(std::sin(yaw), 0.0, std::cos(yaw));
    }
    const Eigen::Vector3d origin = interpolate(0.0);
    for (auto& p : table_) p -= origin;
  }

  double tMin() const { return t_min_; }
  double tMax() const { return t_min_ + (table_.size() - 1) * kStep; }

  /// Heading of the car (yaw of the camera without its small oscillations) [rad].
  double heading(double t) const {
    if (preset_ == RenderPreset::kForward) return wave(deg(0.3), 0.25, 0.7, t);
    if (t <= 0.0) return 0.0;
    // Repeating pattern of 6.5 s: a right turn over [0.5, 3.0] s and a left turn over
    // [3.5, 6.0] s, each a raised-cosine yaw rate peaking at 30 deg/s (3 deg/frame at 10 Hz).
    const double period = 6.5, width = 2.5, peak = deg(30.0);
    const double tau = t - period * std::floor(t / period);
    auto bump = [&](double x) {
      if (x <= 0.0) return 0.0;
      if (x >= width) return 0.5 * peak * width;
      return 0.5 * peak * (x - width / (2.0 * kPi) * std::sin(2.0 * kPi * x / width));
    };
    return bump(tau - 0.5) - bump(tau - 3.5);
  }

  void pose(double t, Eigen::Matrix3d* orientation, Eigen::Vector3d* position) const {
    if (isRoom()) {
      // Smooth rotation about all three axes, peak rates about 30, 23 and 19 deg/s (up to ~40 deg/s
      // together), and the hand's translation (by default millimetre jitter: a hand is never still).
      *orientation = rotationFromYawPitchRoll(wave(deg(16.0), 0.30, 0.4, t), wave(deg(8.0), 0.45, 1.3, t),
                                  wave(deg(5.0), 0.60, 2.1, t));
      const double hand = hand_ / kStillHandTranslationM;  // the still hand's jitter, scaled
      *position = hand * Eigen::Vector3d(wave(0.003, 1.3, 0.2, t), wave(0.002, 1.7, 0.9, t), wave(0.003, 1.1, 1.7, t));
      return;
    }
    if (preset_ == RenderPreset::kDroneNear) {
      // A drone shaken by hand in front of a pallet: peak rates about 45, 38 and 28 deg/s (up to
      // ~3 deg per frame at 20 Hz together) and translation of decimetres at up to ~0.9 m/s
      // (2-5 cm per frame at 20 Hz), 1-2 m from the structure: strong parallax, the rotation /
      // translation ambiguity of a close scene.
      *orientation = rotationFromYawPitchRoll(wave(deg(8.0), 0.9, 0.4, t), wave(deg(5.0), 1.2, 1.3, t),
                                  wave(deg(3.0), 1.5, 2.1, t));
      *position = Eigen::Vector3d(wave(0.12, 0.8, 0.3, t), wave(0.08, 1.1, 1.0, t), wave(0.06, 0.7, 1.9, t));
      return;
    }
    // Car: heading plus small pitch and roll oscillations (~0.1 deg/frame at 10 Hz for drive).
    const double scale = preset_ == RenderPreset::kForward ? 0.5 : 1.0;
    *orientation = rotationFromYawPitchRoll(heading(t), scale * wave(deg(0.25), 0.6, 0.3, t), scale * wave(deg(0.2), 0.7, 1.1, t));
    *position = interpolate(t);
  }

  Eigen::Vector3d interpolate(double t) const {
    const double x = std::clamp((t - t_min_) / kStep, 0.0, static_cast<double>(table_.size() - 1));
    const size_t i = std::min(static_cast<size_t>(x), table_.size() - 2);
    const double f = x - i;
    return (1.0 - f) * table_[i] + f * table_[i + 1];
  }

 private:
  /// Room presets: the hand-held rotation about a fixed point.
  bool isRoom() const { return preset_ == RenderPreset::kHandheld || preset_ == RenderPreset::kDim; }

  static constexpr double kStep = 0.002;  // [s]
  RenderPreset preset_;
  double hand_ = 0.0;  // room presets: the hand's translation amplitude [m]
  double t_min_ = 0.0;
  std::vector<Eigen::Vector3d> table_;
};

/// Distance in the ground (x-z) plane from p to segment [a, b].
double groundDistanceToSegment(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  const Eigen::Vector2d p2(p.x(), p.z()), a2(a.x(), a.z()), b2(b.x(), b.z());
  const Eigen::Vector2d ab = b2 - a2;
  const double len2 = ab.squaredNorm();
  const double s = len2 > 0 ? std::clamp((p2 - a2).dot(ab) / len2, 0.0, 1.0) : 0.0;
  return (p2 - (a2 + s * ab)).norm();
}

/// Where a street scene's objects may stand: the driven path (0.5 m apart) and the part the
/// rendered frames see (their centre and radius in the ground plane).
struct StreetLayout {
  std::vector<Eigen::Vector3d> path;
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();  ///< y = 0
  double radius = 0.0;  ///< [m] of the rendered positions around centre
  double s_max = 0.0;   ///< [m] arc length of the whole path

  /// Distance from the segment [a, b] near arc length s [m] to the path; the path never comes
  /// back on itself (the turns alternate), so only the stretch within 150 m is searched.
  double clearance(const Eigen::Vector3d& a, const Eigen::Vector3d& b, double s) const {
    const long centre_index = std::lround(s / (kDriveSpeed * 0.05));
    const size_t lo = static_cast<size_t>(std::max(0L, centre_index - 300));
    const size_t hi = std::min(path.size(), static_cast<size_t>(std::max(0L, centre_index + 300)));
    double d = std::numeric_limits<double>::infinity();
    for (size_t i = lo; i < hi; ++i) d = std::min(d, groundDistanceToSegment(path[i], a, b));
    return d;
  }
};

/// The layout of a drive along `trajectory` rendered over [0, duration] s.
StreetLayout streetLayout(const Trajectory& trajectory, double duration) {
  StreetLayout layout;
  for (double t = trajectory.tMin(); t <= trajectory.tMax(); t += 0.05) layout.path.push_back(trajectory.interpolate(t));
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  int inside = 0;
  for (double t = 0.0; t <= duration + 1e-9; t += 0.05, ++inside) centre += trajectory.interpolate(t);
  centre /= std::max(inside, 1);
  centre.y() = 0.0;
  double radius = 0.0;
  for (double t = 0.0; t <= duration + 1e-9; t += 0.05)
    radius = std::max(radius, (trajectory.interpolate(t) - centre).norm());
  layout.centre = centre;
  layout.radius = radius;
  layout.s_max = kDriveSpeed * (trajectory.tMax() - trajectory.tMin());
  return layout;
}

/// Facades on both sides, parallel to the local heading, 6-15 m out, with gaps; any that would
/// come within 4.5 m of the road (inside of a turn) are shortened or dropped.
void addFacades(const Trajectory& trajectory, const StreetLayout& layout, Rng* rng, SceneBuilder* builder) {
  const Eigen::Vector3d down(0, 1, 0);
  TextureStyle facade_style;
  for (int side = -1; side <= 1; side += 2) {
    double s = rng->uniform(0.0, 5.0);
    while (s < layout.s_max) {
      double length = rng->uniform(8.0, 25.0);
      const double gap = rng->uniform() < 0.2 ? rng->uniform(12.0, 25.0) : rng->uniform(2.0, 10.0);
      const double lateral = rng->uniform(6.0, 15.0), height = rng->uniform(4.0, 14.0);
      for (int attempt = 0; attempt < 2; ++attempt, length *= 0.5) {
        const double t = trajectory.tMin() + (s + 0.5 * length) / kDriveSpeed;
        const double h = trajectory.heading(t);
        const Eigen::Vector3d f(std::sin(h), 0, std::cos(h)), r(std::cos(h), 0, -std::sin(h));
        const Eigen::Vector3d a = trajectory.interpolate(t) + side * lateral * r - 0.5 * length * f;
        const Eigen::Vector3d b = a + length * f;
        if (layout.clearance(a, b, s + 0.5 * length) < 4.5) continue;
        builder->addPlane(Eigen::Vector3d(a.x(), kCameraHeight - height, a.z()), f, down, length, height,
                          1.5 * lateral, facade_style, false, -1.0f, /*pool=*/0);
        break;
      }
      s += length + gap;
    }
  }
}

/// Poles and boxes close to the road.
void addRoadsideObjects(const Trajectory& trajectory, const StreetLayout& layout, Rng* rng, SceneBuilder* builder) {
  TextureStyle object_style;
  object_style.max_shape = 40.0;
  for (double s = rng->uniform(5.0, 15.0); s < layout.s_max; s += rng->uniform(12.0, 30.0)) {
    const int side = rng->uniform() < 0.5 ? -1 : 1;
    const bool pole = rng->uniform() < 0.6;
    const double t = trajectory.tMin() + s / kDriveSpeed;
    const double h = trajectory.heading(t);
    const Eigen::Vector3d r(std::cos(h), 0, -std::sin(h));
    const double lateral = pole ? rng->uniform(3.0, 4.5) : rng->uniform(3.8, 5.5);
    const double sx = pole ? 0.25 : rng->uniform(1.0, 2.5), sz = pole ? 0.25 : rng->uniform(1.0, 4.5);
    const double height = pole ? rng->uniform(3.0, 6.0) : rng->uniform(0.8, 2.0);
    const double yaw = h + (pole ? 0.0 : rng->uniform(-0.3, 0.3));
    const Eigen::Vector3d c = trajectory.interpolate(t) + side * lateral * r;
    if (layout.clearance(c, c, s) < 0.5 * std::hypot(sx, sz) + 2.2) continue;
    builder->addBox(c.x(), c.z(), kCameraHeight, sx, sz, height, yaw, 4.0 * lateral, object_style, /*pool=*/1);
  }
}

/// Far backdrop: a ring of overlapping planes 60-180 m beyond the driven area, facing it, and on
/// long drives, which leave the ring far behind, more 60-200 m beside the road.
void addBackdrops(const Trajectory& trajectory, const StreetLayout& layout, Rng* rng, SceneBuilder* builder) {
  const Eigen::Vector3d down(0, 1, 0);
  TextureStyle far_style;
  far_style.min_shape = 2.0;
  far_style.max_shape = 40.0;
  const int ring = 16;
  for (int i = 0; i < ring; ++i) {
    const double theta = 2.0 * kPi * i / ring + rng->uniform(-0.08, 0.08);
    const double distance = layout.radius + rng->uniform(60.0, 180.0);
    const double width = 2.0 * distance * std::tan(kPi / ring) * 1.3;
    const double height = rng->uniform(20.0, 70.0);
    const Eigen::Vector3d q = layout.centre + distance * Eigen::Vector3d(std::sin(theta), 0, std::cos(theta));
    const Eigen::Vector3d u(std::cos(theta), 0, -std::sin(theta));
    const Eigen::Vector3d origin = q - 0.5 * width * u + Eigen::Vector3d(0, kCameraHeight - height, 0);
    builder->addPlane(origin, u, down, width, height, distance, far_style);
  }
  if (layout.radius <= 80.0) return;
  for (double s = rng->uniform(0.0, 40.0); s < layout.s_max; s += rng->uniform(40.0, 80.0)) {
    const int side = rng->uniform() < 0.5 ? -1 : 1;
    const double t = trajectory.tMin() + s / kDriveSpeed;
    const double h = trajectory.heading(t);
    const Eigen::Vector3d f(std::sin(h), 0, std::cos(h)), r(std::cos(h), 0, -std::sin(h));
    const double lateral = rng->uniform(60.0, 200.0), width = rng->uniform(60.0, 150.0);
    const double height = rng->uniform(20.0, 70.0);
    const Eigen::Vector3d a = trajectory.interpolate(t) + side * lateral * r - 0.5 * width * f;
    if (layout.clearance(a, a + width * f, s) < 50.0) continue;
    builder->addPlane(a + Eigen::Vector3d(0, kCameraHeight - height, 0), f, down, width, height, lateral, far_style,
                      false, -1.0f, /*pool=*/2);
  }
}

void buildStreetScene(const RenderSettings& settings, Scene* scene) {
  const double duration = (settings.frames - 1) / settings.rate_hz;
  const Trajectory trajectory(settings.preset, duration, settings.hand_translation_m);
  SceneBuilder builder(scene, settings.seed);
  Rng rng(mixSeed(settings.seed, 0x5354524545ull));
  const StreetLayout layout = streetLayout(trajectory, duration);

  // Ground: one huge rectangle; its 2048-texel texture repeats every ~51 m.
  TextureStyle ground_style;
  ground_style.mean_lo = 80;
  ground_style.mean_hi = 110;
  ground_style.shape_contrast = 60;
  ground_style.shape_density = 0.6;
  const double half = layout.radius + 700.0;
  builder.addPlane(Eigen::Vector3d(layout.centre.x() - half, kCameraHeight, layout.centre.z() - half),
                   Eigen::Vector3d::UnitX(), Eigen::Vector3d::UnitZ(), 2 * half, 2 * half, 0.025 * kTexelsPerRadian,
                   ground_style, false, 1.0f);
  // Drawn from one generator in this order, so a seed gives the same scene.
  addFacades(trajectory, layout, &rng, &builder);
  addRoadsideObjects(trajectory, layout, &rng, &builder);
  addBackdrops(trajectory, layout, &rng, &builder);

  // Sky: brightness gradient plus a weak cloud texture, far below FAST's threshold.
  scene->has_sky = true;
  TextureStyle sky_style;
  sky_style.shape_density = 0.0;
  sky_style.noise_amplitude = 4.0;
  sky_style.fine_amplitude = 0.5;
  sky_style.mean_lo = sky_style.mean_hi = 128.0;
  scene->sky = makeTexture(512, 512, 1.0, sky_style, mixSeed(settings.seed, 0x534B59ull));
}

// The hand-held room: x in [-3.2, 3.8], y in [-1.6, 1.4] (y down: floor below), z in [-4.5, 6.5];
// the camera at the origin.
constexpr double kRoomX0 = -3.2, kRoomX1 = 3.8, kRoomY0 = -1.6, kRoomY1 = 1.4, kRoomZ0 = -4.5, kRoomZ1 = 6.5;

/// Floor, ceiling and the four walls of the room, in `style`; gain < 0: a random brightness per
/// plane.
void addRoomShell(SceneBuilder* builder, const TextureStyle& style, float gain) {
  const double x0 = kRoomX0, x1 = kRoomX1, y0 = kRoomY0, y1 = kRoomY1, z0 = kRoomZ0, z1 = kRoomZ1;
  const Eigen::Vector3d ux = Eigen::Vector3d::UnitX(), uy = Eigen::Vector3d::UnitY(), uz = Eigen::Vector3d::UnitZ();
  builder->addPlane({x0, y1, z0}, ux, uz, x1 - x0, z1 - z0, 2.5, style, false, gain);  // floor
  builder->addPlane({x0, y0, z0}, ux, uz, x1 - x0, z1 - z0, 3.0, style, false, gain);  // ceiling
  builder->addPlane({x0, y0, z1}, ux, uy, x1 - x0, y1 - y0, 6.5, style, false, gain);  // front
  builder->addPlane({x0, y0, z0}, ux, uy, x1 - x0, y1 - y0, 4.5, style, false, gain);  // back
  builder->addPlane({x0, y0, z0}, uz, uy, z1 - z0, y1 - y0, 3.5, style, false, gain);  // left
  builder->addPlane({x1, y0, z0}, uz, uy, z1 - z0, y1 - y0, 4.0, style, false, gain);  // right
}

/// Up to `count` boxes standing on the room's floor at random places (200 tries), each side in
/// [side_min, 1.5] m, `height` tall, at least `clearance` m plus half its diagonal from the camera.
void placeRoomBoxes(SceneBuilder* builder, Rng* rng, int count, double side_min, double height_min,
                    double height_max, double clearance, const TextureStyle& style) {
  int placed = 0;
  for (int attempt = 0; attempt < 200 && placed < count; ++attempt) {
    const double sx = rng->uniform(side_min, 1.5), sz = rng->uniform(side_min, 1.5),
                 height = rng->uniform(height_min, height_max);
    const double cx = rng->uniform(kRoomX0 + 0.8, kRoomX1 - 0.8), cz = rng->uniform(kRoomZ0 + 0.8, kRoomZ1 - 0.8);
    if (std::hypot(cx, cz) < clearance + 0.5 * std::hypot(sx, sz)) continue;
    builder->addBox(cx, cz, kRoomY1, sx, sz, height, rng->uniform(-0.6, 0.6), std::hypot(cx, cz), style);
    ++placed;
  }
}

void buildRoomScene(const RenderSettings& settings, Scene* scene) {
  SceneBuilder builder(scene, settings.seed);
  Rng rng(mixSeed(settings.seed, 0x524F4F4Dull));
  addRoomShell(&builder, TextureStyle(), -1.0f);
  // Furniture-like boxes at 1.8 m or more from the camera.
  TextureStyle object_style;
  object_style.max_shape = 50.0;
  placeRoomBoxes(&builder, &rng, 7, 0.4, 0.5, 2.4, 1.8, object_style);
}

/// Structure 1-2 m in front of the camera: a pallet-like box stack, a back wall, the floor and
/// side walls, all textured; nothing far away, so every match carries parallax.
void buildNearScene(const RenderSettings& settings, Scene* scene) {
  SceneBuilder builder(scene, settings.seed);
  Rng rng(mixSeed(settings.seed, 0x4E454152ull));
  const Eigen::Vector3d ux = Eigen::Vector3d::UnitX(), uy = Eigen::Vector3d::UnitY(), uz = Eigen::Vector3d::UnitZ();
  const TextureStyle wall;
  // Floor 1.1 m below the camera, back wall 2.4 m ahead, side walls 1.8 m to each side.
  const double x0 = -1.8, x1 = 1.8, y0 = -1.5, y1 = 1.1, z0 = -1.0, z1 = 2.4;
  builder.addPlane({x0, y1, z0}, ux, uz, x1 - x0, z1 - z0, 1.4, wall);  // floor
  builder.addPlane({x0, y0, z1}, ux, uy, x1 - x0, y1 - y0, 2.4, wall);  // back wall
  builder.addPlane({x0, y0, z0}, uz, uy, z1 - z0, y1 - y0, 1.9, wall);  // left
  builder.addPlane({x1, y0, z0}, uz, uy, z1 - z0, y1 - y0, 1.9, wall);  // right
  // The pallet: boxes 1.1-1.6 m ahead, standing on the floor.
  TextureStyle object_style;
  object_style.max_shape = 40.0;
  for (int i = 0; i < 4; ++i) {
    const double cx = -0.9 + 0.6 * i + rng.uniform(-0.1, 0.1), cz = rng.uniform(1.1, 1.6);
    builder.addBox(cx, cz, y1, rng.uniform(0.35, 0.55), rng.uniform(0.3, 0.5), rng.uniform(0.6, 1.6),
                   rng.uniform(-0.3, 0.3), cz, object_style);
  }
}

/// The dim room: the hand-held room's size, with large plain walls of faint texture, a few
/// doors and boxes, every grey level within kDimLow..kDimHigh (30 levels), as in a dim indoor
/// room filmed with a consumer camera.
constexpr double kDimLow = 45.0, kDimHigh = 75.0;

void buildDimRoomScene(const RenderSettings& settings, Scene* scene) {
  SceneBuilder builder(scene, settings.seed);
  Rng rng(mixSeed(settings.seed, 0x44494Dull));
  const double x0 = kRoomX0, x1 = kRoomX1, y1 = kRoomY1, z0 = kRoomZ0, z1 = kRoomZ1;
  const Eigen::Vector3d ux = Eigen::Vector3d::UnitX(), uy = Eigen::Vector3d::UnitY(), uz = Eigen::Vector3d::UnitZ();
  // Plain paint: weak shading and faint marks (scuffs, switches, pictures), all within the band.
  TextureStyle wall;
  wall.mean_lo = 57.0;
  wall.mean_hi = 63.0;
  wall.noise_amplitude = 3.0;
  wall.fine_amplitude = 1.5;
  wall.shape_density = 0.6;
  wall.min_shape = 4.0;
  wall.max_shape = 60.0;
  wall.shape_contrast = 14.0;
  const float plain = 1.0f;  // no per-plane brightness change: the contrast stays in the textures
  addRoomShell(&builder, wall, plain);
  // Doors: 0.9 x 2.0 m, 1 cm in front of a wall, darker or lighter than it, with a faint grain.
  TextureStyle door = wall;
  door.shape_density = 0.05;
  const double door_w = 0.9, door_h = 2.0, gap = 0.01;
  for (int d = 0; d < 4; ++d) {
    door.mean_lo = door.mean_hi = rng.uniform() < 0.5 ? 50.0 : 70.0;
    const double along = rng.uniform(0.3, 1.0 - 0.3);
    switch (d) {
      case 0: builder.addPlane({x0 + along * (x1 - x0 - door_w), y1 - door_h, z1 - gap}, ux, uy, door_w, door_h, 6.5, door, false, plain); break;
      case 1: builder.addPlane({x0 + gap, y1 - door_h, z0 + along * (z1 - z0 - door_w)}, uz, uy, door_w, door_h, 3.5, door, false, plain); break;
      case 2: builder.addPlane({x1 - gap, y1 - door_h, z0 + along * (z1 - z0 - door_w)}, uz, uy, door_w, door_h, 4.0, door, false, plain); break;
      default: builder.addPlane({x0 + along * (x1 - x0 - door_w), y1 - door_h, z0 + gap}, ux, uy, door_w, door_h, 4.5, door, false, plain); break;
    }
  }
  // A few plain boxes (cupboards, a table) give edges at other depths.
  TextureStyle box = wall;
  box.mean_lo = 50.0;
  box.mean_hi = 70.0;
  placeRoomBoxes(&builder, &rng, 4, 0.5, 0.7, 2.2, 2.0, box);
  for (Plane& p : scene->planes) p.gain = plain;
  // Every grey level within the 30-level band.
  for (Texture& t : scene->textures)
    for (cv::Mat& level : t.levels) level = cv::max(cv::min(level, kDimHigh), kDimLow);
  scene->background = static_cast<float>(0.5 * (kDimLow + kDimHigh));
}

std::string sceneKey(const RenderSettings& s) {
  std::ostringstream key;
  key << presetName(s.preset) << '/' << s.seed;
  if (s.preset == RenderPreset::kDrive || s.preset == RenderPreset::kForward) key << '/' << s.frames << '/' << s.rate_hz;
  return key.str();
}

/// Scenes take ~0.1-1 s to build, so the last one is kept for renderView() loops.
std::shared_ptr<const Scene> sceneFor(const RenderSettings& settings) {
  static std::mutex mutex;
  static std::string cached_key;
  static std::shared_ptr<const Scene> cached;
  const std::string key = sceneKey(settings);
  std::lock_guard<std::mutex> lock(mutex);
  if (cached && cached_key == key) return cached;
  auto scene = std::make_shared<Scene>();
  if (settings.preset == RenderPreset::kHandheld) {
    buildRoomScene(settings, scene.get());
  } else if (settings.preset == RenderPreset::kDroneNear) {
    buildNearScene(settings, scene.get());
  } else if (settings.preset == RenderPreset::kDim) {
    buildDimRoomScene(settings, scene.get());
  } else {
    buildStreetScene(settings, scene.get());
  }
  cached = scene;
  cached_key = key;
  return cached;
}

constexpr RenderPreset kPresets[] = {RenderPreset::kDrive, RenderPreset::kHandheld, RenderPreset::kForward,
                                     RenderPreset::kDim, RenderPreset::kDroneNear};

/// The settings' degradations, blurring along `blur_direction`.
ImageDegradation degradationOf(const RenderSettings& s, const Eigen::Vector2d& blur_direction) {
  ImageDegradation d;
  d.contrast = s.contrast;
  d.blur_px = s.blur_px;
  d.blur_direction = blur_direction;
  d.noise_sigma = s.noise_sigma;
  d.jpeg_quality = s.jpeg_quality;
  return d;
}

void validate(const RenderSettings& s) {
  RenderPreset known;
  if (!parsePreset(presetName(s.preset), &known)) throw std::invalid_argument("renderer: unknown preset");
  if (s.width < 8 || s.height < 8 || s.width > 16384 || s.height > 16384)
    throw std::invalid_argument("renderer: image size " + std::to_string(s.width) + "x" + std::to_string(s.height) +
                                " out of range [8, 16384]");
  if (s.frames < 1 || s.frames > 1000000) throw std::invalid_argument("renderer: frames must be >= 1");
  if (!(std::isfinite(s.fx) && std::isfinite(s.fy) && s.fx > 0 && s.fy > 0))
    throw std::invalid_argument("renderer: focal lengths must be finite and positive");
  if (!(std::isfinite(s.cx) && std::isfinite(s.cy))) throw std::invalid_argument("renderer: non-finite principal point");
  if (!(std::isfinite(s.rate_hz) && s.rate_hz > 0)) throw std::invalid_argument("renderer: rate must be positive");
  if (!(std::isfinite(s.rolling_shutter_s) && s.rolling_shutter_s >= 0 && s.rolling_shutter_s <= 1.0 / s.rate_hz))
    throw std::invalid_argument("renderer: rolling shutter read-out time must be in [0, 1 / rate] s");
  if (!(std::isfinite(s.hand_translation_m) && s.hand_translation_m >= 0 && s.hand_translation_m <= 1.0))
    throw std::invalid_argument("renderer: hand translation must be in [0, 1] m");
  checkDegradation(degradationOf(s, Eigen::Vector2d::UnitX()), "renderer");
}

/// Line kernel of `length` px along the unit direction `direction` (image x right, y down),
/// centred, anti-aliased by splatting many points along the line bilinearly; sums to 1.
cv::Mat motionBlurKernel(double length, const Eigen::Vector2d& direction) {
  const int half = static_cast<int>(std::ceil(0.5 * length)) + 1;
  cv::Mat kernel(2 * half + 1, 2 * half + 1, CV_32F, cv::Scalar(0));
  const int steps = std::max(2, static_cast<int>(std::ceil(length * 16.0)));
  for (int k = 0; k <= steps; ++k) {
    const double s = length * (static_cast<double>(k) / steps - 0.5);
    const double x = half + s * direction.x(), y = half + s * direction.y();
    const int xi = fastFloor(x), yi = fastFloor(y);
    const float fx = static_cast<float>(x - xi), fy = static_cast<float>(y - yi);
    kernel.at<float>(yi, xi) += (1 - fx) * (1 - fy);
    kernel.at<float>(yi, xi + 1) += fx * (1 - fy);
    kernel.at<float>(yi + 1, xi) += (1 - fx) * fy;
    kernel.at<float>(yi + 1, xi + 1) += fx * fy;
  }
  return kernel / cv::sum(kernel)[0];
}

/// Per-frame constants of one plane: every dot product with the sample ray d(i, j) is linear in
/// the sample indices, so the inner loops need one division per plane and sample.
struct PlaneView {
  double numer;          // n . o (camera frame)
  double ni, nj, n0;     // n . d(i, j) = ni * i + nj * j + n0
  double ui, uj, u0, a0; // a = t * (u . d) - a0
  double vi, vj, v0, b0;
  double length_u, length_v;
  double offset_u, offset_v;
  double inv_texel_footprint;  // 1 / (f * texel), for the mip level
  const Texture* texture;
  float gain;
  int i0, i1, j0, j1;    // sample bounding box
};

/// Clips a convex polygon (camera frame) to z >= near (Sutherland-Hodgman).
std::vector<Eigen::Vector3d> clipNear(const std::vector<Eigen::Vector3d>& poly, double near) {
  std::vector<Eigen::Vector3d> out;
  for (size_t k = 0; k < poly.size(); ++k) {
    const Eigen::Vector3d& a = poly[k];
    const Eigen::Vector3d& b = poly[(k + 1) % poly.size()];
    const bool in_a = a.z() >= near, in_b = b.z() >= near;
    if (in_a) out.push_back(a);
    if (in_a != in_b) out.push_back(a + (b - a) * ((near - a.z()) / (b.z() - a.z())));
  }
  return out;
}

/// Rays of the supersamples: sample (i, j) sits at pixel (u, v) = ((i + 0.5) / 2 - 0.5,
/// (j + 0.5) / 2 - 0.5); its ray in the camera frame is d = (ax i + bx, ay j + by, 1), so t along d
/// is the depth.
struct SampleRays {
  double ax, bx, ay, by;
  explicit SampleRays(const RenderSettings& s)
      : ax(1.0 / (kSamples * s.fx)), bx(((0.5 / kSamples - 0.5) - s.cx) / s.fx),
        ay(1.0 / (kSamples * s.fy)), by(((0.5 / kSamples - 0.5) - s.cy) / s.fy) {}
};

/// The planes seen from one pose (camera -> world) within the sample rows [j_begin, j_end).
std::vector<PlaneView> planeViews(const Scene& scene, const RenderSettings& s, const SampleRays& rays,
                                  const Eigen::Matrix3d& orientation, const Eigen::Vector3d& position, int j_begin,
                                  int j_end) {
  const double ax = rays.ax, bx = rays.bx, ay = rays.ay, by = rays.by;
  const int sw = s.width * kSamples;
  const double focal = std::sqrt(s.fx * s.fy);
  const Eigen::Matrix3d Rt = orientation.transpose();
  std::vector<PlaneView> views;
  views.reserve(scene.planes.size());
  for (const Plane& p : scene.planes) {
    const Eigen::Vector3d o = Rt * (p.origin - position);
    const Eigen::Vector3d u = Rt * p.axis_u, v = Rt * p.axis_v, n = Rt * p.normal;
    const double numer = n.dot(o);
    if (std::abs(numer) < 1e-9) continue;        // camera inside the plane: seen edge-on
    if (p.one_sided && numer > 0) continue;       // camera behind a box face
    auto poly = clipNear({o, o + p.length_u * u, o + p.length_u * u + p.length_v * v, o + p.length_v * v}, kNearDepth);
    if (poly.size() < 3) continue;
    double imin = 1e300, imax = -1e300, jmin = 1e300, jmax = -1e300;
    for (const auto& q : poly) {
      const double i = (q.x() / q.z() - bx) / ax, j = (q.y() / q.z() - by) / ay;
      imin = std::min(imin, i), imax = std::max(imax, i), jmin = std::min(jmin, j), jmax = std::max(jmax, j);
    }
    PlaneView pv;
    pv.i0 = static_cast<int>(std::max(0.0, std::floor(imin) - 1));
    pv.i1 = static_cast<int>(std::min(sw - 1.0, std::ceil(imax) + 1));
    pv.j0 = static_cast<int>(std::max(static_cast<double>(j_begin), std::floor(jmin) - 1));
    pv.j1 = static_cast<int>(std::min(j_end - 1.0, std::ceil(jmax) + 1));
    if (pv.i0 > pv.i1 || pv.j0 > pv.j1) continue;
    pv.numer = numer;
    pv.ni = n.x() * ax, pv.nj = n.y() * ay, pv.n0 = n.x() * bx + n.y() * by + n.z();
    pv.ui = u.x() * ax, pv.uj = u.y() * ay, pv.u0 = u.x() * bx + u.y() * by + u.z(), pv.a0 = u.dot(o);
    pv.vi = v.x() * ax, pv.vj = v.y() * ay, pv.v0 = v.x() * bx + v.y() * by + v.z(), pv.b0 = v.dot(o);
    pv.length_u = p.length_u, pv.length_v = p.length_v;
    pv.offset_u = p.offset_u, pv.offset_v = p.offset_v;
    pv.texture = &scene.textures[p.texture];
    pv.inv_texel_footprint = 1.0 / (kSamples * focal * pv.texture->texel);
    pv.gain = p.gain;
    views.push_back(pv);
  }
  return views;
}

/// Adds the grey levels (before any degradation) of the pixel rows [row_begin, row_end), seen from
/// one pose (camera -> world), to `acc` (CV_32F, the whole image, zero there).
void shadeRows(const Scene& scene, const RenderSettings& s, const Eigen::Matrix3d& orientation,
               const Eigen::Vector3d& position, int row_begin, int row_end, cv::Mat* acc) {
  const int sw = s.width * kSamples;
  const int j_begin = row_begin * kSamples, j_end = row_end * kSamples;  // sample rows
  const SampleRays rays(s);
  const double ax = rays.ax, bx = rays.bx, ay = rays.ay, by = rays.by;
  const std::vector<PlaneView> views = planeViews(scene, s, rays, orientation, position, j_begin, j_end);

  // Pass 1: nearest hit per sample.
  const size_t band = static_cast<size_t>(sw) * (j_end - j_begin);
  std::vector<float> depth(band, std::numeric_limits<float>::infinity());
  std::vector<int32_t> hit(band, -1);
  for (size_t k = 0; k < views.size(); ++k) {
    const PlaneView& pv = views[k];
    for (int j = pv.j0; j <= pv.j1; ++j) {
      const double dn = pv.nj * j + pv.n0, du = pv.uj * j + pv.u0, dv = pv.vj * j + pv.v0;
      float* depth_row = depth.data() + static_cast<size_t>(j - j_begin) * sw;
      int32_t* hit_row = hit.data() + static_cast<size_t>(j - j_begin) * sw;
      for (int i = pv.i0; i <= pv.i1; ++i) {
        const double t = pv.numer / (dn + pv.ni * i);
        if (!(t > kNearDepth) || t >= depth_row[i]) continue;
        const double a = t * (du + pv.ui * i) - pv.a0;
        if (a < 0.0 || a > pv.length_u) continue;
        const double b = t * (dv + pv.vi * i) - pv.b0;
        if (b < 0.0 || b > pv.length_v) continue;
        depth_row[i] = static_cast<float>(t);
        hit_row[i] = static_cast<int32_t>(k);
      }
    }
  }

  // Pass 2: shade and box-filter the samples into pixels.
  const float weight = 1.0f / (kSamples * kSamples);
  for (int j = j_begin; j < j_end; ++j) {
    float* acc_row = acc->ptr<float>(j / kSamples);
    const int32_t* hit_row = hit.data() + static_cast<size_t>(j - j_begin) * sw;
    const float* depth_row = depth.data() + static_cast<size_t>(j - j_begin) * sw;
    const double dy = ay * j + by;
    for (int i = 0; i < sw; ++i) {
      const double dx = ax * i + bx;
      float value;
      if (hit_row[i] >= 0) {
        const PlaneView& pv = views[hit_row[i]];
        const double den = pv.nj * j + pv.n0 + pv.ni * i;
        const double t = depth_row[i];
        const double a = t * (pv.uj * j + pv.u0 + pv.ui * i) - pv.a0;
        const double b = t * (pv.vj * j + pv.v0 + pv.vi * i) - pv.b0;
        // Footprint of a sample in texels: range / focal / sqrt(cos incidence), the geometric
        // mean of the footprint's two axes on a slanted surface.
        const double dnorm = std::sqrt(dx * dx + dy * dy + 1.0);
        const double cos_incidence = std::max(std::abs(den) / dnorm, 1e-6);
        const float footprint = static_cast<float>(t * dnorm * pv.inv_texel_footprint / std::sqrt(cos_incidence));
        value = pv.gain * sampleTexture(*pv.texture, a + pv.offset_u, b + pv.offset_v, footprint);
      } else if (scene.has_sky) {
        const Eigen::Vector3d d = orientation * Eigen::Vector3d(dx, dy, 1.0);
        const double inv = 1.0 / d.norm();
        const double up = -d.y() * inv;  // world y points down
        value = static_cast<float>(175.0 + 55.0 * std::max(up, 0.0) + 20.0 * std::min(up, 0.0)) +
                (sampleLevel(scene.sky, 0, 256.0 * d.x() * inv, 256.0 * d.z() * inv) - 128.0f);
      } else {
        value = scene.background;
      }
      acc_row[i / kSamples] += weight * value;
    }
  }
}

/// One view from one pose, degraded.
cv::Mat renderScene(const Scene& scene, const RenderSettings& s, const Eigen::Matrix3d& orientation,
                    const Eigen::Vector3d& position, uint64_t noise_seed, const Eigen::Vector2d& blur_direction) {
  cv::Mat acc(s.height, s.width, CV_32F, cv::Scalar(0));
  shadeRows(scene, s, orientation, position, 0, s.height, &acc);
  return degradeImage(acc, degradationOf(s, blur_direction), noise_seed);
}

/// Time of pixel row `row` relative to the frame's stamp [s] (the middle row's time).
double rowTimeOffset(const RenderSettings& s, int row) {
  return (static_cast<double>(row) / (s.height - 1) - 0.5) * s.rolling_shutter_s;
}

/// The frame stamped `t`: one pose for the whole image (global shutter), or each pixel row from the
/// pose at its own time (rolling shutter), then degraded once, as a sensor's read-out would be.
cv::Mat renderFrame(const Scene& scene, const RenderSettings& s, const Trajectory& trajectory, double t,
                    uint64_t noise_seed, const Eigen::Vector2d& blur_direction) {
  Eigen::Matrix3d orientation;
  Eigen::Vector3d position;
  if (s.rolling_shutter_s == 0.0) {
    trajectory.pose(t, &orientation, &position);
    return renderScene(scene, s, orientation, position, noise_seed, blur_direction);
  }
  cv::Mat acc(s.height, s.width, CV_32F, cv::Scalar(0));
  for (int row = 0; row < s.height; ++row) {
    trajectory.pose(t + rowTimeOffset(s, row), &orientation, &position);
    shadeRows(scene, s, orientation, position, row, row + 1, &acc);
  }
  return degradeImage(acc, degradationOf(s, blur_direction), noise_seed);
}

/// Direction of the image motion at the principal point over one frame interval centred on t
/// (the rotation's: a far point on the optical axis), +x when the camera does not turn.
Eigen::Vector2d imageMotionDirection(const Trajectory& trajectory, const RenderSettings& s, double t) {
  const double h = 0.5 / s.rate_hz;
  Eigen::Matrix3d before, after;
  Eigen::Vector3d position;
  trajectory.pose(t - h, &before, &position);
  trajectory.pose(t + h, &after, &position);
  // The optical axis at t - h, seen from the camera at t + h.
  const Eigen::Vector3d ray = after.transpose() * before * Eigen::Vector3d::UnitZ();
  if (!(ray.z() > 0.0)) return Eigen::Vector2d::UnitX();
  const Eigen::Vector2d flow(s.fx * ray.x() / ray.z(), s.fy * ray.y() / ray.z());
  return flow.norm() > 1e-6 ? Eigen::Vector2d(flow / flow.norm()) : Eigen::Vector2d::UnitX();
}

}  // namespace

const char* presetName(RenderPreset preset) {
  switch (preset) {
    case RenderPreset::kHandheld: return "handheld";
    case RenderPreset::kForward: return "forward";
    case RenderPreset::kDim: return "dim";
    case RenderPreset::kDroneNear: return "drone_near";
    case RenderPreset::kDrive: break;
  }
  return "drive";
}

bool parsePreset(const std::string& name, RenderPreset* preset) {
  for (const RenderPreset p : kPresets) {
    if (name == presetName(p)) {
      *preset = p;
      return true;
    }
  }
  return false;
}

double presetRateHz(RenderPreset preset) {
  switch (preset) {
    case RenderPreset::kHandheld:
    case RenderPreset::kDim: return 30.0;
    case RenderPreset::kDroneNear: return 20.0;
    case RenderPreset::kDrive:
    case RenderPreset::kForward: break;
  }
  return 10.0;
}

void checkDegradation(const ImageDegradation& d, const std::string& who) {
  if (!(std::isfinite(d.noise_sigma) && d.noise_sigma >= 0))
    throw std::invalid_argument(who + ": noise sigma must be finite and >= 0");
  if (!(std::isfinite(d.gain_jitter) && d.gain_jitter >= 0 && d.gain_jitter <= 0.9))
    throw std::invalid_argument(who + ": gain jitter must be in [0, 0.9]");
  if (!(std::isfinite(d.contrast) && d.contrast > 0 && d.contrast <= 100))
    throw std::invalid_argument(who + ": contrast must be in (0, 100]");
  if (!(std::isfinite(d.blur_px) && d.blur_px >= 0 && d.blur_px <= 200))
    throw std::invalid_argument(who + ": blur must be in [0, 200] px");
  if (!(d.blur_direction.allFinite() && std::abs(d.blur_direction.norm() - 1.0) < 1e-6))
    throw std::invalid_argument(who + ": blur direction must be a unit vector");
  if (d.stuck_pixels < 0 || d.stuck_pixels > 100000)
    throw std::invalid_argument(who + ": stuck pixels must be in [0, 100000]");
  if (d.jpeg_quality < 0 || d.jpeg_quality > 100)
    throw std::invalid_argument(who + ": JPEG quality must be in 1..100 (0 = no JPEG)");
}

cv::Mat degradeImage(const cv::Mat& image, const ImageDegradation& d, uint64_t noise_seed) {
  checkDegradation(d, "image degradation");
  if (image.type() != CV_8UC1 && image.type() != CV_32FC1)
    throw std::invalid_argument("image degradation: the image must be CV_8UC1 or CV_32FC1");
  cv::Mat scene;
  // An exposure's gain scales the light the sensor gathers, before its noise; the bright end then
  // saturates at the rounding below.
  double gain = 1.0;
  if (d.gain_jitter > 0.0) gain += Rng(mixSeed(noise_seed, 0x4741494Eull)).uniform(-d.gain_jitter, d.gain_jitter);
  image.convertTo(scene, CV_32F, gain);
  // Contrast and blur act on the noiseless grey levels, as a dimmer or moving scene would.
  if (d.contrast != 1.0) {
    const double mean = cv::mean(scene)[0];
    scene.convertTo(scene, CV_32F, d.contrast, (1.0 - d.contrast) * mean);
  }
  if (d.blur_px > 0.0) {
    cv::filter2D(scene, scene, CV_32F, motionBlurKernel(d.blur_px, d.blur_direction), cv::Point(-1, -1), 0,
                 cv::BORDER_REFLECT_101);
  }
  cv::Mat out(scene.rows, scene.cols, CV_8UC1);
  Rng noise(noise_seed);
  for (int y = 0; y < scene.rows; ++y) {
    const float* row = scene.ptr<float>(y);
    uint8_t* to = out.ptr<uint8_t>(y);
    for (int x = 0; x < scene.cols; ++x) {
      const double v = row[x] + (d.noise_sigma > 0 ? d.noise_sigma * noise.normal() : 0.0);
      to[x] = static_cast<uint8_t>(std::clamp(v, 0.0, 255.0) + 0.5);
    }
  }
  // A sensor's defects belong to the sensor: the same places in every image, whatever the seed.
  Rng stuck(mixSeed(static_cast<uint64_t>(out.cols) << 32 | static_cast<uint64_t>(out.rows), 0x535455434Bull));
  for (int k = 0; k < d.stuck_pixels; ++k) {
    const int x = static_cast<int>(stuck.next() % static_cast<uint64_t>(out.cols));
    const int y = static_cast<int>(stuck.next() % static_cast<uint64_t>(out.rows));
    out.at<uint8_t>(y, x) = 255;
  }
  if (d.jpeg_quality > 0) {
    std::vector<uchar> bytes;
    if (!cv::imencode(".jpg", out, bytes, {cv::IMWRITE_JPEG_QUALITY, d.jpeg_quality}))
      throw std::runtime_error("image degradation: JPEG encoding failed");
    out = cv::imdecode(bytes, cv::IMREAD_GRAYSCALE);
    if (out.empty()) throw std::runtime_error("image degradation: JPEG decoding failed");
  }
  return out;
}

RenderedSequence renderSequence(const RenderSettings& settings) {
  validate(settings);
  const auto scene = sceneFor(settings);
  const double duration = (settings.frames - 1) / settings.rate_hz;
  const Trajectory trajectory(settings.preset, duration, settings.hand_translation_m);
  RenderedSequence out;
  out.K << settings.fx, 0, settings.cx, 0, settings.fy, settings.cy, 0, 0, 1;
  for (int k = 0; k < settings.frames; ++k) {
    const double t = k / settings.rate_hz;
    Eigen::Matrix3d orientation;
    Eigen::Vector3d position;
    trajectory.pose(t, &orientation, &position);
    out.images.push_back(renderFrame(*scene, settings, trajectory, t, mixSeed(settings.seed, 1000 + k),
                                     imageMotionDirection(trajectory, settings, t)));
    out.orientations.push_back(orientation);
    out.positions.push_back(position);
    out.stamps.push_back(t);
  }
  return out;
}

void presetPose(const RenderSettings& settings, double t, Eigen::Matrix3d* orientation, Eigen::Vector3d* position) {
  validate(settings);
  if (!std::isfinite(t)) throw std::invalid_argument("presetPose: non-finite time");
  const Trajectory trajectory(settings.preset, (settings.frames - 1) / settings.rate_hz, settings.hand_translation_m);
  trajectory.pose(t, orientation, position);
}

cv::Mat renderView(const RenderSettings& settings, const Eigen::Matrix3d& orientation,
                   const Eigen::Vector3d& position) {
  validate(settings);
  if (!orientation.allFinite() || !position.allFinite())
    throw std::invalid_argument("renderView: non-finite pose");
  const auto scene = sceneFor(settings);
  return renderScene(*scene, settings, orientation, position, mixSeed(settings.seed, 0x56494557ull),
                     Eigen::Vector2d::UnitX());
}

void writeKittiLayout(const RenderedSequence& sequence, const std::string& folder) {
  const size_t n = sequence.images.size();
  if (n == 0 || sequence.orientations.size() != n || sequence.positions.size() != n || sequence.stamps.size() != n)
    throw std::invalid_argument("writeKittiLayout: images, orientations, positions and stamps must be non-empty and "
                                "of equal length");
  namespace fs = std::filesystem;
  const fs::path root(folder), images = root / "image_l";
  std::error_code ec;
  fs::create_directories(images, ec);
  if (ec || !fs::is_directory(images))
    throw std::runtime_error("writeKittiLayout: cannot create " + images.string() + (ec ? ": " + ec.message() : ""));
  for (size_t k = 0; k < n; ++k) {
    char name[32];
    std::snprintf(name, sizeof(name), "%06zu.png", k);
    const fs::path path = images / name;
    bool ok = false;
    try {
      ok = cv::imwrite(path.string(), sequence.images[k]);
    } catch (const cv::Exception& e) {
      throw std::runtime_error("writeKittiLayout: cannot write " + path.string() + ": " + e.what());
    }
    if (!ok) throw std::runtime_error("writeKittiLayout: cannot write " + path.string());
  }
  auto open = [&](const std::string& name) {
    auto stream = std::make_unique<std::ofstream>(root / name);
    if (!*stream) throw std::runtime_error("writeKittiLayout: cannot write " + (root / name).string());
    return stream;
  };
  auto check = [&](std::ofstream& stream, const std::string& name) {
    stream.close();
    if (!stream) throw std::runtime_error("writeKittiLayout: error writing " + (root / name).string());
  };
  {
    // KITTI odometry style: P0 (left) and P1 (right camera, 0.54 m baseline like KITTI's).
    const Eigen::Matrix3d& K = sequence.K;
    auto calib = open("calib.txt");
    char line[512];
    for (int cam = 0; cam < 2; ++cam) {
      const double tx = cam == 0 ? 0.0 : -K(0, 0) * 0.54;
      std::snprintf(line, sizeof(line),
                    "P%d: %.12e %.12e %.12e %.12e %.12e %.12e %.12e %.12e %.12e %.12e %.12e %.12e\n", cam, K(0, 0),
                    K(0, 1), K(0, 2), tx, K(1, 0), K(1, 1), K(1, 2), 0.0, K(2, 0), K(2, 1), K(2, 2), 0.0);
      *calib << line;
    }
    check(*calib, "calib.txt");
  }
  {
    auto poses = open("poses.txt");
    char line[512];
    for (size_t k = 0; k < n; ++k) {
      const Eigen::Matrix3d& R = sequence.orientations[k];
      const Eigen::Vector3d& p = sequence.positions[k];
      std::snprintf(line, sizeof(line), "%.9e %.9e %.9e %.9e %.9e %.9e %.9e %.9e %.9e %.9e %.9e %.9e\n", R(0, 0),
                    R(0, 1), R(0, 2), p.x(), R(1, 0), R(1, 1), R(1, 2), p.y(), R(2, 0), R(2, 1), R(2, 2), p.z());
      *poses << line;
    }
    check(*poses, "poses.txt");
  }
  {
    auto times = open("times.txt");
    char line[64];
    for (size_t k = 0; k < n; ++k) {
      std::snprintf(line, sizeof(line), "%.9e\n", sequence.stamps[k]);
      *times << line;
    }
    check(*times, "times.txt");
  }
  {
    // The poses are the ones the images were rendered from: exact.
    auto sigma = open(kTruthSigmaFile);
    *sigma << "0\n";
    check(*sigma, kTruthSigmaFile);
  }
}

}  // namespace visual_gyro
