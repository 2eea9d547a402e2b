// cuda_voter_bench: estimation time of the CPU gold voter and the CUDA voter against the number of
// hypotheses (at 2 000 matches) and the number of matches (at 10 000 hypotheses), on both vote
// grids; the paper's timing figures with today's hardware. Whole-call time by the host's steady
// clock (upload to result on the host), GPU kernel time by CUDA events; medians over --runs runs
// after --warmup runs. Without a working CUDA device the CUDA rows are skipped (said loudly).
// Exit status: 0 every voter ran, 1 one threw or an input was bad, 2 a bad command line.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <fstream>
#include <limits>
#include <string>
#include <vector>

#include "standalone/check_common.h"

using namespace visual_gyro;
using namespace visual_gyro::bearings;

namespace {

const char* const kTool = "cuda_voter_bench";

const char* const kUsage =
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

struct BenchOptions {
  ToolOptions tool;
  std::string file;
  long long frame_index = -1;
  int runs = 20, warmup = 3;
  bool quick = false, want_yaw = true, want_rotation = true, want_cpu = true, want_cuda = true;
};

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

bool parseOptions(int argc, char** argv, BenchOptions* o) {
  const long long kMaxInt = std::numeric_limits<int>::max();
  const bool run = parseToolArguments(argc, argv, kUsage, kOptionDevice | kOptionCsv, &o->tool, [&](cli::Arguments& args) {
    if (args.is("--file")) {
      o->file = args.value();
    } else if (args.is("--frame")) {
      o->frame_index = args.intValue(0, std::numeric_limits<long long>::max());
    } else if (args.is("--runs")) {
      o->runs = static_cast<int>(args.intValue(1, kMaxInt));
    } else if (args.is("--warmup")) {
      o->warmup = static_cast<int>(args.intValue(0, kMaxInt));
    } else if (args.is("--quick")) {
      o->quick = true;
    } else if (args.is("--grids") || args.is("--backends")) {
      const bool grids = args.is("--grids");
      const std::string option = args.current();
      bool first = false, second = false;
      for (const std::string& item : args.listValue()) {
        const bool is_first = item == (grids ? "yaw" : "cpu"), is_second = item == (grids ? "rotation" : "cuda");
        if (!is_first && !is_second) throw cli::UsageError(option + ": unknown item \"" + item + "\"");
        first = first || is_first;
        second = second || is_second;
      }
      (grids ? o->want_yaw : o->want_cpu) = first;
      (grids ? o->want_rotation : o->want_cuda) = second;
    } else {
      return false;
    }
    return true;
  });
  if (o->quick) {
    o->runs = std::min(o->runs, 5);
    o->warmup = std::min(o->warmup, 1);
  }
  return run;
}

/// The frame the file's points are resampled from: --frame K, else the one with the most matches.
/// Throws std::runtime_error for an empty file, a frame beyond it or one with fewer than 3 matches.
BearingFrame baseFrame(const BenchOptions& o, std::string* source) {
  const std::vector<BearingFrame> frames = readBearingFile(o.file);
  if (frames.empty()) throw std::runtime_error(o.file + " has no frames");
  size_t pick = 0;
  if (o.frame_index >= 0) {
    if (static_cast<size_t>(o.frame_index) >= frames.size()) throw std::runtime_error("--frame beyond the file's frames");
    pick = static_cast<size_t>(o.frame_index);
  } else {
    for (size_t f = 1; f < frames.size(); ++f)
      if (frames[f].prev.size() > frames[pick].prev.size()) pick = f;
  }
  const BearingFrame& base = frames[pick];
  if (base.prev.size() < 3) throw std::runtime_error("the chosen frame has fewer than 3 matches");
  *source = o.file + " frame " + std::to_string(base.index) + " (" + std::to_string(base.prev.size()) + " matches)";
  return base;
}

/// The points of the two series: hypotheses at 2 000 matches, matches at 10 000 hypotheses.
struct Point {
  const char* series;
  uint32_t matches, hypotheses;
};

std::vector<Point> benchPoints(bool quick) {
  const std::vector<uint32_t> hypothesis_counts =
      quick ? std::vector<uint32_t>{100, 1000, 10000} : std::vector<uint32_t>{100, 300, 1000, 3000, 10000, 30000, 100000};
  const std::vector<uint32_t> match_counts =
      quick ? std::vector<uint32_t>{250, 2000} : std::vector<uint32_t>{250, 500, 1000, 2000, 4000, 8000};
  std::vector<Point> points;
  for (uint32_t h : hypothesis_counts) points.push_back({"hypotheses", 2000, h});
  for (uint32_t m : match_counts) points.push_back({"matches", m, 10000});
  return points;
}

/// The two voters with their names for the CSV.
struct Voters {
  std::unique_ptr<HypothesisVoter> cpu, gpu;
  std::string cpu_name, gpu_name;
};

/// Times the voters at one point on one grid: a table line and a CSV row per voter; the number of
/// voters that threw.
int benchPoint(const Point& point, GridKind kind, const BearingFrame& frame, const BenchOptions& o, Voters& voters,
               const std::string& source, CsvWriter& csv) {
  const VoteRequest q = makeRequest(kind, frame.prev.data(), frame.cur.data(), point.matches, point.hypotheses, 1);
  double cpu_median = 0.0;
  int failures = 0;
  for (int b = 0; b < 2; ++b) {
    HypothesisVoter* voter = b == 0 ? (o.want_cpu ? voters.cpu.get() : nullptr) : voters.gpu.get();
    if (voter == nullptr) continue;
    Timing t;
    try {
      t = timeVoter(*voter, q, o.warmup, o.runs);
    } catch (const std::exception& e) {
      std::fprintf(stderr, "%s: %s voter failed: %s\n", kTool, voter->name().c_str(), e.what());
      ++failures;
      continue;
    }
    if (b == 0) cpu_median = t.call_median;
    const double speedup = (b == 1 && cpu_median > 0.0) ? cpu_median / t.call_median : 0.0;
    // Kernel time and speed-up exist only for the CUDA rows: "-" in the table, empty in the CSV.
    char device_ms[32] = "", speedup_text[32] = "";
    if (b == 1) {
      std::snprintf(device_ms, sizeof device_ms, "%.5f", t.device_median);
      if (speedup > 0.0) std::snprintf(speedup_text, sizeof speedup_text, "%.3f", speedup);
    }
    std::printf("%-10s %-8s %-7s %7u %7u %12.4f %12.4f %12s %9s\n", point.series, gridName(kind),
                voter->name().c_str(), point.matches, point.hypotheses, t.call_median, t.call_p90,
                b == 1 ? device_ms : "-", b == 1 ? speedup_text : "-");
    csv.row("%s,%s,%s,%s,%u,%u,%d,%.5f,%.5f,%.5f,%s,%u,%d,%s,%s", point.series, gridName(kind),
            voter->name().c_str(), csvField(b == 0 ? voters.cpu_name : voters.gpu_name).c_str(), point.matches,
            point.hypotheses, o.runs, t.call_median, t.call_p10, t.call_p90, device_ms, t.accepted, t.winner_votes,
            speedup_text, csvField(source).c_str());
  }
  return failures;
}

int runBench(const BenchOptions& o) {
  std::string source = "synthetic";
  BearingFrame base;
  if (!o.file.empty()) base = baseFrame(o, &source);
  auto framesWith = [&](uint32_t matches) {
    if (!o.file.empty()) return resampleFrame(base, matches, 7);
    SyntheticOptions options;  // 30 % outliers, pure rotation
    options.matches = matches;
    return makeSyntheticFrame(options, 42);
  };

  Voters voters;
  voters.cpu = createCpuVoter();
  voters.cpu_name = cpuModel();
  std::string why;
  if (o.want_cuda) {
    voters.gpu = openCudaVoter(kTool, o.tool.device, "timing the CPU gold voter only; no CUDA figures were measured", &why);
    if (voters.gpu) voters.gpu_name = cudaVoterStats(*voters.gpu).device_name;
  }
  std::printf("%s: bearings from %s; %d runs (median) after %d warm-up runs\n", kTool, source.c_str(), o.runs,
              o.warmup);
  CsvWriter csv(o.tool.csv_path, "series,grid,backend,device,matches,hypotheses,runs,call_ms_median,call_ms_p10,"
                                 "call_ms_p90,device_ms_median,accepted,winner_votes,speedup_vs_cpu,source");
  std::printf("%-10s %-8s %-7s %7s %7s %12s %12s %12s %9s\n", "series", "grid", "backend", "matches", "hyps",
              "call_ms_med", "call_ms_p90", "kernel_ms", "speedup");
  int failures = 0;
  for (const Point& point : benchPoints(o.quick)) {
    const BearingFrame frame = framesWith(point.matches);
    for (GridKind kind : {GridKind::kYaw, GridKind::kRotation})
      if (kind == GridKind::kYaw ? o.want_yaw : o.want_rotation)
        failures += benchPoint(point, kind, frame, o, voters, source, csv);
  }
  if (csv) std::printf("%s: wrote %s\n", kTool, o.tool.csv_path.c_str());
  if (voters.gpu) {
    const CudaVoterStats s = cudaVoterStats(*voters.gpu);
    std::printf("%s: GPU %s; %llu buffer reallocations after construction (growing to the largest frame)\n", kTool,
                voters.gpu_name.c_str(), static_cast<unsigned long long>(s.reallocations));
  } else if (o.want_cuda) {
    std::printf("%s: CUDA rows skipped: %s\n", kTool, why.c_str());
  }
  return failures > 0 ? 1 : 0;
}

}  // namespace

int main(int argc, char** argv) {
  return cli::runCommand(kTool, kUsage, [&]() {
    BenchOptions options;
    if (!parseOptions(argc, argv, &options)) return 0;
    return runBench(options);
  });
}
