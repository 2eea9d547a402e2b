// cuda_estimator_check: the whole rotation estimator (voter + host verification and refinement)
// on the CPU backend and on the CUDA backend, over the frames of bearing files, compared by the
// figures evaluate reports (rotation and yaw RMSE against the files' truth, invalid estimates, mean
// rate): the CUDA run passes when they are within 5 % of the CPU run's. Also prints the median time
// split of an estimate per backend (voter call, its GPU kernels, host part), which is what decides
// whether the refinement is worth moving to the device. Without a working CUDA device the GPU part
// is skipped (said loudly) and the CPU run still happens.
// Exit status: 0 every comparison passed, 1 one failed or an input was bad, 2 a bad command line,
// 3 --require-gpu given but no device works.
#include <cstdio>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "standalone/check_common.h"
#include "standalone/estimator_compare.h"

using namespace visual_gyro;
using namespace visual_gyro::bearings;

namespace {

const char* const kTool = "cuda_estimator_check";

const char* const kUsage =
    "usage: cuda_estimator_check [options] BEARING_FILES...\n"
    "Runs the estimator (methods vote and paper, default settings) over every file's frames on the\n"
    "CPU and on the CUDA backend and compares evaluate's figures (within 5 %).\n"
    "  --method M[,M2]   vote, paper (default: vote,paper)\n"
    "  --hypotheses H    hypotheses per frame (default: the estimator's default)\n"
    "  --max-frames K    at most K frames per file (default: all)\n"
    "  --relative R      allowed relative difference of a figure (default 0.05)\n"
    "  --require-gpu     exit 3 when no CUDA device works (default: skip the GPU part)\n"
    "  --csv PATH        one row per file, method and backend\n";

struct EstimatorCheckOptions {
  ToolOptions tool;
  std::vector<std::string> methods{"vote", "paper"};
  int hypotheses = 0;  ///< 0: the estimator's default
  double relative = 0.05;
};

bool parseOptions(int argc, char** argv, EstimatorCheckOptions* o) {
  const unsigned shared = kOptionFiles | kOptionMaxFrames | kOptionRequireGpu | kOptionCsv;
  const bool run = parseToolArguments(argc, argv, kUsage, shared, &o->tool, [&](cli::Arguments& args) {
    if (args.is("--method")) {
      o->methods = args.listValue();
      for (const std::string& m : o->methods)
        if (m != "vote" && m != "paper") throw cli::UsageError("--method: unknown method \"" + m + "\"");
    } else if (args.is("--hypotheses")) {
      o->hypotheses = static_cast<int>(args.intValue(1, std::numeric_limits<int>::max()));
    } else if (args.is("--relative")) {
      o->relative = args.doubleValue(0.0, std::numeric_limits<double>::max());
    } else {
      return false;
    }
    return true;
  });
  if (run && o->tool.files.empty()) throw cli::UsageError("no bearing file given");
  return run;
}

void printRun(const EstimatorRun& r) {
  char kernels[32] = "-";  // no kernels on the CPU
  if (r.backend == Backend::kCuda) std::snprintf(kernels, sizeof kernels, "%.3f", medianOf(r.vote_device_ms));
  std::printf("  %-5s frames %4d invalid %3d  rot RMSE %8.4f max %8.4f  yaw RMSE %8.4f deg  rate %8.3f deg/s"
              "  | ms median: estimate %7.3f vote %7.3f (kernels %s) host %7.3f\n",
              backendName(r.backend), r.accuracy.frames, r.accuracy.invalid, r.accuracy.rot_rmse_deg, r.accuracy.rot_max_deg,
              r.accuracy.yaw_rmse_deg, r.accuracy.mean_rate_dps,
              medianOf(r.estimate_ms), medianOf(r.vote_ms), kernels, medianOf(r.refine_ms));
}

void writeRun(CsvWriter& csv, const std::string& file, const std::string& method, const EstimatorRun& r, int passed) {
  if (r.accuracy.frames == 0) return;
  csv.row("%s,%s,%s,%d,%d,%g,%g,%g,%g,%g,%g,%g,%g,%d", csvField(file).c_str(), method.c_str(), backendName(r.backend),
          r.accuracy.frames, r.accuracy.invalid, r.accuracy.rot_rmse_deg, r.accuracy.rot_max_deg,
          r.accuracy.yaw_rmse_deg, r.accuracy.mean_rate_dps, medianOf(r.estimate_ms), medianOf(r.vote_ms),
          medianOf(r.vote_device_ms), medianOf(r.refine_ms), passed);
}

/// One file and method on the CPU and, with `gpu`, on the CUDA backend: both printed and written,
/// then compared. 1 passed, 0 failed, -1 not compared (no GPU).
int checkMethod(const BearingInput& input, const std::string& method, const EstimatorCheckOptions& o, bool gpu,
                CsvWriter& csv) {
  EstimatorSettings settings;
  parseMethod(method, &settings.method);
  if (o.hypotheses > 0) settings.hypotheses = o.hypotheses;
  std::printf("%s, method %s, %zu frames:\n", input.name.c_str(), method.c_str(), input.frames.size());
  EstimatorRun cpu_run, gpu_run;
  try {
    settings.backend = BackendChoice::kCpu;
    cpu_run = runEstimator(createRotationEstimator(settings).get(), input.frames);
    printRun(cpu_run);
    if (gpu) {
      settings.backend = BackendChoice::kCuda;
      std::string warning;
      auto estimator = createRotationEstimator(settings, [&](const std::string& w) { warning = w; });
      if (estimator->backend() != Backend::kCuda) throw std::runtime_error("CUDA backend fell back: " + warning);
      gpu_run = runEstimator(estimator.get(), input.frames);
      printRun(gpu_run);
    }
  } catch (const std::exception& e) {
    std::printf("  FAILED: %s\n", e.what());
    return 0;
  }
  int verdict = -1;
  if (gpu) {
    const EstimatorComparison c = compareEstimatorRuns(cpu_run, gpu_run, o.relative);
    verdict = c.passed() ? 1 : 0;
    std::printf("  %s: largest per-frame difference %.4f deg, validity differs on %d frames%s\n",
                c.passed() ? "PASS" : "FAIL", c.max_rotation_difference_deg, c.validity_differs,
                c.passed() ? "" : "; differing figures:");
    for (const std::string& p : c.problems) std::printf("    %s\n", p.c_str());
  }
  for (const EstimatorRun* r : {&cpu_run, &gpu_run}) writeRun(csv, input.name, method, *r, verdict);
  return verdict;
}

int runCheck(const EstimatorCheckOptions& o) {
  std::string why;
  // The estimator makes its own CUDA voter: this one only finds out whether a device works.
  const bool gpu = openCudaVoter(kTool, o.tool.device, "running the CPU backend only; no CPU/GPU comparison was made",
                                 &why) != nullptr;
  if (!gpu && o.tool.require_gpu) return kExitNoGpu;
  const std::vector<BearingInput> inputs = readBearingInputs(o.tool);
  CsvWriter csv(o.tool.csv_path, "file,method,backend,frames,invalid,rot_rmse_deg,rot_max_deg,yaw_rmse_deg,"
                                 "mean_rate_dps,estimate_ms_median,vote_ms_median,vote_device_ms_median,"
                                 "host_ms_median,passed");
  int passed = 0, failed = 0, skipped = 0;
  for (const BearingInput& input : inputs)
    for (const std::string& method : o.methods) {
      const int verdict = checkMethod(input, method, o, gpu, csv);
      verdict > 0 ? ++passed : verdict == 0 ? ++failed : ++skipped;
    }
  std::printf("%d passed, %d failed, %d skipped\n", passed, failed, skipped);
  return failed > 0 ? 1 : 0;
}

}  // namespace

int main(int argc, char** argv) {
  return cli::runCommand(kTool, kUsage, [&]() {
    EstimatorCheckOptions options;
    if (!parseOptions(argc, argv, &options)) return 0;
    return runCheck(options);
  });
}
