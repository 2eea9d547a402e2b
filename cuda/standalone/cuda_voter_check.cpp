// cuda_voter_check: CPU gold voter versus CUDA voter, bin for bin and hypothesis by hypothesis, on
// bearing files and on synthetic frames (see cuda/README.md for the rule and the file format).
// Without a working CUDA device the GPU part is skipped (said loudly) and the CPU gold voter still
// runs, so the tool is useful on any machine. Exit status: 0 all compared frames passed,
// 1 a comparison failed or an input was bad, 2 --require-gpu given but no device works.
#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <iostream>
#include <map>
#include <limits>
#include <string>
#include <vector>

#include "bearing_file.h"
#include "command_line.h"
#include "standalone/check_common.h"
#include "standalone/voter_compare.h"

using namespace visual_gyro;
using namespace visual_gyro::bearings;

namespace {

void usage() {
  std::cout <<
      "usage: cuda_voter_check [options] [bearing files...]\n"
      "Runs the CPU gold voter and the CUDA voter with the same seed on every frame, on the yaw grid\n"
      "(0.1 deg bins, +-15 deg, centroid subtraction) and the rotation-vector grid (0.5 deg, 24^3,\n"
      "max angle change 0.5 deg), and compares them bin for bin and hypothesis by hypothesis.\n"
      "  --synthetic N            also check N synthetic frames (default: 8 when no file is given)\n"
      "  --matches M              matches per synthetic frame (default 2000)\n"
      "  --hypotheses H           hypotheses per frame (default 10000)\n"
      "  --seed S                 frame f of a run uses seed S + f (default 1)\n"
      "  --max-frames K           at most K frames per file (default: all)\n"
      "  --device D               CUDA device (default 0)\n"
      "  --require-gpu            exit 2 when no CUDA device works (default: skip the GPU part)\n"
      "  --edge-margin R          bin-edge margin of the rule [rad] (default 1e-4)\n"
      "  --max-explained-fraction F  hypotheses that may change cell for explained reasons (default 1e-2)\n"
      "  --csv PATH               one row per frame and grid\n"
      "  --write-synthetic PATH   write the synthetic frames as a bearing file\n";
}

/// Totals of one input (file or synthetic set) on one grid.
struct Totals {
  uint64_t frames = 0, compared = 0, passed = 0, failed = 0, skipped = 0;
  uint64_t hypotheses = 0, mismatched = 0, near_edge = 0, near_threshold = 0, ill_conditioned = 0, unexplained = 0;
  uint64_t winners_equal = 0, accepted = 0;
  double max_value_difference = 0.0, max_scaled_difference = 0.0, cpu_ms = 0.0, gpu_ms = 0.0, gpu_device_ms = 0.0;
};

}  // namespace

int main(int argc, char** argv) {
  std::vector<std::string> files;
  long long synthetic = -1;
  uint32_t matches = 2000, hypotheses = 10000;
  uint64_t seed = 1;
  uint64_t max_frames = ~0ull;
  int device = 0;
  bool require_gpu = false;
  CompareOptions compare;
  std::string csv_path, write_path;
  try {
    for (cli::Arguments args(argc, argv); args.next();) {
      const std::string arg = args.current();
      if (arg == "-h" || arg == "--help") {
        usage();
        return 0;
      } else if (arg == "--synthetic") {
        synthetic = static_cast<long long>(args.intValue(0, std::numeric_limits<long long>::max()));
      } else if (arg == "--matches") {
        matches = static_cast<uint32_t>(args.intValue(0, std::numeric_limits<long long>::max()));
      } else if (arg == "--hypotheses") {
        hypotheses = static_cast<uint32_t>(args.intValue(0, std::numeric_limits<long long>::max()));
      } else if (arg == "--seed") {
        seed = args.intValue(0, std::numeric_limits<long long>::max());
      } else if (arg == "--max-frames") {
        max_frames = args.intValue(0, std::numeric_limits<long long>::max());
      } else if (arg == "--device") {
        device = static_cast<int>(args.intValue(0, std::numeric_limits<long long>::max()));
      } else if (arg == "--require-gpu") {
        require_gpu = true;
      } else if (arg == "--edge-margin") {
        compare.edge_margin = args.doubleValue(-std::numeric_limits<double>::max(), std::numeric_limits<double>::max());
      } else if (arg == "--max-explained-fraction") {
        compare.max_explained_fraction = args.doubleValue(0.0, 1.0);
      } else if (arg == "--csv") {
        csv_path = args.value();
      } else if (arg == "--write-synthetic") {
        write_path = args.value();
      } else if (!arg.empty() && arg[0] == '-') {
        throw std::invalid_argument("unknown option " + arg);
      } else {
        files.push_back(arg);
      }
    }
    if (matches < 3) throw std::invalid_argument("--matches must be at least 3");
  } catch (const std::exception& e) {
    std::cerr << "cuda_voter_check: " << e.what() << "\n";
    usage();
    return 1;
  }
  if (synthetic < 0) synthetic = files.empty() ? 8 : 0;

  std::string why;
  std::unique_ptr<HypothesisVoter> gpu = tryCudaVoter(device, &why);
  std::unique_ptr<HypothesisVoter> cpu = createCpuVoter();
  if (gpu) {
    const CudaVoterStats s = cudaVoterStats(*gpu);
    std::printf("cuda_voter_check: GPU %s (compute capability %d.%d)\n", s.device_name.c_str(),
                s.compute_capability / 10, s.compute_capability % 10);
  } else {
    std::printf("cuda_voter_check: GPU PART SKIPPED: %s\n"
                "cuda_voter_check: running the CPU gold voter only; no CPU/GPU comparison was made\n",
                why.c_str());
    if (require_gpu) {
      std::fprintf(stderr, "cuda_voter_check: --require-gpu given but no CUDA device works\n");
      return 2;
    }
  }

  // Inputs: (name, frames).
  std::vector<std::pair<std::string, std::vector<BearingFrame>>> inputs;
  for (const std::string& path : files) {
    try {
      std::vector<BearingFrame> frames = readBearingFile(path);
      if (frames.size() > max_frames) frames.resize(max_frames);
      inputs.emplace_back(path, std::move(frames));
    } catch (const std::exception& e) {
      std::fprintf(stderr, "cuda_voter_check: %s\n", e.what());
      return 1;
    }
  }
  std::vector<std::array<double, 3>> truth;  // synthetic frames' (yaw, pitch, roll)
  if (synthetic > 0) {
    std::vector<BearingFrame> frames;
    SyntheticOptions options;
    options.matches = matches;
    for (long long f = 0; f < synthetic; ++f) {
      // Alternate pure rotation and forward driving (parallax), as in the shared sequences.
      options.forward_translation = (f % 2) ? 1.0 : 0.0;
      std::array<double, 3> ypr;
      frames.push_back(makeSyntheticFrame(options, seed * 1000003ull + static_cast<uint64_t>(f), f, ypr.data()));
      truth.push_back(ypr);
    }
    if (!write_path.empty()) {
      try {
        writeBearingFile(write_path, frames);
        std::printf("cuda_voter_check: wrote %lld synthetic frames to %s\n", synthetic, write_path.c_str());
      } catch (const std::exception& e) {
        std::fprintf(stderr, "cuda_voter_check: %s\n", e.what());
        return 1;
      }
    }
    inputs.emplace_back("synthetic", std::move(frames));
  }

  FILE* csv = nullptr;
  if (!csv_path.empty()) {
    csv = std::fopen(csv_path.c_str(), "w");
    if (csv == nullptr) {
      std::fprintf(stderr, "cuda_voter_check: cannot write %s\n", csv_path.c_str());
      return 1;
    }
    std::fprintf(csv, "input,frame,grid,matches,cpu_accepted,%s,max_value_diff_rad,max_scaled_diff_rad,cpu_ms,gpu_call_ms,"
                      "gpu_device_ms,status\n", cellDifferencesCsvHeader().c_str());
  }

  uint64_t total_passed = 0, total_failed = 0, total_skipped = 0;
  uint64_t run_frame = 0;  // seeds: seed + run_frame, as the estimator does per frame
  uint64_t truth_hits = 0, truth_frames = 0;
  for (const auto& input : inputs) {
    const bool is_synthetic = &input == &inputs.back() && synthetic > 0;
    std::map<GridKind, Totals> totals;
    for (size_t fi = 0; fi < input.second.size(); ++fi) {
      const BearingFrame& frame = input.second[fi];
      const uint32_t n = static_cast<uint32_t>(frame.prev.size());
      const uint64_t frame_seed = seed + run_frame++;
      for (GridKind kind : {GridKind::kYaw, GridKind::kRotation}) {
        Totals& t = totals[kind];
        ++t.frames;
        if (n < 3) {
          ++t.skipped;
          ++total_skipped;
          continue;
        }
        VoteRequest q = makeRequest(kind, frame.prev.data(), frame.cur.data(), n, hypotheses, frame_seed);
        q.keep_records = true;
        VoteResult c, g;
        auto start = std::chrono::steady_clock::now();
        cpu->vote(q, &c);
        const double cpu_ms = msSince(start);
        t.cpu_ms += cpu_ms;
        t.accepted += c.accepted;
        t.hypotheses += hypotheses;
        if (is_synthetic && kind == GridKind::kYaw && fi < truth.size() && c.winner >= 0) {
          const double yaw = c.cell_sums[3 * c.winner] / c.histogram[c.winner];
          ++truth_frames;
          if (std::fabs(yaw - truth[fi][0]) < 0.2 * kRadPerDeg) ++truth_hits;
        }
        std::string status = "skipped";
        CompareReport r;
        double gpu_ms = 0.0, device_ms = 0.0;
        if (gpu) {
          try {
            start = std::chrono::steady_clock::now();
            gpu->vote(q, &g);
            gpu_ms = msSince(start);
            device_ms = g.device_ms;
            r = compareVotes(q, c, g, compare);
            // The record-free path (what the estimator runs) must vote identically.
            VoteRequest lean = q;
            lean.keep_records = false;
            VoteResult g2;
            gpu->vote(lean, &g2);
            if (g2.histogram != g.histogram || g2.winner != g.winner || g2.accepted != g.accepted)
              r.problems.push_back("GPU without records votes differently from GPU with records");
          } catch (const std::exception& e) {
            r.problems.push_back(std::string("GPU vote threw: ") + e.what());
          }
          ++t.compared;
          t.gpu_ms += gpu_ms;
          t.gpu_device_ms += device_ms;
          t.mismatched += r.mismatched;
          t.near_edge += r.near_edge;
          t.near_threshold += r.near_threshold;
          t.ill_conditioned += r.ill_conditioned;
          t.unexplained += r.unexplained;
          t.max_value_difference = std::max(t.max_value_difference, r.max_value_difference);
          t.max_scaled_difference = std::max(t.max_scaled_difference, r.max_scaled_difference);
          if (r.winnersEqual()) ++t.winners_equal;
          if (r.passed()) {
            status = "passed";
            ++t.passed;
            ++total_passed;
          } else {
            status = "failed";
            ++t.failed;
            ++total_failed;
            std::printf("FAILED %s frame %lld %s grid:", input.first.c_str(), static_cast<long long>(frame.index),
                        gridName(kind));
            for (const std::string& p : r.problems) std::printf(" [%s]", p.c_str());
            std::printf("\n");
          }
        } else {
          ++t.skipped;
          ++total_skipped;
        }
        if (csv != nullptr) {
          if (!gpu) {  // the CPU's side only
            r.hypotheses = hypotheses;
            r.cpu_winner = c.winner;
          }
          std::fprintf(csv, "%s,%lld,%s,%u,%u,%s,%.3g,%.3g,%.4f,%.4f,%.4f,%s\n", input.first.c_str(),
                       static_cast<long long>(frame.index), gridName(kind), n, c.accepted,
                       cellDifferencesCsv(r).c_str(), r.max_value_difference, r.max_scaled_difference, cpu_ms, gpu_ms,
                       device_ms, status.c_str());
        }
      }
    }
    for (const auto& entry : totals) {
      const Totals& t = entry.second;
      const double frames = std::max<double>(1.0, static_cast<double>(t.frames));
      std::printf("[%s] %s grid: %llu frames, %llu hypotheses, CPU gold %.3f ms/frame, %.0f accepted/frame\n",
                  input.first.c_str(), gridName(entry.first), static_cast<unsigned long long>(t.frames),
                  static_cast<unsigned long long>(t.hypotheses), t.cpu_ms / frames, t.accepted / frames);
      if (t.compared == 0) {
        std::printf("  GPU comparison skipped (%llu frames)\n", static_cast<unsigned long long>(t.skipped));
        continue;
      }
      const double per = static_cast<double>(t.compared);
      std::printf("  GPU %.3f ms/frame (kernels %.3f ms); %llu of %llu hypotheses in different cells (fraction %.2e):"
                  " %llu at bin edges, %llu straddling an edge by a tolerated difference, %llu at degeneracy thresholds,"
                  " %llu unexplained; max |value diff| %.2e rad (times sv1/sv0: %.2e);"
                  " winners equal in %llu/%llu frames; %llu passed, %llu failed\n",
                  t.gpu_ms / per, t.gpu_device_ms / per, static_cast<unsigned long long>(t.mismatched),
                  static_cast<unsigned long long>(t.hypotheses),
                  t.hypotheses ? static_cast<double>(t.mismatched) / t.hypotheses : 0.0,
                  static_cast<unsigned long long>(t.near_edge), static_cast<unsigned long long>(t.ill_conditioned),
                  static_cast<unsigned long long>(t.near_threshold), static_cast<unsigned long long>(t.unexplained),
                  t.max_value_difference, t.max_scaled_difference,
                  static_cast<unsigned long long>(t.winners_equal), static_cast<unsigned long long>(t.compared),
                  static_cast<unsigned long long>(t.passed), static_cast<unsigned long long>(t.failed));
    }
  }
  if (csv != nullptr) std::fclose(csv);
  if (truth_frames > 0)
    std::printf("CPU gold sanity: synthetic yaw winner within 0.2 deg of the true yaw in %llu/%llu frames\n",
                static_cast<unsigned long long>(truth_hits), static_cast<unsigned long long>(truth_frames));
  std::printf("rule: %s\n", describeRule(compare).c_str());
  if (gpu) {
    const CudaVoterStats s = cudaVoterStats(*gpu);
    std::printf("CUDA voter: %llu frames, %llu buffer reallocations after construction, %.1f MiB device memory\n",
                static_cast<unsigned long long>(s.frames), static_cast<unsigned long long>(s.reallocations),
                s.device_bytes / 1048576.0);
  }
  std::printf("%llu passed, %llu failed, %llu skipped%s\n", static_cast<unsigned long long>(total_passed),
              static_cast<unsigned long long>(total_failed), static_cast<unsigned long long>(total_skipped),
              gpu ? "" : " (GPU part skipped: no usable CUDA device)");
  return total_failed > 0 ? 1 : 0;
}
