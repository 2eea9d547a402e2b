// cuda_voter_check: CPU gold voter versus CUDA voter, bin for bin and hypothesis by hypothesis, on
// bearing files and on synthetic frames (see cuda/README.md for the rule and the file format).
// Without a working CUDA device the GPU part is skipped (said loudly) and the CPU gold voter still
// runs, so the tool is useful on any machine. Exit status: 0 all compared frames passed,
// 1 a comparison failed or an input was bad, 2 a bad command line, 3 --require-gpu given but no
// device works.
#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <string>
#include <vector>

#include "standalone/check_common.h"
#include "standalone/voter_compare.h"

using namespace visual_gyro;
using namespace visual_gyro::bearings;

namespace {

const char* const kTool = "cuda_voter_check";

const char* const kUsage =
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
    "  --require-gpu            exit 3 when no CUDA device works (default: skip the GPU part)\n"
    "  --edge-margin R          bin-edge margin of the rule [rad] (default 1e-4)\n"
    "  --max-explained-fraction F  hypotheses that may change cell for explained reasons (default 1e-2)\n"
    "  --csv PATH               one row per frame and grid\n"
    "  --write-synthetic PATH   write the synthetic frames as a bearing file\n";

struct CheckOptions {
  ToolOptions tool;
  long long synthetic = -1;  ///< synthetic frames; -1: 8 when no file is given
  uint32_t matches = 2000, hypotheses = 10000;
  uint64_t seed = 1;
  CompareOptions compare;
  std::string write_path;
};

/// One input (a file or the synthetic set); synthetic frames also carry their true (yaw, pitch, roll).
struct Input {
  BearingInput bearings;
  std::vector<std::array<double, 3>> truth;
};

/// Totals of one input on one grid.
struct Totals {
  uint64_t frames = 0, compared = 0, passed = 0, failed = 0, skipped = 0;
  uint64_t hypotheses = 0, mismatched = 0, near_edge = 0, near_threshold = 0, ill_conditioned = 0, unexplained = 0;
  uint64_t winners_equal = 0, accepted = 0;
  double max_value_difference = 0.0, max_scaled_difference = 0.0, cpu_ms = 0.0, gpu_ms = 0.0, gpu_device_ms = 0.0;
};

/// What one frame on one grid gave.
struct FrameCheck {
  VoteResult cpu;
  CompareReport report;
  bool compared = false;
  double cpu_ms = 0.0, gpu_ms = 0.0, device_ms = 0.0;
};

/// Counters of the whole run.
struct RunTotals {
  uint64_t passed = 0, failed = 0, skipped = 0;
  uint64_t truth_hits = 0, truth_frames = 0;  ///< synthetic yaw winners near the true yaw
};

bool parseOptions(int argc, char** argv, CheckOptions* o) {
  const unsigned shared = kOptionFiles | kOptionMaxFrames | kOptionDevice | kOptionRequireGpu | kOptionCsv;
  const long long kMax = std::numeric_limits<long long>::max();
  const bool run = parseToolArguments(argc, argv, kUsage, shared, &o->tool, [&](cli::Arguments& args) {
    if (args.is("--synthetic")) {
      o->synthetic = args.intValue(0, kMax);
    } else if (args.is("--matches")) {
      o->matches = static_cast<uint32_t>(args.intValue(3, std::numeric_limits<uint32_t>::max()));
    } else if (args.is("--hypotheses")) {
      o->hypotheses = static_cast<uint32_t>(args.intValue(0, std::numeric_limits<uint32_t>::max()));
    } else if (args.is("--seed")) {
      o->seed = static_cast<uint64_t>(args.intValue(0, kMax));
    } else if (args.is("--edge-margin")) {
      o->compare.edge_margin = args.doubleValue(0.0, 1.0);
    } else if (args.is("--max-explained-fraction")) {
      o->compare.max_explained_fraction = args.doubleValue(0.0, 1.0);
    } else if (args.is("--write-synthetic")) {
      o->write_path = args.value();
    } else {
      return false;
    }
    return true;
  });
  if (o->synthetic < 0) o->synthetic = o->tool.files.empty() ? 8 : 0;
  return run;
}

/// The files, then the synthetic frames (pure rotation and forward driving alternating, as in the
/// shared sequences), written to o.write_path when given.
std::vector<Input> loadInputs(const CheckOptions& o) {
  std::vector<Input> inputs;
  for (BearingInput& file : readBearingInputs(o.tool)) inputs.push_back({std::move(file), {}});
  if (o.synthetic <= 0) return inputs;
  Input synthetic{{"synthetic", {}}, {}};
  SyntheticOptions options;
  options.matches = o.matches;
  for (long long f = 0; f < o.synthetic; ++f) {
    options.forward_translation = (f % 2) ? 1.0 : 0.0;
    std::array<double, 3> ypr;
    synthetic.bearings.frames.push_back(
        makeSyntheticFrame(options, o.seed * 1000003ull + static_cast<uint64_t>(f), f, ypr.data()));
    synthetic.truth.push_back(ypr);
  }
  if (!o.write_path.empty()) {
    writeBearingFile(o.write_path, synthetic.bearings.frames);
    std::printf("%s: wrote %lld synthetic frames to %s\n", kTool, o.synthetic, o.write_path.c_str());
  }
  inputs.push_back(std::move(synthetic));
  return inputs;
}

/// Votes `q` on the CPU and, when there is one, on the GPU (with and without records), and compares.
FrameCheck checkFrame(HypothesisVoter& cpu, HypothesisVoter* gpu, const VoteRequest& q, const CompareOptions& compare) {
  FrameCheck check;
  auto start = std::chrono::steady_clock::now();
  cpu.vote(q, &check.cpu);
  check.cpu_ms = msSince(start);
  check.report.hypotheses = q.hypotheses;
  check.report.cpu_winner = check.cpu.winner;
  if (gpu == nullptr) return check;
  check.compared = true;
  try {
    VoteResult g;
    start = std::chrono::steady_clock::now();
    gpu->vote(q, &g);
    check.gpu_ms = msSince(start);
    check.device_ms = g.device_ms;
    check.report = compareVotes(q, check.cpu, g, compare);
    // The record-free path (what the estimator runs) must vote identically.
    VoteRequest lean = q;
    lean.keep_records = false;
    VoteResult g2;
    gpu->vote(lean, &g2);
    if (g2.histogram != g.histogram || g2.winner != g.winner || g2.accepted != g.accepted)
      check.report.problems.push_back("GPU without records votes differently from GPU with records");
  } catch (const std::exception& e) {
    check.report.problems.push_back(std::string("GPU vote threw: ") + e.what());
  }
  return check;
}

void addTo(Totals* t, const FrameCheck& c) {
  t->cpu_ms += c.cpu_ms;
  t->accepted += c.cpu.accepted;
  t->hypotheses += c.report.hypotheses;
  if (!c.compared) {
    ++t->skipped;
    return;
  }
  const CompareReport& r = c.report;
  ++t->compared;
  t->gpu_ms += c.gpu_ms;
  t->gpu_device_ms += c.device_ms;
  t->mismatched += r.mismatched;
  t->near_edge += r.near_edge;
  t->near_threshold += r.near_threshold;
  t->ill_conditioned += r.ill_conditioned;
  t->unexplained += r.unexplained;
  t->max_value_difference = std::max(t->max_value_difference, r.max_value_difference);
  t->max_scaled_difference = std::max(t->max_scaled_difference, r.max_scaled_difference);
  if (r.winnersEqual()) ++t->winners_equal;
  r.passed() ? ++t->passed : ++t->failed;
}

void printTotals(const std::string& input, GridKind kind, const Totals& t) {
  const double frames = std::max<double>(1.0, static_cast<double>(t.frames));
  std::printf("[%s] %s grid: %llu frames, %llu hypotheses, CPU gold %.3f ms/frame, %.0f accepted/frame\n",
              input.c_str(), gridName(kind), static_cast<unsigned long long>(t.frames),
              static_cast<unsigned long long>(t.hypotheses), t.cpu_ms / frames, t.accepted / frames);
  if (t.compared == 0) {
    std::printf("  GPU comparison skipped (%llu frames)\n", static_cast<unsigned long long>(t.skipped));
    return;
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
              t.max_value_difference, t.max_scaled_difference, static_cast<unsigned long long>(t.winners_equal),
              static_cast<unsigned long long>(t.compared), static_cast<unsigned long long>(t.passed),
              static_cast<unsigned long long>(t.failed));
}

/// Checks every frame of `input` on both grids: the frames' rows to `csv`, failures printed, then
/// the input's totals per grid. Frame f of the whole run uses seed o.seed + f, as the estimator does.
void checkInput(const Input& input, const CheckOptions& o, HypothesisVoter& cpu, HypothesisVoter* gpu,
                CsvWriter& csv, uint64_t* run_frame, RunTotals* run) {
  std::map<GridKind, Totals> totals;
  const std::string& name = input.bearings.name;
  for (size_t fi = 0; fi < input.bearings.frames.size(); ++fi) {
    const BearingFrame& frame = input.bearings.frames[fi];
    const uint32_t n = static_cast<uint32_t>(frame.prev.size());
    const uint64_t frame_seed = o.seed + (*run_frame)++;
    for (GridKind kind : {GridKind::kYaw, GridKind::kRotation}) {
      Totals& t = totals[kind];
      ++t.frames;
      if (n < 3) {
        ++t.skipped;
        ++run->skipped;
        continue;
      }
      VoteRequest q = makeRequest(kind, frame.prev.data(), frame.cur.data(), n, o.hypotheses, frame_seed);
      q.keep_records = true;
      const FrameCheck c = checkFrame(cpu, gpu, q, o.compare);
      addTo(&t, c);
      if (kind == GridKind::kYaw && fi < input.truth.size() && c.cpu.winner >= 0) {
        const double yaw = c.cpu.cell_sums[3 * c.cpu.winner] / c.cpu.histogram[c.cpu.winner];
        ++run->truth_frames;
        if (std::fabs(yaw - input.truth[fi][0]) < 0.2 * kRadPerDeg) ++run->truth_hits;
      }
      const char* status = !c.compared ? "skipped" : c.report.passed() ? "passed" : "failed";
      if (!c.compared) {
        ++run->skipped;
      } else if (c.report.passed()) {
        ++run->passed;
      } else {
        ++run->failed;
        std::printf("FAILED %s frame %lld %s grid:", name.c_str(), static_cast<long long>(frame.index), gridName(kind));
        for (const std::string& p : c.report.problems) std::printf(" [%s]", p.c_str());
        std::printf("\n");
      }
      csv.row("%s,%lld,%s,%u,%u,%s,%.3g,%.3g,%.4f,%.4f,%.4f,%s", csvField(name).c_str(),
              static_cast<long long>(frame.index), gridName(kind), n, c.cpu.accepted,
              cellDifferencesCsv(c.report).c_str(), c.report.max_value_difference, c.report.max_scaled_difference,
              c.cpu_ms, c.gpu_ms, c.device_ms, status);
    }
  }
  for (const auto& entry : totals) printTotals(name, entry.first, entry.second);
}

int runCheck(const CheckOptions& o) {
  std::string why;
  std::unique_ptr<HypothesisVoter> gpu =
      openCudaVoter(kTool, o.tool.device, "running the CPU gold voter only; no CPU/GPU comparison was made", &why);
  if (!gpu && o.tool.require_gpu) {
    std::fprintf(stderr, "%s: --require-gpu given but no CUDA device works\n", kTool);
    return kExitNoGpu;
  }
  std::unique_ptr<HypothesisVoter> cpu = createCpuVoter();
  const std::vector<Input> inputs = loadInputs(o);
  CsvWriter csv(o.tool.csv_path, "input,frame,grid,matches,cpu_accepted," + cellDifferencesCsvHeader() +
                                     ",max_value_diff_rad,max_scaled_diff_rad,cpu_ms,gpu_call_ms,gpu_device_ms,status");
  RunTotals run;
  uint64_t run_frame = 0;
  for (const Input& input : inputs) checkInput(input, o, *cpu, gpu.get(), csv, &run_frame, &run);

  if (run.truth_frames > 0)
    std::printf("CPU gold sanity: synthetic yaw winner within 0.2 deg of the true yaw in %llu/%llu frames\n",
                static_cast<unsigned long long>(run.truth_hits), static_cast<unsigned long long>(run.truth_frames));
  std::printf("rule: %s\n", describeRule(o.compare).c_str());
  if (gpu) {
    const CudaVoterStats s = cudaVoterStats(*gpu);
    std::printf("CUDA voter: %llu frames, %llu buffer reallocations after construction, %.1f MiB device memory\n",
                static_cast<unsigned long long>(s.frames), static_cast<unsigned long long>(s.reallocations),
                s.device_bytes / 1048576.0);
  }
  std::printf("%llu passed, %llu failed, %llu skipped%s\n", static_cast<unsigned long long>(run.passed),
              static_cast<unsigned long long>(run.failed), static_cast<unsigned long long>(run.skipped),
              gpu ? "" : " (GPU part skipped: no usable CUDA device)");
  return run.failed > 0 ? 1 : 0;
}

}  // namespace

int main(int argc, char** argv) {
  return cli::runCommand(kTool, kUsage, [&]() {
    CheckOptions options;
    if (!parseOptions(argc, argv, &options)) return 0;
    return runCheck(options);
  });
}
