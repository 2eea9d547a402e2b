// cuda_estimator_check: the whole rotation estimator (voter + host verification and refinement)
// on the CPU backend and on the CUDA backend, over the frames of bearing files, compared by the
// figures evaluate reports (rotation and yaw RMSE against the files' truth, invalid estimates, mean
// rate): the CUDA run passes when they are within 5 % of the CPU run's. Also prints the median time
// split of an estimate per backend (voter call, its GPU kernels, host part), which is what decides
// whether the refinement is worth moving to the device. Without a working CUDA device the GPU part
// is skipped (said loudly) and the CPU run still happens.
// Exit status: 0 every comparison passed, 1 one failed or an input was bad, 2 --require-gpu given
// but no device works.
#include <cstdio>
#include <fstream>
#include <iostream>
#include <memory>
#include <limits>
#include <string>
#include <vector>

#include "bearing_file.h"
#include "command_line.h"
#include "standalone/check_common.h"
#include "standalone/estimator_compare.h"

using namespace visual_gyro;
using namespace visual_gyro::bearings;

namespace {

void usage() {
  std::cout <<
      "usage: cuda_estimator_check [options] BEARING_FILES...\n"
      "Runs the estimator (methods vote and paper, default settings) over every file's frames on the\n"
      "CPU and on the CUDA backend and compares evaluate's figures (within 5 %).\n"
      "  --method M[,M2]   vote, paper (default: vote,paper)\n"
      "  --hypotheses H    hypotheses per frame (default: the estimator's default)\n"
      "  --max-frames K    at most K frames per file (default: all)\n"
      "  --relative R      allowed relative difference of a figure (default 0.05)\n"
      "  --require-gpu     exit 2 when no CUDA device works (default: skip the GPU part)\n"
      "  --csv PATH        one row per file, method and backend\n";
}

void printRun(const EstimatorRun& r) {
  char kernels[32] = "-";  // no kernels on the CPU
  if (r.backend == "cuda") std::snprintf(kernels, sizeof kernels, "%.3f", medianOf(r.vote_device_ms));
  std::printf("  %-5s frames %4d invalid %3d  rot RMSE %8.4f max %8.4f  yaw RMSE %8.4f deg  rate %8.3f deg/s"
              "  | ms median: estimate %7.3f vote %7.3f (kernels %s) host %7.3f\n",
              r.backend.c_str(), r.accuracy.frames, r.accuracy.invalid, r.accuracy.rot_rmse_deg, r.accuracy.rot_max_deg,
              r.accuracy.yaw_rmse_deg, r.accuracy.mean_rate_dps,
              medianOf(r.estimate_ms), medianOf(r.vote_ms), kernels, medianOf(r.refine_ms));
}

}  // namespace

int main(int argc, char** argv) {
  std::vector<std::string> files, methods{"vote", "paper"};
  long long hypotheses = 0;
  uint64_t max_frames = ~0ull;
  double relative = 0.05;
  bool require_gpu = false;
  std::string csv_path;
  try {
    for (cli::Arguments args(argc, argv); args.next();) {
      const std::string arg = args.current();
      if (arg == "-h" || arg == "--help") {
        usage();
        return 0;
      } else if (arg == "--method") {
        methods = args.listValue();
        for (const std::string& m : methods)
          if (m != "vote" && m != "paper") throw std::invalid_argument("--method: unknown method \"" + m + "\"");
      } else if (arg == "--hypotheses") {
        hypotheses = static_cast<long long>(args.intValue(0, std::numeric_limits<long long>::max()));
      } else if (arg == "--max-frames") {
        max_frames = args.intValue(0, std::numeric_limits<long long>::max());
      } else if (arg == "--relative") {
        relative = args.doubleValue(-std::numeric_limits<double>::max(), std::numeric_limits<double>::max());
        if (!(relative >= 0.0)) throw std::invalid_argument("--relative must be >= 0");
      } else if (arg == "--require-gpu") {
        require_gpu = true;
      } else if (arg == "--csv") {
        csv_path = args.value();
      } else if (!arg.empty() && arg[0] == '-') {
        throw std::invalid_argument("unknown option " + arg);
      } else {
        files.push_back(arg);
      }
    }
    if (files.empty()) throw std::invalid_argument("no bearing file given");
  } catch (const std::exception& e) {
    std::cerr << "cuda_estimator_check: " << e.what() << "\n";
    usage();
    return 1;
  }

  std::string why;
  const bool gpu = cudaDeviceAvailable(&why);
  if (!gpu) {
    std::cout << "cuda_estimator_check: GPU PART SKIPPED: " << why << "\n";
    if (require_gpu) return 2;
  }
  std::ofstream csv;
  if (!csv_path.empty()) {
    csv.open(csv_path);
    if (!csv) {
      std::cerr << "cuda_estimator_check: cannot write " << csv_path << "\n";
      return 1;
    }
    csv << "file,method,backend,frames,invalid,rot_rmse_deg,rot_max_deg,yaw_rmse_deg,mean_rate_dps,"
           "estimate_ms_median,vote_ms_median,vote_device_ms_median,host_ms_median,passed\n";
  }

  int passed = 0, failed = 0, skipped = 0;
  for (const std::string& path : files) {
    std::vector<BearingFrame> frames;
    try {
      frames = readBearingFile(path);
    } catch (const std::exception& e) {
      std::cerr << "cuda_estimator_check: " << e.what() << "\n";
      ++failed;
      continue;
    }
    if (frames.size() > max_frames) frames.resize(max_frames);
    for (const std::string& method : methods) {
      EstimatorSettings settings;
      parseMethod(method, &settings.method);
      if (hypotheses > 0) settings.hypotheses = static_cast<int>(hypotheses);
      std::printf("%s, method %s, %zu frames:\n", path.c_str(), method.c_str(), frames.size());
      EstimatorRun cpu_run, gpu_run;
      try {
        settings.backend = BackendChoice::kCpu;
        cpu_run = runEstimator(createRotationEstimator(settings).get(), frames);
        printRun(cpu_run);
        if (gpu) {
          settings.backend = BackendChoice::kCuda;
          std::string warning;
          auto estimator = createRotationEstimator(settings, [&](const std::string& w) { warning = w; });
          if (estimator->backendName() != "cuda") throw std::runtime_error("CUDA backend fell back: " + warning);
          gpu_run = runEstimator(estimator.get(), frames);
          printRun(gpu_run);
        }
      } catch (const std::exception& e) {
        std::printf("  FAILED: %s\n", e.what());
        ++failed;
        continue;
      }
      bool ok = true;
      if (gpu) {
        const EstimatorComparison c = compareEstimatorRuns(cpu_run, gpu_run, relative);
        ok = c.passed();
        std::printf("  %s: largest per-frame difference %.4f deg, validity differs on %d frames%s\n",
                    ok ? "PASS" : "FAIL", c.max_rotation_difference_deg, c.validity_differs,
                    ok ? "" : "; differing figures:");
        for (const std::string& p : c.problems) std::printf("    %s\n", p.c_str());
        ok ? ++passed : ++failed;
      } else {
        ++skipped;
      }
      if (csv) {
        for (const EstimatorRun* r : {&cpu_run, &gpu_run}) {
          if (r->accuracy.frames == 0) continue;
          csv << path << ',' << method << ',' << r->backend << ',' << r->accuracy.frames << ',' << r->accuracy.invalid << ','
              << r->accuracy.rot_rmse_deg << ',' << r->accuracy.rot_max_deg << ',' << r->accuracy.yaw_rmse_deg << ',' << r->accuracy.mean_rate_dps << ','
              << medianOf(r->estimate_ms) << ',' << medianOf(r->vote_ms) << ',' << medianOf(r->vote_device_ms) << ','
              << medianOf(r->refine_ms) << ',' << (gpu ? (ok ? 1 : 0) : -1) << '\n';
        }
      }
    }
  }
  std::printf("%d passed, %d failed, %d skipped\n", passed, failed, skipped);
  return failed > 0 ? 1 : 0;
}
