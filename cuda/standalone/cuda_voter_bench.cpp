// cuda_voter_bench: estimation time of the CPU gold voter and the CUDA voter against the number of
// hypotheses (at 2 000 matches) and the number of matches (at 10 000 hypotheses), on both vote
// grids; the paper's timing figures with today's hardware. Whole-call time by the host's steady
// clock (upload to result on the host), GPU kernel time by CUDA events; medians over --runs runs
// after --warmup runs. Without a working CUDA device the CUDA rows are skipped (said loudly).
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <limits>
#include <string>
#include <vector>

#include "bearing_file.h"
#include "command_line.h"
#include "standalone/check_common.h"

using namespace visual_gyro;
using namespace visual_gyro::bearings;

namespace {

void usage() {
  std::cout <<
      "usage: cuda_voter_bench [options]\n"
      "  --file PATH        bearing file; its frame with the most matches (or --frame K) is\n"
      "                     resampled to each match count (default: synthetic bearings)\n"
      "  --frame K          use the K-th frame of the file (0-based)\n"
      "  --csv PATH         write the results as CSV (default: none)\n"
      "  --runs N           timed runs per point, median reported (default 20)\n"
      "  --warmup N         untimed runs first (default 3)\n"
      "  --grids LIST       yaw, rotation or yaw,rotation (default)\n"
      "  --backends LIST    cpu, cuda or cpu,cuda (default)\n"
      "  --device D         CUDA device (default 0)\n"
      "  --quick            fewer points and runs (a smoke test)\n";
}

double percentile(std::vector<double> v, double q) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  const double pos = q * (v.size() - 1);
  const size_t lo = static_cast<size_t>(pos);
  const size_t hi = std::min(lo + 1, v.size() - 1);
  return v[lo] + (pos - lo) * (v[hi] - v[lo]);
}

std::string cpuModel() {
  std::ifstream in("/proc/cpuinfo");
  std::string line;
  while (std::getline(in, line))
    if (line.rfind("model name", 0) == 0) {
      const size_t colon = line.find(':');
      if (colon != std::string::npos) return line.substr(line.find_first_not_of(' ', colon + 1));
    }
  return "cpu";
}

std::string csvField(std::string text) {
  for (char& c : text)
    if (c == ',' || c == '"') c = ' ';
  return text;
}

struct Timing {
  double call_median = 0, call_p10 = 0, call_p90 = 0, device_median = 0;
  uint32_t accepted = 0;
  int32_t winner_votes = 0;
};

Timing timeVoter(HypothesisVoter& voter, VoteRequest q, int warmup, int runs) {
  VoteResult result;
  std::vector<double> call, device;
  const uint64_t seed = q.seed;
  for (int r = 0; r < warmup + runs; ++r) {
    q.seed = seed + static_cast<uint64_t>(r);  // a new frame's triples each run, as in a sequence
    const auto start = std::chrono::steady_clock::now();
    voter.vote(q, &result);
    const double ms = msSince(start);
    if (r < warmup) continue;
    call.push_back(ms);
    device.push_back(result.device_ms);
  }
  Timing t;
  t.call_median = percentile(call, 0.5);
  t.call_p10 = percentile(call, 0.1);
  t.call_p90 = percentile(call, 0.9);
  t.device_median = percentile(device, 0.5);
  t.accepted = result.accepted;
  t.winner_votes = result.winner >= 0 ? result.histogram[result.winner] : 0;
  return t;
}

}  // namespace

int main(int argc, char** argv) {
  std::string file, csv_path;
  long long frame_index = -1;
  int runs = 20, warmup = 3, device = 0;
  bool quick = false, want_yaw = true, want_rotation = true, want_cpu = true, want_cuda = true;
  try {
    for (cli::Arguments args(argc, argv); args.next();) {
      const std::string arg = args.current();
      if (arg == "-h" || arg == "--help") {
        usage();
        return 0;
      } else if (arg == "--file") {
        file = args.value();
      } else if (arg == "--frame") {
        frame_index = static_cast<long long>(args.intValue(0, std::numeric_limits<long long>::max()));
      } else if (arg == "--csv") {
        csv_path = args.value();
      } else if (arg == "--runs") {
        runs = static_cast<int>(args.intValue(0, std::numeric_limits<long long>::max()));
      } else if (arg == "--warmup") {
        warmup = static_cast<int>(args.intValue(0, std::numeric_limits<long long>::max()));
      } else if (arg == "--device") {
        device = static_cast<int>(args.intValue(0, std::numeric_limits<long long>::max()));
      } else if (arg == "--quick") {
        quick = true;
      } else if (arg == "--grids" || arg == "--backends") {
        const std::string list = args.value();
        const bool first = list.find(arg == "--grids" ? "yaw" : "cpu") != std::string::npos;
        const bool second = list.find(arg == "--grids" ? "rotation" : "cuda") != std::string::npos;
        if (!first && !second) throw std::invalid_argument("nothing selected by " + arg + " " + list);
        (arg == "--grids" ? want_yaw : want_cpu) = first;
        (arg == "--grids" ? want_rotation : want_cuda) = second;
      } else {
        throw std::invalid_argument("unknown argument " + arg);
      }
    }
    if (runs < 1) throw std::invalid_argument("--runs must be at least 1");
  } catch (const std::exception& e) {
    std::cerr << "cuda_voter_bench: " << e.what() << "\n";
    usage();
    return 1;
  }
  if (quick) {
    runs = std::min(runs, 5);
    warmup = std::min(warmup, 1);
  }

  BearingFrame base;
  std::string source = "synthetic";
  if (!file.empty()) {
    try {
      const std::vector<BearingFrame> frames = readBearingFile(file);
      if (frames.empty()) throw std::runtime_error(file + " has no frames");
      size_t pick = 0;
      if (frame_index >= 0) {
        if (static_cast<size_t>(frame_index) >= frames.size()) throw std::runtime_error("--frame beyond the file's frames");
        pick = static_cast<size_t>(frame_index);
      } else {
        for (size_t f = 1; f < frames.size(); ++f)
          if (frames[f].prev.size() > frames[pick].prev.size()) pick = f;
      }
      base = frames[pick];
      if (base.prev.size() < 3) throw std::runtime_error("the chosen frame has fewer than 3 matches");
      source = file + " frame " + std::to_string(base.index) + " (" + std::to_string(base.prev.size()) + " matches)";
    } catch (const std::exception& e) {
      std::cerr << "cuda_voter_bench: " << e.what() << "\n";
      return 1;
    }
  }
  auto framesWith = [&](uint32_t matches) {
    if (!file.empty()) return resampleFrame(base, matches, 7);
    SyntheticOptions options;  // 30 % outliers, pure rotation
    options.matches = matches;
    return makeSyntheticFrame(options, 42);
  };

  std::unique_ptr<HypothesisVoter> cpu = createCpuVoter();
  std::unique_ptr<HypothesisVoter> gpu;
  std::string gpu_name, why;
  if (want_cuda) {
    gpu = tryCudaVoter(device, &why);
    if (gpu) {
      gpu_name = cudaVoterStats(*gpu).device_name;
    } else {
      std::printf("cuda_voter_bench: GPU PART SKIPPED: %s\n"
                  "cuda_voter_bench: timing the CPU gold voter only; no CUDA figures were measured\n",
                  why.c_str());
    }
  }
  const std::string cpu_name = cpuModel();
  std::printf("cuda_voter_bench: bearings from %s; %d runs (median) after %d warm-up runs\n", source.c_str(), runs,
              warmup);

  FILE* csv = nullptr;
  if (!csv_path.empty()) {
    csv = std::fopen(csv_path.c_str(), "w");
    if (csv == nullptr) {
      std::fprintf(stderr, "cuda_voter_bench: cannot write %s\n", csv_path.c_str());
      return 1;
    }
    std::fprintf(csv, "series,grid,backend,device,matches,hypotheses,runs,call_ms_median,call_ms_p10,call_ms_p90,"
                      "device_ms_median,accepted,winner_votes,speedup_vs_cpu,source\n");
  }

  const std::vector<uint32_t> hypothesis_counts =
      quick ? std::vector<uint32_t>{100, 1000, 10000} : std::vector<uint32_t>{100, 300, 1000, 3000, 10000, 30000, 100000};
  const std::vector<uint32_t> match_counts =
      quick ? std::vector<uint32_t>{250, 2000} : std::vector<uint32_t>{250, 500, 1000, 2000, 4000, 8000};
  struct Point {
    const char* series;
    uint32_t matches, hypotheses;
  };
  std::vector<Point> points;
  for (uint32_t h : hypothesis_counts) points.push_back({"hypotheses", 2000, h});
  for (uint32_t m : match_counts) points.push_back({"matches", m, 10000});

  std::printf("%-10s %-8s %-7s %7s %7s %12s %12s %12s %9s\n", "series", "grid", "backend", "matches", "hyps",
              "call_ms_med", "call_ms_p90", "kernel_ms", "speedup");
  int failures = 0;
  for (const Point& point : points) {
    const BearingFrame frame = framesWith(point.matches);
    for (GridKind kind : {GridKind::kYaw, GridKind::kRotation}) {
      if ((kind == GridKind::kYaw && !want_yaw) || (kind == GridKind::kRotation && !want_rotation)) continue;
      const VoteRequest q = makeRequest(kind, frame.prev.data(), frame.cur.data(), point.matches, point.hypotheses, 1);
      double cpu_median = 0.0;
      for (int b = 0; b < 2; ++b) {
        HypothesisVoter* voter = b == 0 ? (want_cpu ? cpu.get() : nullptr) : gpu.get();
        if (voter == nullptr) continue;
        Timing t;
        try {
          t = timeVoter(*voter, q, warmup, runs);
        } catch (const std::exception& e) {
          std::fprintf(stderr, "cuda_voter_bench: %s voter failed: %s\n", voter->name().c_str(), e.what());
          ++failures;
          continue;
        }
        if (b == 0) cpu_median = t.call_median;
        const double speedup = (b == 1 && cpu_median > 0.0) ? cpu_median / t.call_median : 0.0;
        if (b == 1)
          std::printf("%-10s %-8s %-7s %7u %7u %12.4f %12.4f %12.4f %9.1f\n", point.series, gridName(kind),
                      voter->name().c_str(), point.matches, point.hypotheses, t.call_median, t.call_p90,
                      t.device_median, speedup);
        else
          std::printf("%-10s %-8s %-7s %7u %7u %12.4f %12.4f %12s %9s\n", point.series, gridName(kind),
                      voter->name().c_str(), point.matches, point.hypotheses, t.call_median, t.call_p90, "-", "-");
        if (csv != nullptr) {
          // Kernel time and speed-up exist only for the CUDA rows: left empty for the CPU ones.
          char device_ms[32] = "", speedup_text[32] = "";
          if (b == 1) {
            std::snprintf(device_ms, sizeof device_ms, "%.5f", t.device_median);
            if (speedup > 0.0) std::snprintf(speedup_text, sizeof speedup_text, "%.3f", speedup);
          }
          std::fprintf(csv, "%s,%s,%s,%s,%u,%u,%d,%.5f,%.5f,%.5f,%s,%u,%d,%s,%s\n", point.series, gridName(kind),
                       voter->name().c_str(), csvField(b == 0 ? cpu_name : gpu_name).c_str(), point.matches,
                       point.hypotheses, runs, t.call_median, t.call_p10, t.call_p90, device_ms, t.accepted,
                       t.winner_votes, speedup_text, csvField(source).c_str());
        }
      }
    }
  }
  if (csv != nullptr) {
    std::fclose(csv);
    std::printf("cuda_voter_bench: wrote %s\n", csv_path.c_str());
  }
  if (gpu) {
    const CudaVoterStats s = cudaVoterStats(*gpu);
    std::printf("cuda_voter_bench: GPU %s; %llu buffer reallocations after construction (growing to the largest"
                " frame)\n",
                gpu_name.c_str(), static_cast<unsigned long long>(s.reallocations));
  } else if (want_cuda) {
    std::printf("cuda_voter_bench: CUDA rows skipped: %s\n", why.c_str());
  }
  return failures > 0 ? 1 : 0;
}
