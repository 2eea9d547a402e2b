// What the stand-alone GPU tools (cuda_voter_check, cuda_voter_bench, cuda_estimator_check) share:
// the command line (the options they have in common, help, usage errors and exit statuses), the
// CUDA device or the loud note that the GPU part is skipped, the bearing files they read, the CSV
// file they write, and the two standard vote grids. Plain C++ (the command-line conventions are
// src/tools/command_line.h's).
#pragma once

#include <chrono>
#include <cstdarg>
#include <cstdio>
#include <cstdlib>
#include <functional>
#include <limits>
#include <memory>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "bearing_file.h"
#include "command_line.h"
#include "cuda_voter.h"
#include "hypothesis_voter.h"

namespace visual_gyro {
namespace bearings {

constexpr double kRadPerDeg = 3.14159265358979323846 / 180.0;

/// Exit status of a tool given --require-gpu when no CUDA device works (1: a check failed or an
/// input was bad; 2: a bad command line, as every visual_gyro command).
constexpr int kExitNoGpu = 3;

/// The options several tools take; each tool names those it accepts (ToolOption bits).
enum ToolOption : unsigned {
  kOptionFiles = 1u << 0,       ///< positional bearing files
  kOptionMaxFrames = 1u << 1,   ///< --max-frames K
  kOptionDevice = 1u << 2,      ///< --device D
  kOptionRequireGpu = 1u << 3,  ///< --require-gpu
  kOptionCsv = 1u << 4,         ///< --csv PATH
};

/// Values of the shared options.
struct ToolOptions {
  std::vector<std::string> files;                           ///< bearing files, in order
  uint64_t max_frames = std::numeric_limits<uint64_t>::max();  ///< frames read per file at most
  int device = 0;                                           ///< CUDA device index
  bool require_gpu = false;                                 ///< no working device is a failure
  std::string csv_path;                                     ///< "" writes no CSV
};

/// Walks the command line: -h/--help prints `usage` and returns false (exit 0); the shared options
/// in `accepted` fill *options; every other argument goes to `own`, which consumes it (and its
/// value) and returns true, or returns false when it does not know it. Throws cli::UsageError for
/// an unknown option, a bad value or a stray positional argument.
inline bool parseToolArguments(int argc, char** argv, const std::string& usage, unsigned accepted,
                               ToolOptions* options, const std::function<bool(cli::Arguments&)>& own) {
  const long long kMaxInt = std::numeric_limits<int>::max();
  for (cli::Arguments args(argc, argv); args.next();) {
    if (args.is("-h") || args.is("--help")) {
      std::fputs(usage.c_str(), stdout);
      return false;
    }
    if ((accepted & kOptionMaxFrames) && args.is("--max-frames")) {
      options->max_frames = static_cast<uint64_t>(args.intValue(0, std::numeric_limits<long long>::max()));
    } else if ((accepted & kOptionDevice) && args.is("--device")) {
      options->device = static_cast<int>(args.intValue(0, kMaxInt));
    } else if ((accepted & kOptionRequireGpu) && args.is("--require-gpu")) {
      options->require_gpu = true;
    } else if ((accepted & kOptionCsv) && args.is("--csv")) {
      options->csv_path = args.value();
    } else if (own && own(args)) {
      continue;
    } else if ((accepted & kOptionFiles) && !args.isOption()) {
      args.positional(&options->files, std::numeric_limits<size_t>::max());
    } else {
      args.unexpected();
    }
  }
  return true;
}

/// The CUDA voter on `device`, or null with the reason in *why when no device works.
inline std::unique_ptr<HypothesisVoter> tryCudaVoter(int device, std::string* why) {
  if (!cudaDeviceAvailable(why, device)) return nullptr;
  try {
    return createCudaVoter(device);
  } catch (const std::exception& e) {
    *why = e.what();
    return nullptr;
  }
}

/// The CUDA voter on `device`, announced as "<tool>: GPU <name> (compute capability x.y)"; or null,
/// announced loudly as "<tool>: GPU PART SKIPPED: <why>" followed by "<tool>: <cpu_only>" (what
/// still runs), with the reason in *why.
inline std::unique_ptr<HypothesisVoter> openCudaVoter(const char* tool, int device, const char* cpu_only,
                                                      std::string* why) {
  std::unique_ptr<HypothesisVoter> gpu = tryCudaVoter(device, why);
  if (gpu) {
    const CudaVoterStats s = cudaVoterStats(*gpu);
    std::printf("%s: GPU %s (compute capability %d.%d)\n", tool, s.device_name.c_str(), s.compute_capability / 10,
                s.compute_capability % 10);
  } else {
    std::printf("%s: GPU PART SKIPPED: %s\n%s: %s\n", tool, why->c_str(), tool, cpu_only);
  }
  std::fflush(stdout);
  return gpu;
}

/// A bearing file's frames under the name it was given.
struct BearingInput {
  std::string name;
  std::vector<BearingFrame> frames;
};

/// Reads every file of options.files, each cut to options.max_frames frames. Throws
/// std::runtime_error naming the file and line of a bad file.
inline std::vector<BearingInput> readBearingInputs(const ToolOptions& options) {
  std::vector<BearingInput> inputs;
  for (const std::string& path : options.files) {
    std::vector<BearingFrame> frames = readBearingFile(path);
    if (frames.size() > options.max_frames) frames.resize(options.max_frames);
    inputs.push_back({path, std::move(frames)});
  }
  return inputs;
}

/// A CSV file written row by row; no file (every call a no-op) when the path is empty.
class CsvWriter {
 public:
  /// Opens `path` and writes `header` (without newline) as its first line; throws
  /// std::runtime_error when it cannot be written.
  CsvWriter(const std::string& path, const std::string& header) {
    if (path.empty()) return;
    file_ = std::fopen(path.c_str(), "w");
    if (file_ == nullptr) throw std::runtime_error("cannot write " + path);
    std::fprintf(file_, "%s\n", header.c_str());
  }
  CsvWriter(const CsvWriter&) = delete;
  CsvWriter& operator=(const CsvWriter&) = delete;
  ~CsvWriter() {
    if (file_ != nullptr) std::fclose(file_);
  }
  /// True when a file is being written.
  explicit operator bool() const { return file_ != nullptr; }
  /// Appends one line, printf-style (the newline is added).
  __attribute__((format(printf, 2, 3))) void row(const char* format, ...) {
    if (file_ == nullptr) return;
    va_list values;
    va_start(values, format);
    std::vfprintf(file_, format, values);
    va_end(values);
    std::fputc('\n', file_);
  }

 private:
  FILE* file_ = nullptr;
};

/// `text` with the characters that would break a CSV field (commas, quotes) made blanks.
inline std::string csvField(std::string text) {
  for (char& c : text)
    if (c == ',' || c == '"') c = ' ';
  return text;
}

/// The two grids every check and benchmark runs, as the estimator's methods use them.
enum class GridKind { kYaw, kRotation };

inline const char* gridName(GridKind kind) { return kind == GridKind::kYaw ? "yaw" : "rotation"; }

/// A VoteRequest for `frame`-style bearings on one of the two standard grids:
///  - yaw (the paper): bin 0.1 deg, window +-15 deg (300 bins), centroid subtraction on;
///  - rotation (method vote): rotation-vector cells of 0.5 deg, 24 bins per axis (+-6 deg around
///    zero), centroid subtraction off, max_angle_change 0.5 deg.
/// Both: min separation 0.3 deg, min triangle area 0.5 deg^2.
inline VoteRequest makeRequest(GridKind kind, const hyp::Vec3f* prev, const hyp::Vec3f* cur, uint32_t matches,
                               uint32_t hypotheses, uint64_t seed) {
  VoteRequest q;
  q.prev = prev;
  q.cur = cur;
  q.matches = matches;
  q.hypotheses = hypotheses;
  q.seed = seed;
  q.triple.min_separation = static_cast<float>(0.3 * kRadPerDeg);
  q.triple.min_triangle_area = static_cast<float>(0.5 * kRadPerDeg * kRadPerDeg);
  if (kind == GridKind::kYaw) {
    q.triple.centroid_subtraction = 1;
    q.triple.max_angle_change = 0.f;
    q.grid.kind = hyp::kVoteYaw;
    q.grid.bin_width = static_cast<float>(0.1 * kRadPerDeg);
    q.grid.bins = 300;
  } else {
    q.triple.centroid_subtraction = 0;
    q.triple.max_angle_change = static_cast<float>(0.5 * kRadPerDeg);
    q.grid.kind = hyp::kVoteRotationVector;
    q.grid.bin_width = static_cast<float>(0.5 * kRadPerDeg);
    q.grid.bins = 24;
  }
  q.grid.centre[0] = q.grid.centre[1] = q.grid.centre[2] = 0.f;
  return q;
}

/// Milliseconds since `start` on the host's steady clock.
inline double msSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
}

}  // namespace bearings
}  // namespace visual_gyro
