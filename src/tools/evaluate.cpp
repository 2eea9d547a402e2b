// evaluate: runs the front end once per frame pair of a KITTI- or EuRoC-layout sequence, then every
// requested rotation estimator on exactly the same matches, and compares them with the ground
// truth (poses, or the EuRoC gyro). Prints a readable summary per method and, last, one JSON line
// per method (the last line of the output is the last method's JSON object).
//
// Exit status: 0 done, 1 data problem (missing folder, unreadable image), 2 bad command line.

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <iostream>
#include <limits>
#include <map>
#include <memory>
#include <random>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include <unistd.h>

#include <Eigen/Geometry>
#include <opencv2/imgcodecs.hpp>

#include "baselines.h"
#include "comparison_front_ends.h"
#include "visual_gyro/sequence.h"
#include "standalone/bearing_file.h"
#include "visual_gyro/visual_gyro.h"

namespace visual_gyro {
namespace tools {
namespace {

constexpr double kRadToDeg = 180.0 / M_PI;
const double kNaN = std::numeric_limits<double>::quiet_NaN();

/// Command-line usage errors (exit 2).
struct UsageError : std::runtime_error {
  using std::runtime_error::runtime_error;
};
/// Data errors (exit 1).
struct DataError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

const char* const kUsage =
    "usage: evaluate <sequence folder> [options]\n"
    "  --method M[,M2,...]    vote, paper, essential5, fundamental8, opengv_rotation_only,\n"
    "                         opengv_eigensolver, opengv_5pt (default: vote)\n"
    "  --csv FILE             per-frame rows of every method\n"
    "  --frames N             evaluate at most N frame pairs\n"
    "  --stride K             pair image k with image k-K (more motion per pair; default 1)\n"
    "  --hypotheses H         triples per frame (vote, paper)\n"
    "  --seed S               estimator seed (frame f draws with S + f)\n"
    "  --backend B            auto, cpu or cuda (vote, paper; default auto)\n"
    "  --outliers F           replace the fraction F of the matches by random wrong pairings\n"
    "  --max-matches N        use at most N matches per pair (a deterministic random subset)\n"
    "  --export-bearings FILE write the matched bearings of every pair (text)\n"
    "  --front-end F          native (default), orb (OpenCV ORB, 1500 features, BFMatcher with\n"
    "                         cross-check) or klt (goodFeaturesToTrack + calcOpticalFlowPyrLK)\n"
    "  --set key=value        front-end or estimator setting (repeatable), e.g. --set yaw_bin_deg=0.2\n"
    "  --timing-sweep FILE    time the estimators (CSV), no evaluation: series 'hypotheses'\n"
    "                         (vote/paper over L_h at M matches; other methods once at M) and\n"
    "                         series 'matches' (every method over L_m, vote/paper at H hypotheses)\n"
    "  --sweep-hypotheses L_h default 100,300,1000,3000,10000,30000,100000\n"
    "  --sweep-matches L_m    default 250,500,1000,2000,4000,8000\n"
    "  --sweep-at-matches M   matches of the hypotheses series (default 2000)\n"
    "  --sweep-at-hypotheses H  hypotheses of the matches series (default 10000)\n"
    "  --sweep-repeats R      runs per pair in the sweep; the fastest counts (default 3)\n"
    "  --quiet                summary and JSON only (no progress)\n"
    "  --list-methods         print the methods this build has, comma-separated, and exit\n"
    "  --list-backends        print the backends that work here (cpu[,cuda]; why not cuda on stderr)\n";

// ---------------------------------------------------------------------------------------------
// Small helpers
// ---------------------------------------------------------------------------------------------

std::vector<std::string> splitList(const std::string& text) {
  std::vector<std::string> out;
  std::stringstream ss(text);
  std::string item;
  while (std::getline(ss, item, ',')) {
    item.erase(0, item.find_first_not_of(" \t"));
    item.erase(item.find_last_not_of(" \t") + 1);
    if (!item.empty()) out.push_back(item);
  }
  return out;
}

double parseDouble(const std::string& text, const std::string& what) {
  try {
    size_t used = 0;
    const double v = std::stod(text, &used);
    if (used == text.size() && std::isfinite(v)) return v;
  } catch (const std::exception&) {
  }
  throw UsageError(what + ": '" + text + "' is not a number");
}

long long parseInt(const std::string& text, const std::string& what) {
  try {
    size_t used = 0;
    const long long v = std::stoll(text, &used);
    if (used == text.size()) return v;
  } catch (const std::exception&) {
  }
  throw UsageError(what + ": '" + text + "' is not an integer");
}

bool parseBool(const std::string& text, const std::string& what) {
  if (text == "1" || text == "true" || text == "on" || text == "yes") return true;
  if (text == "0" || text == "false" || text == "off" || text == "no") return false;
  throw UsageError(what + ": '" + text + "' is not a boolean (true/false)");
}

double elapsedMs(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
}

/// Angle of a rotation matrix [rad] (via the quaternion: accurate for small angles too).
double rotationAngle(const Eigen::Matrix3d& r) {
  return Eigen::AngleAxisd(Eigen::Quaterniond(r).normalized()).angle();
}

Eigen::Vector3d rotationVector(const Eigen::Matrix3d& r) {
  const Eigen::AngleAxisd aa(Eigen::Quaterniond(r).normalized());
  return aa.angle() * aa.axis();
}

/// Yaw about the camera's vertical axis (+y, down) [rad], R = Ry(yaw) Rx(pitch) Rz(roll).
double yawOf(const Eigen::Matrix3d& r) { return std::atan2(r(0, 2), r(2, 2)); }

double wrapPi(double a) {
  while (a > M_PI) a -= 2.0 * M_PI;
  while (a <= -M_PI) a += 2.0 * M_PI;
  return a;
}

/// Minimal JSON object writer: keys in insertion order, NaN/inf written as null.
class JsonObject {
 public:
  JsonObject& add(const std::string& key, const std::string& value) {
    return raw(key, quote(value));
  }
  JsonObject& add(const std::string& key, const char* value) { return add(key, std::string(value)); }
  JsonObject& add(const std::string& key, double value) { return raw(key, number(value)); }
  JsonObject& add(const std::string& key, int value) { return raw(key, std::to_string(value)); }
  JsonObject& add(const std::string& key, bool value) { return raw(key, value ? "true" : "false"); }
  JsonObject& add(const std::string& key, const JsonObject& value) { return raw(key, value.str()); }
  std::string str() const { return "{" + body_ + "}"; }

 private:
  JsonObject& raw(const std::string& key, const std::string& value) {
    if (!body_.empty()) body_ += ", ";
    body_ += quote(key) + ": " + value;
    return *this;
  }
  static std::string number(double v) {
    if (!std::isfinite(v)) return "null";
    char buf[32];
    std::snprintf(buf, sizeof(buf), "%.6g", v);
    return buf;
  }
  static std::string quote(const std::string& s) {
    std::string out = "\"";
    for (const char c : s) {
      switch (c) {
        case '"': out += "\\\""; break;
        case '\\': out += "\\\\"; break;
        case '\n': out += "\\n"; break;
        case '\t': out += "\\t"; break;
        default:
          if (static_cast<unsigned char>(c) < 0x20) {
            char buf[8];
            std::snprintf(buf, sizeof(buf), "\\u%04x", c);
            out += buf;
          } else {
            out += c;
          }
      }
    }
    return out + "\"";
  }
  std::string body_;
};

// ---------------------------------------------------------------------------------------------
// Options
// ---------------------------------------------------------------------------------------------

struct Options {
  std::string folder;
  std::vector<std::string> methods{"vote"};
  std::string csv;
  long long frames = -1;
  int stride = 1;
  int hypotheses = -1;
  bool has_seed = false;
  uint64_t seed = 1;
  std::string backend = "auto";
  bool has_backend = false;
  double outliers = 0.0;
  int max_matches = 0;
  std::string export_bearings;
  std::string front_end = "native";
  std::vector<std::string> sets;
  std::string timing_sweep;
  std::vector<int> sweep_hypotheses{100, 300, 1000, 3000, 10000, 30000, 100000};
  std::vector<int> sweep_matches{250, 500, 1000, 2000, 4000, 8000};
  int sweep_at_matches = 2000;
  int sweep_at_hypotheses = 10000;
  int sweep_repeats = 3;
  bool quiet = false;
};

bool isOwnMethod(const std::string& m) { return m == "vote" || m == "paper"; }

void checkMethod(const std::string& m) {
  if (isOwnMethod(m) || isBaselineCompiled(m)) return;
  if (isOpenGvBaseline(m)) {
    throw UsageError("method '" + m +
                     "' needs OpenGV, which this build does not have (install libopengv-dev and "
                     "rebuild)");
  }
  std::string known = "vote, paper";
  for (const auto& n : baselineNames()) known += ", " + n;
  throw UsageError("unknown method '" + m + "' (known: " + known + ")");
}

std::vector<int> parseIntList(const std::string& text, const std::string& what) {
  std::vector<int> out;
  for (const auto& item : splitList(text)) {
    const long long v = parseInt(item, what);
    if (v <= 0 || v > 100000000) throw UsageError(what + ": " + item + " out of range");
    out.push_back(static_cast<int>(v));
  }
  if (out.empty()) throw UsageError(what + ": empty list");
  return out;
}

Options parseOptions(int argc, char** argv) {
  Options o;
  std::vector<std::string> args(argv + 1, argv + argc);
  bool have_folder = false;
  for (size_t i = 0; i < args.size(); ++i) {
    const std::string& a = args[i];
    auto value = [&]() -> std::string {
      if (i + 1 >= args.size()) throw UsageError("option " + a + " needs a value");
      return args[++i];
    };
    if (a == "-h" || a == "--help") {
      std::cout << kUsage;
      std::exit(0);
    } else if (a == "--method" || a == "--methods") {
      o.methods = splitList(value());
      if (o.methods.empty()) throw UsageError("--method: empty list");
    } else if (a == "--csv") {
      o.csv = value();
    } else if (a == "--frames") {
      o.frames = parseInt(value(), a);
      if (o.frames <= 0) throw UsageError("--frames must be positive");
    } else if (a == "--stride") {
      const long long s = parseInt(value(), a);
      if (s <= 0 || s > 1000) throw UsageError("--stride must be in 1..1000");
      o.stride = static_cast<int>(s);
    } else if (a == "--hypotheses") {
      const long long h = parseInt(value(), a);
      if (h <= 0 || h > 10000000) throw UsageError("--hypotheses must be in 1..10000000, got " + std::to_string(h));
      o.hypotheses = static_cast<int>(h);
    } else if (a == "--seed") {
      const long long s = parseInt(value(), a);
      if (s < 0) throw UsageError("--seed must not be negative");
      o.seed = static_cast<uint64_t>(s);
      o.has_seed = true;
    } else if (a == "--backend") {
      o.backend = value();
      o.has_backend = true;
      if (o.backend != "auto" && o.backend != "cpu" && o.backend != "cuda") {
        throw UsageError("--backend must be auto, cpu or cuda, not '" + o.backend + "'");
      }
    } else if (a == "--outliers") {
      o.outliers = parseDouble(value(), a);
      if (o.outliers < 0.0 || o.outliers > 1.0) throw UsageError("--outliers must be in [0, 1]");
    } else if (a == "--max-matches") {
      const long long m = parseInt(value(), a);
      if (m <= 0) throw UsageError("--max-matches must be positive");
      o.max_matches = static_cast<int>(std::min<long long>(m, 100000000));
    } else if (a == "--export-bearings") {
      o.export_bearings = value();
    } else if (a == "--set") {
      o.sets.push_back(value());
    } else if (a == "--front-end") {
      o.front_end = value();
      const auto& others = comparisonFrontEndNames();
      if (o.front_end != "native" &&
          std::find(others.begin(), others.end(), o.front_end) == others.end()) {
        throw UsageError("--front-end must be native, orb or klt, not '" + o.front_end + "'");
      }
    } else if (a == "--timing-sweep") {
      o.timing_sweep = value();
    } else if (a == "--sweep-hypotheses") {
      o.sweep_hypotheses = parseIntList(value(), a);
      for (int h : o.sweep_hypotheses)
        if (h > 10000000) throw UsageError("--sweep-hypotheses: " + std::to_string(h) + " is above 10000000");
    } else if (a == "--sweep-matches") {
      o.sweep_matches = parseIntList(value(), a);
      for (int m : o.sweep_matches)
        if (m < 8) throw UsageError("--sweep-matches: " + std::to_string(m) + " is below 8");
    } else if (a == "--sweep-at-matches") {
      const long long m = parseInt(value(), a);
      if (m < 8 || m > 1000000) throw UsageError("--sweep-at-matches must be in 8..1000000");
      o.sweep_at_matches = static_cast<int>(m);
    } else if (a == "--sweep-at-hypotheses") {
      const long long h = parseInt(value(), a);
      if (h < 1 || h > 10000000) throw UsageError("--sweep-at-hypotheses must be in 1..10000000");
      o.sweep_at_hypotheses = static_cast<int>(h);
    } else if (a == "--sweep-repeats") {
      const long long r = parseInt(value(), a);
      if (r <= 0 || r > 1000) throw UsageError("--sweep-repeats must be in 1..1000");
      o.sweep_repeats = static_cast<int>(r);
    } else if (a == "--quiet") {
      o.quiet = true;
    } else if (a == "--list-methods") {
      std::string list = "vote,paper";
      for (const auto& n : baselineNames()) list += "," + n;
      std::cout << list << "\n";
      std::exit(0);
    } else if (a == "--list-backends") {
      std::string why;
      const bool cuda = cudaBackendUsable(&why);
      if (!cuda) std::cerr << "evaluate: no CUDA backend: " << why << std::endl;
      std::cout << (cuda ? "cpu,cuda" : "cpu") << std::endl;
      std::exit(0);
    } else if (!a.empty() && a[0] == '-') {
      throw UsageError("unknown option " + a);
    } else if (!have_folder) {
      o.folder = a;
      have_folder = true;
    } else {
      throw UsageError("unexpected argument '" + a + "' (one sequence folder only)");
    }
  }
  if (!have_folder) throw UsageError("no sequence folder given");
  for (const auto& m : o.methods) checkMethod(m);
  return o;
}

/// Applies one `key=value` to the pipeline settings (keys as in the settings structs, optionally
/// prefixed with "front_end." or "estimator.").
void applySetting(const std::string& assignment, VisualGyroSettings* s) {
  const size_t eq = assignment.find('=');
  if (eq == std::string::npos || eq == 0) throw UsageError("--set expects key=value, got '" + assignment + "'");
  std::string key = assignment.substr(0, eq);
  const std::string v = assignment.substr(eq + 1);
  for (const char* prefix : {"front_end.", "estimator."}) {
    if (key.rfind(prefix, 0) == 0) key = key.substr(std::string(prefix).size());
  }
  FrontEndSettings& f = s->front_end;
  EstimatorSettings& e = s->estimator;
  const std::string what = "--set " + key;
  auto toInt = [&]() { return static_cast<int>(parseInt(v, what)); };
  auto toDouble = [&]() { return parseDouble(v, what); };
  // Front end.
  if (key == "fast_threshold") f.fast_threshold = toInt();
  else if (key == "min_fast_threshold") f.min_fast_threshold = toInt();
  else if (key == "matching") f.matching = v;
  else if (key == "guided_radius_px") f.guided_radius_px = toDouble();
  else if (key == "guided_radius_growth") f.guided_radius_growth = toDouble();
  else if (key == "guided_min_matches") f.guided_min_matches = toInt();
  else if (key == "max_features") f.max_features = toInt();
  else if (key == "grid_cols") f.grid_cols = toInt();
  else if (key == "grid_rows") f.grid_rows = toInt();
  else if (key == "smoothing_sigma") f.smoothing_sigma = toDouble();
  else if (key == "max_ratio") f.max_ratio = toDouble();
  else if (key == "max_hamming") f.max_hamming = toInt();
  else if (key == "cross_check") f.cross_check = parseBool(v, what);
  else if (key == "subpixel_refinement") f.subpixel_refinement = parseBool(v, what);
  // Estimator (method is chosen per method with --method).
  else if (key == "backend") e.backend = v;
  else if (key == "hypotheses") e.hypotheses = toInt();
  else if (key == "seed") e.seed = static_cast<uint64_t>(parseInt(v, what));
  else if (key == "min_separation_deg") e.min_separation_deg = toDouble();
  else if (key == "min_triangle_area_deg2") e.min_triangle_area_deg2 = toDouble();
  else if (key == "centroid_subtraction") e.centroid_subtraction = parseBool(v, what);
  else if (key == "yaw_bin_deg") e.yaw_bin_deg = toDouble();
  else if (key == "yaw_window_deg") e.yaw_window_deg = toDouble();
  else if (key == "rotation_bin_deg") e.rotation_bin_deg = toDouble();
  else if (key == "rotation_window_deg") e.rotation_window_deg = toDouble();
  else if (key == "wide_window_deg") e.wide_window_deg = toDouble();
  else if (key == "max_angle_change_deg") e.max_angle_change_deg = toDouble();
  else if (key == "candidates") e.candidates = toInt();
  else if (key == "inlier_threshold_deg") e.inlier_threshold_deg = toDouble();
  else if (key == "use_prior") e.use_prior = parseBool(v, what);
  else if (key == "refine_iterations") e.refine_iterations = toInt();
  else if (key == "min_matches") e.min_matches = toInt();
  else if (key == "min_votes") e.min_votes = toInt();
  else if (key == "min_inlier_ratio") e.min_inlier_ratio = toDouble();
  else if (key == "min_covariance_rad2") e.min_covariance_rad2 = toDouble();
  // Plausibility limits of the pipeline.
  else if (key == "min_dt") s->min_dt = toDouble();
  else if (key == "max_rate_dps") s->max_rate_dps = toDouble();
  else throw UsageError("--set: unknown setting '" + key + "'");
}

// ---------------------------------------------------------------------------------------------
// Frame pairs: the front end's output, shared by all methods
// ---------------------------------------------------------------------------------------------

struct FramePair {
  size_t previous_index = 0;  ///< image index of the previous frame
  size_t index = 0;           ///< image index of the current frame
  double dt = 0.0;            ///< [s]
  std::vector<Eigen::Vector3d> previous, current;  ///< matched bearings (after --max-matches/--outliers)
  int matches_found = 0;      ///< matches the front end found (before --max-matches)
  StageTimes front_end;       ///< detect, describe, match of the current frame [ms]
  std::string matching;       ///< native front end: guided, global or global_fallback
  bool has_truth = false;
  /// The truth is from poses, not from a (biased) gyro: only then is it fit to judge a covariance.
  bool truth_from_poses = false;
  Eigen::Matrix3d true_rotation = Eigen::Matrix3d::Identity();  ///< b_prev ~ R b_cur
  bool has_gyro = false;
  Eigen::Vector3d true_omega = Eigen::Vector3d::Zero();  ///< mean gyro rate, camera frame [rad/s]
  double true_translation = kNaN;  ///< camera displacement between the two images [m] (poses)
  bool frozen = false;  ///< the current image is bit-identical to the previous one (no matches)
};

/// Ground truth between images a < b: composed frame-to-frame rotations, dt-weighted mean gyro.
void fillTruth(const Sequence& seq, FramePair* p) {
  Eigen::Matrix3d r = Eigen::Matrix3d::Identity();
  bool ok = true;
  for (size_t k = p->previous_index + 1; k <= p->index && ok; ++k) {
    Eigen::Matrix3d step;
    ok = seq.trueRotation(k, &step);
    if (ok) r = r * step;
  }
  p->has_truth = ok;
  p->truth_from_poses = ok && seq.hasPoses();
  if (ok) p->true_rotation = r;
  if (seq.positions.size() == seq.image_paths.size()) {
    p->true_translation = (seq.positions[p->index] - seq.positions[p->previous_index]).norm();
  }
  // A rate reference where one was measured independently of the frame steps: the gyro, or
  // EuRoC's ground-truth poses (KITTI's poses already give the rotation errors).
  if (seq.truth == "gyro" || seq.truth == "poses") {
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    double weight = 0.0;
    bool gyro_ok = true;
    for (size_t k = p->previous_index + 1; k <= p->index && gyro_ok; ++k) {
      Eigen::Vector3d w;
      gyro_ok = seq.trueAngularVelocity(k, &w);
      const double dt = seq.stamps[k] - seq.stamps[k - 1];
      sum += w * dt;
      weight += dt;
    }
    p->has_gyro = gyro_ok && weight > 0.0;
    if (p->has_gyro) p->true_omega = sum / weight;
  }
}

/// Keeps a deterministic random subset of at most max_matches matches.
void subsample(int max_matches, uint64_t seed, FramePair* p) {
  const size_t n = p->previous.size();
  if (max_matches <= 0 || n <= static_cast<size_t>(max_matches)) return;
  std::vector<size_t> order(n);
  for (size_t i = 0; i < n; ++i) order[i] = i;
  std::mt19937_64 rng(seed * 0x9E3779B97F4A7C15ull + p->index);
  std::shuffle(order.begin(), order.end(), rng);
  order.resize(max_matches);
  std::sort(order.begin(), order.end());
  std::vector<Eigen::Vector3d> a, b;
  for (size_t i : order) {
    a.push_back(p->previous[i]);
    b.push_back(p->current[i]);
  }
  p->previous.swap(a);
  p->current.swap(b);
}

/// Replaces the fraction `fraction` of the matches by wrong pairings: the current-frame bearing of
/// a chosen match becomes that of another, distant match (>= ~20 px away at `angle_per_px`), so
/// every replaced match is a real feature paired with the wrong partner. Deterministic in seed.
void injectOutliers(double fraction, uint64_t seed, double angle_per_px, FramePair* p) {
  const size_t n = p->previous.size();
  const size_t count = static_cast<size_t>(std::llround(fraction * static_cast<double>(n)));
  if (count == 0 || n < 2) return;
  std::mt19937_64 rng(seed * 0xD1B54A32D192ED03ull + 0x5bd1e995ull + p->index);
  std::vector<size_t> order(n);
  for (size_t i = 0; i < n; ++i) order[i] = i;
  std::shuffle(order.begin(), order.end(), rng);
  const std::vector<Eigen::Vector3d> original = p->current;
  const double min_cos = std::cos(20.0 * angle_per_px);
  std::uniform_int_distribution<size_t> pick(0, n - 1);
  for (size_t c = 0; c < count; ++c) {
    const size_t i = order[c];
    size_t j = pick(rng);
    for (int attempt = 0; attempt < 20 && (j == i || original[i].dot(original[j]) > min_cos); ++attempt) {
      j = pick(rng);
    }
    if (j == i) j = (i + 1) % n;
    p->current[i] = original[j];
  }
}

/// Runs the front end over the sequence: one FramePair per (k - stride, k). The native front end
/// runs the pipeline; with guided matching its own vote estimator runs too (on the CPU, not timed
/// into any method), because the rotation prior that guides the matching comes from it, as in the
/// node. orb and klt give pixels, turned into bearings through the sequence's camera model.
std::vector<FramePair> runFrontEnd(const Sequence& seq, const VisualGyroSettings& settings,
                                   const Options& o) {
  VisualGyroSettings front_end_only = settings;
  front_end_only.estimator.backend = "cpu";
  front_end_only.estimator.method = "vote";
  front_end_only.run_estimator = settings.front_end.matching == "guided";
  VisualGyro gyro(seq.camera, front_end_only, [](const std::string& w) { std::cerr << "warning: " << w << "\n"; });
  std::unique_ptr<ComparisonFrontEnd> other;
  if (o.front_end != "native") other = makeComparisonFrontEnd(o.front_end);
  std::vector<cv::Point2f> previous_pixels, current_pixels;
  std::vector<FramePair> pairs;
  const double angle_per_px = 1.0 / seq.camera.fx();
  bool have_previous = false;
  size_t previous_index = 0;
  size_t skipped_min_dt = 0;
  std::string first_skip;
  // A live counter only on a terminal; logs get one line at the end.
  const bool progress = !o.quiet && isatty(fileno(stderr));
  for (size_t k = 0; k < seq.image_paths.size(); k += o.stride) {
    if (o.frames > 0 && static_cast<long long>(pairs.size()) >= o.frames) break;
    const cv::Mat gray = cv::imread(seq.image_paths[k], cv::IMREAD_GRAYSCALE);
    if (gray.empty()) throw DataError("cannot read image " + seq.image_paths[k]);
    FrameResult r;
    if (other) {
      if (gray.cols != seq.camera.width() || gray.rows != seq.camera.height()) {
        throw DataError("image " + seq.image_paths[k] + " is " + std::to_string(gray.cols) + "x" +
                        std::to_string(gray.rows) + " but the camera model is " +
                        std::to_string(seq.camera.width()) + "x" + std::to_string(seq.camera.height()));
      }
      const bool paired = other->process(gray, &previous_pixels, &current_pixels, &r.rotation.times);
      if (paired) {
        r.dt = seq.stamps[k] - seq.stamps[previous_index];
        r.matching = o.front_end;
        for (size_t i = 0; i < previous_pixels.size(); ++i) {
          r.previous_bearings.push_back(seq.camera.bearing(previous_pixels[i].x, previous_pixels[i].y));
          r.current_bearings.push_back(seq.camera.bearing(current_pixels[i].x, current_pixels[i].y));
        }
      }
    } else {
      r = gyro.processFrame(gray, seq.stamps[k]);
      if (have_previous && r.skipped && r.dt > 0.0) {
        // A time step below min_dt: the pipeline skipped the frame, the next pairs with the previous.
        if (skipped_min_dt++ == 0) first_skip = "image " + seq.image_paths[k] + ": " + r.error;
        continue;
      }
    }
    if (!have_previous) {
      have_previous = true;
      previous_index = k;
      if (r.features == 0 && !r.error.empty() && r.error != "first frame") {
        throw DataError("image " + seq.image_paths[k] + ": " + r.error);
      }
      continue;
    }
    // Image-level problems (size mismatch, bad stamp) are data errors; a frozen frame and the
    // front-end pipeline's own estimate (guided matching) failing are not.
    if (r.previous_bearings.empty() && !r.error.empty() && !r.frozen && r.error != r.rotation.error) {
      throw DataError("image " + seq.image_paths[k] + ": " + r.error);
    }
    FramePair p;
    p.previous_index = previous_index;
    p.index = k;
    p.dt = r.dt > 0.0 ? r.dt : seq.stamps[k] - seq.stamps[previous_index];
    p.previous = std::move(r.previous_bearings);
    p.current = std::move(r.current_bearings);
    p.matches_found = static_cast<int>(p.previous.size());
    p.front_end = r.rotation.times;
    p.frozen = r.frozen;
    p.matching = r.matching;
    fillTruth(seq, &p);
    const uint64_t seed = o.has_seed ? o.seed : settings.estimator.seed;
    subsample(o.max_matches, seed, &p);
    injectOutliers(o.outliers, seed, angle_per_px, &p);
    if (progress) {
      std::fprintf(stderr, "\r[evaluate] front end: pair %zu (images %zu-%zu), %zu matches   ",
                   pairs.size() + 1, previous_index, k, p.previous.size());
    }
    pairs.push_back(std::move(p));
    // A frozen image left the pipeline's previous frame in place; so does this loop.
    if (!r.frozen) previous_index = k;
  }
  if (progress) std::fprintf(stderr, "\n");
  if (skipped_min_dt > 0) {
    std::fprintf(stderr, "[evaluate] %s: %zu frame(s) skipped, time step below min_dt %g s (first: %s)\n",
                 seq.name.c_str(), skipped_min_dt, settings.min_dt, first_skip.c_str());
    if (pairs.empty()) {
      throw DataError(seq.name + ": no usable frame pairs: every time step is below min_dt (" +
                      std::to_string(skipped_min_dt) + " frames skipped; first: " + first_skip + ")");
    }
  }
  if (!o.quiet && !pairs.empty()) {
    double matches = 0;
    for (const FramePair& p : pairs) matches += p.previous.size();
    std::fprintf(stderr, "[evaluate] %s: %zu frame pairs, %.1f matches per pair\n", seq.name.c_str(), pairs.size(),
                 matches / pairs.size());
  }
  return pairs;
}

void exportBearings(const std::vector<FramePair>& pairs, const std::string& path) {
  std::vector<bearings::BearingFrame> frames(pairs.size());
  for (size_t k = 0; k < pairs.size(); ++k) {
    const FramePair& p = pairs[k];
    bearings::BearingFrame& f = frames[k];
    f.index = static_cast<int64_t>(p.index);
    f.dt = p.dt;
    f.has_truth = p.has_truth;
    if (p.has_truth)
      for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c) f.truth[3 * r + c] = p.true_rotation(r, c);
    auto toFloat = [](const Eigen::Vector3d& v) {
      return hyp::make3(static_cast<float>(v.x()), static_cast<float>(v.y()), static_cast<float>(v.z()));
    };
    for (size_t i = 0; i < p.previous.size(); ++i) {
      f.prev.push_back(toFloat(p.previous[i]));
      f.cur.push_back(toFloat(p.current[i]));
    }
  }
  try {
    bearings::writeBearingFile(path, frames);
  } catch (const std::runtime_error& e) {
    throw DataError(e.what());
  }
}

// ---------------------------------------------------------------------------------------------
// Methods
// ---------------------------------------------------------------------------------------------

struct MethodEstimate {
  bool valid = false;
  std::string error;
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();  ///< b_prev ~ R b_cur
  Eigen::Vector3d rotation_vector = Eigen::Vector3d::Zero();
  double estimate_ms = 0.0;
  /// Covariance of the rotation vector [rad^2] (vote / paper; the baselines give none).
  bool has_covariance = false;
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Identity();
  int inliers = -1;  ///< vote / paper: RotationResult::inliers; -1 for the baselines
  bool pure_rotation = false;
  VoteDiagnostics diagnostics;  ///< vote only
  // vote / paper only (NaN for the baselines): the estimate's voter part (host clock), its GPU
  // kernels (NaN on the CPU backend), and the host part after the vote (see StageTimes).
  double vote_ms = kNaN, vote_device_ms = kNaN, refine_ms = kNaN;
};

/// One method with its own state across frames (prior, previous estimate).
class MethodRunner {
 public:
  virtual ~MethodRunner() = default;
  virtual MethodEstimate run(const FramePair& pair) = 0;
  virtual std::string backend() const = 0;
};

/// vote / paper: a RotationEstimator fed the prior VisualGyro would give it (its own previous
/// valid rotation vector, rescaled to this interval; none after an invalid estimate).
class OwnEstimatorRunner : public MethodRunner {
 public:
  OwnEstimatorRunner(const EstimatorSettings& settings)
      : estimator_(createRotationEstimator(settings, [](const std::string& w) {
          std::cerr << "warning: " << w << "\n";
        })) {}

  MethodEstimate run(const FramePair& pair) override {
    const RotationPrior prior = prior_.priorFor(pair.dt);
    const auto start = std::chrono::steady_clock::now();
    const RotationResult r = estimator_->estimate(pair.previous, pair.current, prior);
    MethodEstimate out;
    out.estimate_ms = elapsedMs(start);
    out.vote_ms = r.times.vote;
    out.vote_device_ms = r.backend == "cuda" ? r.times.vote_device : kNaN;  // no kernels on the CPU
    out.refine_ms = r.times.refine;
    prior_.update(r, pair.dt);
    out.valid = r.valid;
    out.error = r.error;
    out.inliers = r.inliers;
    out.pure_rotation = r.pure_rotation;
    out.diagnostics = r.diagnostics;
    if (r.valid) {
      out.rotation = r.rotation;
      out.rotation_vector = r.rotation_vector;
      out.has_covariance = true;
      out.covariance = r.covariance;
    }
    return out;
  }
  std::string backend() const override { return estimator_->backendName(); }

 private:
  std::unique_ptr<RotationEstimator> estimator_;
  PriorTracker prior_;  // the same prior VisualGyro gives its estimator
};

/// OpenCV / OpenGV baselines; the eigensolver starts from this method's previous valid estimate.
class BaselineRunner : public MethodRunner {
 public:
  BaselineRunner(const std::string& name, const BaselineSettings& settings)
      : name_(name), settings_(settings) {}

  MethodEstimate run(const FramePair& pair) override {
    BaselineSettings s = settings_;
    s.seed = settings_.seed + pair.index;
    const auto start = std::chrono::steady_clock::now();
    const BaselineResult r = runBaseline(name_, pair.previous, pair.current, s, initial_);
    MethodEstimate out;
    out.estimate_ms = elapsedMs(start);
    out.valid = r.valid;
    out.error = r.error;
    if (r.valid) {
      out.rotation = r.rotation;
      out.rotation_vector = rotationVector(r.rotation);
      initial_ = r.rotation;
    } else {
      initial_.setIdentity();
    }
    return out;
  }
  std::string backend() const override { return "cpu"; }

 private:
  std::string name_;
  BaselineSettings settings_;
  Eigen::Matrix3d initial_ = Eigen::Matrix3d::Identity();
};

/// Applies the pipeline's plausibility rules to another method: no estimate on a frozen image, and
/// a rate above max_rate_dps is invalid, exactly as VisualGyro reports them.
class PlausibilityRunner : public MethodRunner {
 public:
  PlausibilityRunner(std::unique_ptr<MethodRunner> inner, const VisualGyroSettings& settings)
      : inner_(std::move(inner)), settings_(settings) {}

  MethodEstimate run(const FramePair& pair) override {
    if (pair.frozen) {
      MethodEstimate out;
      out.error = "image identical to the previous one (camera frozen?)";
      return out;
    }
    MethodEstimate out = inner_->run(pair);
    if (out.valid) {
      const std::string implausible = checkRatePlausible(out.rotation_vector, pair.dt, settings_);
      if (!implausible.empty()) {
        out.valid = false;
        out.error = implausible;
        out.rotation.setIdentity();
        out.rotation_vector.setZero();
      }
    }
    return out;
  }
  std::string backend() const override { return inner_->backend(); }

 private:
  std::unique_ptr<MethodRunner> inner_;
  VisualGyroSettings settings_;
};

std::unique_ptr<MethodRunner> makeRunner(const std::string& method, const EstimatorSettings& estimator,
                                         const BaselineSettings& baseline) {
  if (isOwnMethod(method)) {
    EstimatorSettings s = estimator;
    s.method = method;
    return std::make_unique<OwnEstimatorRunner>(s);
  }
  return std::make_unique<BaselineRunner>(method, baseline);
}

// ---------------------------------------------------------------------------------------------
// Evaluation
// ---------------------------------------------------------------------------------------------

struct FrameRow {
  size_t frame = 0;
  int matches = 0;
  bool valid = false;
  double yaw_est_deg = 0, yaw_true_deg = kNaN, rot_err_deg = kNaN, yaw_err_deg = kNaN;
  double rate_dps = 0, rate_err_dps = kNaN, estimate_ms = 0;
  /// Normalised estimation error squared e^T C^-1 e of the rotation vector error e (valid
  /// estimates with a covariance and truth from poses only: a gyro's bias is no estimation error).
  double nees = kNaN;
  double sigma_deg = kNaN;  ///< sqrt(trace C) [deg]
  /// Rotation error as a rotation vector (estimate^T truth, camera frame) [deg], and the standard
  /// deviations the covariance gives each axis [deg].
  Eigen::Vector3d error_vector_deg = Eigen::Vector3d::Constant(kNaN);
  Eigen::Vector3d sigma_axes_deg = Eigen::Vector3d::Constant(kNaN);
  int inliers = -1;
  bool pure_rotation = false;
  VoteDiagnostics diagnostics;
  std::string error;
};

struct MethodSummary {
  std::string method, backend;
  std::vector<FrameRow> rows;
  int frames = 0, invalid = 0;
  double rot_rmse = kNaN, rot_max = kNaN, yaw_rmse = kNaN, yaw_max = kNaN;
  double mean_rate = kNaN, rate_rmse = kNaN;
  double detect = 0, describe = 0, match = 0, estimate = 0, total = 0;
  double vote = 0, vote_device = 0, refine = 0;  // NaN for the baselines
  double matches_mean = 0;
  double true_rotation_mean = kNaN;     ///< mean true rotation per pair [deg]
  double true_translation_mean = kNaN;  ///< mean true translation per pair [m]
  double true_rate_mean = kNaN;         ///< mean |gyro rate| [deg/s] (EuRoC)
  double nees_mean = kNaN;      ///< mean NEES over the valid frames with truth (3 when honest)
  double nees_beyond99 = kNaN;  ///< fraction of those frames beyond the 99 % chi-square bound
  std::string first_error;
  std::string front_end;       ///< native, orb or klt
  std::string matching;        ///< native: the matching setting (guided, global); else ""
  int guided_pairs = 0;        ///< native: pairs matched guided by the prior
  int fallback_pairs = 0;      ///< native: pairs where guided found too few and global ran
};

/// 99 % quantile of the chi-square distribution with 3 degrees of freedom.
constexpr double kChiSquare3Dof99 = 11.345;

MethodSummary evaluateMethod(const std::string& method, MethodRunner* runner,
                             const std::vector<FramePair>& pairs) {
  MethodSummary s;
  s.method = method;
  s.backend = runner->backend();
  double rot_sq = 0, yaw_sq = 0, rate_sq = 0, rate_sum = 0;
  int truth_n = 0, gyro_n = 0;
  double true_rate_sum = 0;
  double rot_max = 0, yaw_max = 0;
  double true_rot_sum = 0, true_trans_sum = 0;
  int true_trans_n = 0;
  double nees_sum = 0;
  int nees_n = 0, nees_beyond = 0;
  for (const FramePair& p : pairs) {
    if (std::isfinite(p.true_translation)) {
      true_trans_sum += p.true_translation;
      ++true_trans_n;
    }
    if (p.has_truth) true_rot_sum += rotationAngle(p.true_rotation) * kRadToDeg;
    const MethodEstimate e = runner->run(p);
    FrameRow row;
    row.frame = p.index;
    row.matches = static_cast<int>(p.previous.size());
    row.valid = e.valid;
    row.estimate_ms = e.estimate_ms;
    // An invalid estimate counts as identity (no rotation): that is what a consumer would integrate.
    const Eigen::Matrix3d r_est = e.valid ? e.rotation : Eigen::Matrix3d::Identity();
    const Eigen::Vector3d rv = e.valid ? e.rotation_vector : Eigen::Vector3d::Zero();
    row.yaw_est_deg = yawOf(r_est) * kRadToDeg;
    const Eigen::Vector3d omega = rv / p.dt;
    row.rate_dps = omega.norm() * kRadToDeg;
    rate_sum += row.rate_dps;
    if (p.has_truth) {
      row.yaw_true_deg = yawOf(p.true_rotation) * kRadToDeg;
      row.rot_err_deg = rotationAngle(r_est.transpose() * p.true_rotation) * kRadToDeg;
      row.yaw_err_deg = wrapPi(yawOf(r_est) - yawOf(p.true_rotation)) * kRadToDeg;
      rot_sq += row.rot_err_deg * row.rot_err_deg;
      yaw_sq += row.yaw_err_deg * row.yaw_err_deg;
      rot_max = std::max(rot_max, row.rot_err_deg);
      yaw_max = std::max(yaw_max, std::abs(row.yaw_err_deg));
      ++truth_n;
    }
    row.inliers = e.inliers;
    row.pure_rotation = e.pure_rotation;
    row.diagnostics = e.diagnostics;
    row.error = e.error;
    if (e.has_covariance) {
      row.sigma_deg = std::sqrt(e.covariance.trace()) * kRadToDeg;
      row.sigma_axes_deg = e.covariance.diagonal().cwiseSqrt() * kRadToDeg;
    }
    if (p.has_truth) row.error_vector_deg = rotationVector(r_est.transpose() * p.true_rotation) * kRadToDeg;
    if (p.truth_from_poses && e.valid && e.has_covariance) {
      // Error as a rotation vector in the camera frame, the frame of the covariance.
      const Eigen::Vector3d err = rotationVector(r_est.transpose() * p.true_rotation);
      const Eigen::FullPivLU<Eigen::Matrix3d> lu(e.covariance);
      if (lu.isInvertible()) {
        row.nees = err.dot(lu.solve(err));
        nees_sum += row.nees;
        nees_beyond += row.nees > kChiSquare3Dof99;
        ++nees_n;
      }
    }
    if (p.has_gyro) {
      row.rate_err_dps = (omega - p.true_omega).norm() * kRadToDeg;
      rate_sq += row.rate_err_dps * row.rate_err_dps;
      true_rate_sum += p.true_omega.norm() * kRadToDeg;
      ++gyro_n;
    }
    if (!e.valid) {
      ++s.invalid;
      if (s.first_error.empty()) s.first_error = "frame " + std::to_string(p.index) + ": " + e.error;
    }
    s.detect += p.front_end.detect;
    s.describe += p.front_end.describe;
    s.match += p.front_end.match;
    s.estimate += e.estimate_ms;
    s.vote += e.vote_ms;
    s.vote_device += e.vote_device_ms;
    s.refine += e.refine_ms;
    s.matches_mean += row.matches;
    if (p.matching == "guided") ++s.guided_pairs;
    if (p.matching == "global_fallback") ++s.fallback_pairs;
    s.rows.push_back(row);
  }
  s.frames = static_cast<int>(pairs.size());
  if (s.frames > 0) {
    const double n = s.frames;
    s.detect /= n;
    s.describe /= n;
    s.match /= n;
    s.estimate /= n;
    s.vote /= n;
    s.vote_device /= n;
    s.refine /= n;
    s.total = s.detect + s.describe + s.match + s.estimate;
    s.matches_mean /= n;
    s.mean_rate = rate_sum / n;
  }
  if (truth_n > 0) {
    s.rot_rmse = std::sqrt(rot_sq / truth_n);
    s.yaw_rmse = std::sqrt(yaw_sq / truth_n);
    s.rot_max = rot_max;
    s.yaw_max = yaw_max;
    s.true_rotation_mean = true_rot_sum / truth_n;
  }
  if (true_trans_n > 0) s.true_translation_mean = true_trans_sum / true_trans_n;
  if (nees_n > 0) {
    s.nees_mean = nees_sum / nees_n;
    s.nees_beyond99 = static_cast<double>(nees_beyond) / nees_n;
  }
  if (gyro_n > 0) {
    s.rate_rmse = std::sqrt(rate_sq / gyro_n);
    s.true_rate_mean = true_rate_sum / gyro_n;
  }
  return s;
}

std::string fmt(double v, int decimals = 3) {
  if (!std::isfinite(v)) return "n/a";
  char buf[64];
  std::snprintf(buf, sizeof(buf), "%.*f", decimals, v);
  return buf;
}

void printSummary(const Sequence& seq, const Options& o, const MethodSummary& s) {
  std::cout << "== " << s.method << " on " << seq.name << " (" << seq.layout << ", backend " << s.backend
            << ")\n";
  std::cout << "   frames " << s.frames << ", invalid " << s.invalid
            << " (invalid frames count as identity rotation in the errors)";
  if (o.outliers > 0) std::cout << ", injected outliers " << fmt(100.0 * o.outliers, 0) << " %";
  if (o.stride > 1) std::cout << ", stride " << o.stride;
  std::cout << "\n";
  std::cout << "   rotation error  RMSE " << fmt(s.rot_rmse) << " deg, max " << fmt(s.rot_max) << " deg\n";
  std::cout << "   yaw error       RMSE " << fmt(s.yaw_rmse) << " deg, max " << fmt(s.yaw_max) << " deg\n";
  std::cout << "   rate            mean " << fmt(s.mean_rate) << " deg/s";
  if (std::isfinite(s.rate_rmse) && seq.truth == "gyro") {
    // The loader integrates the raw gyro (bias included), so on a static stretch the reference
    // itself reads the bias; its mean is shown to make that visible.
    std::cout << ", RMSE vs gyro " << fmt(s.rate_rmse) << " deg/s (gyro: raw, bias not removed, mean |rate| "
              << fmt(s.true_rate_mean) << " deg/s)";
  } else if (std::isfinite(s.rate_rmse)) {
    std::cout << ", RMSE vs poses " << fmt(s.rate_rmse) << " deg/s (mean |rate| " << fmt(s.true_rate_mean)
              << " deg/s)";
  }
  std::cout << "\n";
  if (std::isfinite(s.nees_mean))
    std::cout << "   covariance      NEES mean " << fmt(s.nees_mean, 2) << " (3 when honest), beyond 99 % bound "
              << fmt(100.0 * s.nees_beyond99, 1) << " % of valid frames\n";
  std::cout << "   matches         mean " << fmt(s.matches_mean, 1) << " (front end " << s.front_end;
  if (!s.matching.empty()) {
    std::cout << ", matching " << s.matching;
    if (s.matching == "guided") {
      std::cout << ": " << s.guided_pairs << " pairs guided, " << s.fallback_pairs << " fell back to global";
    }
  }
  std::cout << ")\n";
  std::cout << "   ms per frame    detect " << fmt(s.detect) << ", describe " << fmt(s.describe) << ", match "
            << fmt(s.match) << ", estimate " << fmt(s.estimate) << ", total " << fmt(s.total) << "\n";
  if (std::isfinite(s.vote)) {
    std::cout << "   estimate split  vote " << fmt(s.vote);
    if (std::isfinite(s.vote_device)) std::cout << " (GPU kernels " << fmt(s.vote_device) << ")";
    std::cout << ", refine " << fmt(s.refine) << "\n";
  }
  if (!s.first_error.empty()) std::cout << "   first invalid   " << s.first_error << "\n";
}

std::string jsonLine(const Sequence& seq, const Options& o, const EstimatorSettings& est,
                     const MethodSummary& s) {
  JsonObject times;
  times.add("detect", s.detect).add("describe", s.describe).add("match", s.match)
      .add("estimate", s.estimate).add("total", s.total);
  if (std::isfinite(s.vote)) times.add("vote", s.vote).add("vote_device", s.vote_device).add("refine", s.refine);
  JsonObject j;
  j.add("dataset", seq.name)
      .add("method", s.method)
      .add("frames", s.frames)
      .add("invalid", s.invalid)
      .add("rot_rmse_deg", s.rot_rmse)
      .add("rot_max_deg", s.rot_max)
      .add("yaw_rmse_deg", s.yaw_rmse)
      .add("yaw_max_deg", s.yaw_max)
      .add("mean_rate_dps", s.mean_rate)
      .add("rate_rmse_dps", s.rate_rmse)
      .add("ms_per_frame", times)
      .add("backend", s.backend)
      .add("matches_mean", s.matches_mean)
      .add("front_end", s.front_end)
      .add("matching", s.matching)
      .add("guided_pairs", s.guided_pairs)
      .add("fallback_pairs", s.fallback_pairs)
      .add("layout", seq.layout)
      .add("hypotheses", isOwnMethod(s.method) ? est.hypotheses : 0)
      .add("outliers", o.outliers)
      .add("stride", o.stride)
      .add("true_rot_mean_deg", s.true_rotation_mean)
      .add("true_trans_mean_m", s.true_translation_mean)
      .add("gyro_mean_rate_dps", s.true_rate_mean)
      .add("truth", seq.truth)
      .add("nees_mean", s.nees_mean)
      .add("nees_beyond_99", s.nees_beyond99);
  return j.str();
}

void writeCsv(const std::string& path, const std::vector<MethodSummary>& all) {
  std::ofstream f(path);
  if (!f) throw DataError("cannot write " + path);
  f << "frame,method,matches,valid,yaw_est_deg,yaw_true_deg,rot_err_deg,yaw_err_deg,rate_dps,estimate_ms,"
       "rate_err_dps,nees,sigma_deg,inliers,pure_rotation,prior_used,wide_vote,winner_source,candidates,"
       "rotation_inliers,epipolar_inliers,runner_up_inliers,valley,prior_offset_deg,residual_sigma_deg,err_x_deg,err_y_deg,"
       "err_z_deg,sigma_x_deg,sigma_y_deg,sigma_z_deg,error\n";
  auto num = [](double v) -> std::string {
    if (!std::isfinite(v)) return "";
    char buf[32];
    std::snprintf(buf, sizeof(buf), "%.6g", v);
    return buf;
  };
  for (const MethodSummary& s : all) {
    for (const FrameRow& r : s.rows) {
      f << r.frame << ',' << s.method << ',' << r.matches << ',' << (r.valid ? 1 : 0) << ','
        << num(r.yaw_est_deg) << ',' << num(r.yaw_true_deg) << ',' << num(r.rot_err_deg) << ','
        << num(r.yaw_err_deg) << ',' << num(r.rate_dps) << ',' << num(r.estimate_ms) << ','
        << num(r.rate_err_dps) << ',' << num(r.nees) << ',' << num(r.sigma_deg) << ',' << r.inliers << ','
        << (r.pure_rotation ? 1 : 0) << ',' << (r.diagnostics.prior_used ? 1 : 0) << ','
        << (r.diagnostics.wide_vote ? 1 : 0) << ',' << r.diagnostics.winner_source << ','
        << r.diagnostics.candidates_verified << ',' << r.diagnostics.rotation_inliers << ','
        << r.diagnostics.epipolar_inliers << ',' << r.diagnostics.runner_up_inliers << ','
        << (r.diagnostics.valley_moved ? "moved" : r.diagnostics.valley_searched ? "searched" : "") << ','
        << num(r.diagnostics.prior_offset * kRadToDeg) << ',' << num(r.diagnostics.residual_sigma * kRadToDeg);
      for (int k = 0; k < 3; ++k) f << ',' << num(r.error_vector_deg[k]);
      for (int k = 0; k < 3; ++k) f << ',' << num(r.sigma_axes_deg[k]);
      f << ",\"" << r.error << "\"\n";
    }
  }
  if (!f) throw DataError("cannot write " + path);
}

// ---------------------------------------------------------------------------------------------
// Timing sweep (make bench): estimate time over hypotheses and over matches on the same pairs
// ---------------------------------------------------------------------------------------------

/// Brings a pair to exactly `matches` matches for the timing sweep: a random subset when it has
/// more, else all of its matches plus copies of random ones, each bearing turned by a random angle
/// of about `jitter_rad` (so no two are identical). Returns the fraction of real matches.
double resampleForTiming(int matches, uint64_t seed, double jitter_rad, FramePair* p) {
  const size_t n = p->previous.size();
  if (n >= static_cast<size_t>(matches)) {
    subsample(matches, seed, p);
    return 1.0;
  }
  std::mt19937_64 rng(seed * 0x2545F4914F6CDD1Dull + p->index);
  std::uniform_int_distribution<size_t> pick(0, n - 1);
  std::normal_distribution<double> noise(0.0, jitter_rad);
  auto jitter = [&](const Eigen::Vector3d& b) {
    return Eigen::Vector3d(b + Eigen::Vector3d(noise(rng), noise(rng), noise(rng))).normalized();
  };
  while (p->previous.size() < static_cast<size_t>(matches)) {
    const size_t i = pick(rng);
    p->previous.push_back(jitter(p->previous[i]));
    p->current.push_back(jitter(p->current[i]));
  }
  return static_cast<double>(n) / matches;
}

/// Timing sweep (make bench): estimation time of every method on the same pairs, in two series as
/// the paper plots them: over hypotheses at a fixed number of matches (methods without a
/// hypothesis count, the OpenCV and OpenGV RANSACs, run once there with their own adaptive
/// iteration count), and over matches at a fixed number of hypotheses. Pairs with fewer matches than
/// asked are topped up with jittered copies (column real_fraction says how much was real).
void timingSweep(const Sequence& seq, const Options& o, const EstimatorSettings& est,
                 const BaselineSettings& base, const std::vector<FramePair>& pairs) {
  struct Point {
    const char* series;
    int hypotheses;  // 0: the method's own (baselines)
    int matches;
  };
  std::ofstream f(o.timing_sweep);
  if (!f) throw DataError("cannot write " + o.timing_sweep);
  f << "source,dataset,series,method,backend,hypotheses,matches,pairs,real_fraction,ms_mean,ms_median,ms_min,"
       "vote_ms_mean,vote_device_ms_mean,refine_ms_mean\n";
  std::cout << "timing sweep on " << seq.name << " (" << pairs.size() << " pairs; per pair the fastest of "
            << o.sweep_repeats << " runs)\n";
  std::printf("%-10s %-22s %-6s %10s %8s %6s %6s %10s %10s\n", "series", "method", "backend", "hypotheses",
              "matches", "pairs", "real", "ms_mean", "ms_median");
  const double jitter_rad = 0.5 / seq.camera.fx();  // half a pixel
  for (const std::string& method : o.methods) {
    const bool own = isOwnMethod(method);
    std::vector<Point> points;
    if (own) {
      for (int h : o.sweep_hypotheses) points.push_back({"hypotheses", h, o.sweep_at_matches});
    } else {
      points.push_back({"hypotheses", 0, o.sweep_at_matches});
    }
    for (int m : o.sweep_matches) points.push_back({"matches", own ? o.sweep_at_hypotheses : 0, m});
    for (const Point& point : points) {
      EstimatorSettings s = est;
      if (point.hypotheses > 0) s.hypotheses = point.hypotheses;
      std::unique_ptr<MethodRunner> runner = makeRunner(method, s, base);
      std::vector<double> ms;
      double real = 0.0, vote = 0.0, vote_device = 0.0, refine = 0.0;
      for (const FramePair& p0 : pairs) {
        if (p0.previous.size() < 8) continue;
        FramePair p = p0;
        real += resampleForTiming(point.matches, o.has_seed ? o.seed : est.seed, jitter_rad, &p);
        // The fastest of a few runs: the machine is shared, the minimum is the estimator's own cost.
        MethodEstimate best;
        best.estimate_ms = std::numeric_limits<double>::infinity();
        for (int rep = 0; rep < o.sweep_repeats; ++rep) {
          const MethodEstimate e = runner->run(p);
          if (e.estimate_ms < best.estimate_ms) best = e;
        }
        ms.push_back(best.estimate_ms);
        vote += best.vote_ms;
        vote_device += best.vote_device_ms;
        refine += best.refine_ms;
      }
      if (ms.empty()) continue;
      real /= ms.size();
      auto meanOrEmpty = [&](double sum) {
        return std::isfinite(sum) ? std::to_string(sum / ms.size()) : std::string();
      };
      std::vector<double> sorted = ms;
      std::sort(sorted.begin(), sorted.end());
      double mean = 0;
      for (double v : ms) mean += v;
      mean /= ms.size();
      const double median = sorted[sorted.size() / 2];
      f << "evaluate," << seq.name << ',' << point.series << ',' << method << ',' << runner->backend() << ','
        << point.hypotheses << ',' << point.matches << ',' << ms.size() << ',' << real << ',' << mean << ','
        << median << ',' << sorted.front() << ',' << meanOrEmpty(vote) << ',' << meanOrEmpty(vote_device) << ','
        << meanOrEmpty(refine) << '\n';
      std::printf("%-10s %-22s %-6s %10d %8d %6zu %6.2f %10.3f %10.3f\n", point.series, method.c_str(),
                  runner->backend().c_str(), point.hypotheses, point.matches, ms.size(), real, mean, median);
      std::fflush(stdout);
    }
  }
  if (!f) throw DataError("cannot write " + o.timing_sweep);
}

int run(int argc, char** argv) {
  const Options o = parseOptions(argc, argv);
  // One thread: the figures compare front ends and estimators per thread. OpenCV would otherwise
  // spread some of its functions (ORB, brute-force matching, optical flow) over every core.
  cv::setNumThreads(1);

  VisualGyroSettings settings;
  for (const auto& assignment : o.sets) applySetting(assignment, &settings);
  if (o.hypotheses > 0) settings.estimator.hypotheses = o.hypotheses;
  if (o.has_seed) settings.estimator.seed = o.seed;
  if (o.has_backend) settings.estimator.backend = o.backend;
  settings.run_estimator = false;  // the methods run below, all on the same matches
  std::string problem = validateFrontEndSettings(settings.front_end);
  if (!problem.empty()) throw UsageError("front-end settings: " + problem);
  problem = validateSettings(settings.estimator);
  if (!problem.empty()) throw UsageError("estimator settings: " + problem);
  problem = validatePlausibilitySettings(settings);
  if (!problem.empty()) throw UsageError("settings: " + problem);

  Sequence seq;
  try {
    seq = loadSequence(o.folder);
  } catch (const std::exception& e) {
    throw DataError(e.what());
  }
  if (seq.image_paths.size() < 2) throw DataError(o.folder + ": fewer than two images");
  if (seq.stamps.size() != seq.image_paths.size()) throw DataError(o.folder + ": stamps and images differ in number");
  problem = seq.camera.validate();
  if (!problem.empty()) throw DataError(o.folder + ": camera model: " + problem);
  problem = calibrationProblem(seq.camera);
  if (!problem.empty()) throw DataError(o.folder + ": implausible calibration: " + problem);

  std::vector<FramePair> pairs;
  try {
    pairs = runFrontEnd(seq, settings, o);
  } catch (const std::invalid_argument& e) {
    throw DataError(e.what());
  }
  if (pairs.empty()) throw DataError(o.folder + ": no frame pairs to evaluate");
  if (!o.export_bearings.empty()) exportBearings(pairs, o.export_bearings);

  BaselineSettings base;
  base.threshold_rad = 1.0 / seq.camera.fx();  // 1 px-equivalent
  base.seed = settings.estimator.seed;

  if (!o.timing_sweep.empty()) {
    timingSweep(seq, o, settings.estimator, base, pairs);
    return 0;
  }

  std::vector<MethodSummary> summaries;
  for (const std::string& method : o.methods) {
    std::unique_ptr<MethodRunner> runner =
        std::make_unique<PlausibilityRunner>(makeRunner(method, settings.estimator, base), settings);
    summaries.push_back(evaluateMethod(method, runner.get(), pairs));
    summaries.back().front_end = o.front_end;
    if (o.front_end == "native") summaries.back().matching = settings.front_end.matching;
  }
  if (!o.csv.empty()) writeCsv(o.csv, summaries);
  std::cerr.flush();
  for (const MethodSummary& s : summaries) printSummary(seq, o, s);
  for (const MethodSummary& s : summaries) std::cout << jsonLine(seq, o, settings.estimator, s) << "\n";
  std::cout.flush();
  return 0;
}

}  // namespace
}  // namespace tools
}  // namespace visual_gyro

int main(int argc, char** argv) {
  try {
    return visual_gyro::tools::run(argc, argv);
  } catch (const visual_gyro::tools::UsageError& e) {
    std::cerr << "evaluate: " << e.what() << "\n" << visual_gyro::tools::kUsage;
    return 2;
  } catch (const visual_gyro::tools::DataError& e) {
    std::cerr << "evaluate: " << e.what() << "\n";
    return 1;
  } catch (const std::exception& e) {
    std::cerr << "evaluate: " << e.what() << "\n";
    return 1;
  }
}
