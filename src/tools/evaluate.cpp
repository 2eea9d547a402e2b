// evaluate: runs the front end once per frame pair of a KITTI- or EuRoC-layout sequence, then every
// requested rotation estimator on exactly the same matches, and compares them with the ground
// truth (poses, or the EuRoC gyro, aligned with the first method's estimates: its bias and clock
// offset removed). Prints a readable summary per method and, last, one JSON line
// per method (the last line of the output is the last method's JSON object). The work itself is in
// the eval library (src/eval/); this file is the command line.
//
// Exit status: 0 done, 1 data problem (missing folder, unreadable image), 2 bad command line.

#include <algorithm>
#include <cstdlib>
#include <iostream>
#include <memory>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "command_line.h"
#include "comparison_front_ends.h"
#include "frame_pairs.h"
#include "method_evaluation.h"
#include "method_runners.h"
#include "timing_sweep.h"
#include "visual_gyro/sequence.h"
#include "visual_gyro/visual_gyro.h"

namespace visual_gyro {
namespace {

using cli::UsageError;
using eval::DataError;

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
    "  --moving-region F      move the fraction F of the matches (those furthest right) as one\n"
    "                         independent object, turned by --moving-deg D a pair (default 0.5)\n"
    "  --max-matches N        use at most N matches per pair (a deterministic random subset)\n"
    "  --gain-jitter F        degrade every image as it is read: grey levels times 1 + u, u drawn\n"
    "                         per image uniformly in [-F, F], 0 <= F <= 0.9 (an automatic\n"
    "                         exposure stepping between frames), then\n"
    "  --contrast F           grey levels scaled about the image mean by F (dimmer footage:\n"
    "                         F < 1), then\n"
    "  --noise SIGMA          Gaussian pixel noise [grey levels] added, then\n"
    "  --stuck-pixels N       N pixels stuck at white, at the same places in every image (a\n"
    "                         sensor's hot pixels), then\n"
    "  --jpeg Q               a JPEG round trip at quality Q, 1..100 (as render_sequence's)\n"
    "  --scale F              downscale every image by F, 0 < F <= 1, as it is read (area\n"
    "                         interpolation, before the degradations; the camera's fx, fy, cx, cy\n"
    "                         follow, the distortion stays): the footage of a lower-resolution camera\n"
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
    "  --raw-gyro             score against a gyro reference as recorded (bias and clock offset\n"
    "                         not removed; by default both are estimated from the first method)\n"
    "  --quiet                summary and JSON only (no progress)\n"
    "  --list-methods         print the methods this build has, comma-separated, and exit\n"
    "  --list-ablations       print the vote method's ablations (vote-without-<part>: the vote\n"
    "                         method with one part off), comma-separated, and exit\n"
    "  --list-backends        print the backends that work here (cpu[,cuda]; why not cuda on stderr)\n"
    "  --settings-table       print every setting as Markdown, one table per tier (user, expert, paper-only)\n";

struct Options {
  std::string folder;
  std::vector<std::string> methods{"vote"};
  std::string csv;
  std::string export_bearings;
  std::vector<std::string> sets;  ///< key=value, in order
  int hypotheses = -1;
  double scale = 1.0;
  bool has_seed = false;
  uint64_t seed = 1;
  std::string backend;
  eval::FramePairOptions pairs;
  eval::TimingSweepOptions sweep;
  bool raw_gyro = false;
};

// The options that only print something (the usage, the lists, the settings table): true when
// `args` holds one of them and it was printed.
bool printedInformation(cli::Arguments& args) {
  const auto commaList = [](const std::vector<std::string>& names) {
    std::string list;
    for (const auto& m : names) list += (list.empty() ? "" : ",") + m;
    return list;
  };
  if (args.is("-h") || args.is("--help")) {
    std::cout << kUsage;
  } else if (args.is("--list-methods")) {
    std::cout << commaList(eval::methodNames()) << "\n";
  } else if (args.is("--list-ablations")) {
    std::cout << commaList(eval::ablationMethodNames()) << "\n";
  } else if (args.is("--settings-table")) {
    std::cout << settingsMarkdownTable();
  } else if (args.is("--list-backends")) {
    std::string why;
    const bool cuda = cudaBackendUsable(&why);
    if (!cuda) std::cerr << "evaluate: no CUDA backend: " << why << std::endl;
    std::cout << (cuda ? "cpu,cuda" : "cpu") << std::endl;
  } else {
    return false;
  }
  return true;
}

Options parseOptions(int argc, char** argv) {
  Options o;
  bool have_folder = false;
  bool moving_deg_given = false;
  for (cli::Arguments args(argc, argv); args.next();) {
    if (printedInformation(args)) {
      std::exit(0);
    } else if (args.is("--method") || args.is("--methods")) {
      o.methods = args.listValue();
    } else if (args.is("--csv")) {
      o.csv = args.value();
    } else if (args.is("--frames")) {
      o.pairs.frames = args.intValue(1, 1000000000);
    } else if (args.is("--stride")) {
      o.pairs.stride = static_cast<int>(args.intValue(1, 1000));
    } else if (args.is("--hypotheses")) {
      o.hypotheses = static_cast<int>(args.intValue(1, 10000000));
    } else if (args.is("--seed")) {
      o.seed = static_cast<uint64_t>(args.intValue(0, 2147483647));
      o.has_seed = true;
    } else if (args.is("--backend")) {
      o.backend = args.value();
      BackendChoice choice;
      if (!parseBackendChoice(o.backend, &choice))
        throw UsageError("--backend must be auto, cpu or cuda, not '" + o.backend + "'");
    } else if (args.is("--outliers")) {
      o.pairs.outliers = args.doubleValue(0.0, 1.0);
    } else if (args.is("--moving-region")) {
      o.pairs.moving_region = args.doubleValue(0.0, 1.0);
    } else if (args.is("--moving-deg")) {
      o.pairs.moving_deg = args.doubleValue(-90.0, 90.0);
      moving_deg_given = true;
    } else if (args.is("--gain-jitter")) {
      o.pairs.degradation.gain_jitter = args.doubleValue(0.0, 0.9);
    } else if (args.is("--contrast")) {
      o.pairs.degradation.contrast = args.doubleValue(1e-3, 100.0);
    } else if (args.is("--noise")) {
      o.pairs.degradation.noise_sigma = args.doubleValue(0.0, 255.0);
    } else if (args.is("--stuck-pixels")) {
      o.pairs.degradation.stuck_pixels = static_cast<int>(args.intValue(0, 100000));
    } else if (args.is("--jpeg")) {
      o.pairs.degradation.jpeg_quality = static_cast<int>(args.intValue(1, 100));
    } else if (args.is("--scale")) {
      o.scale = args.doubleValue(0.0, 1.0);
      if (!(o.scale > 0.0)) throw UsageError("--scale must be above 0");
    } else if (args.is("--max-matches")) {
      o.pairs.max_matches = static_cast<int>(args.intValue(1, 100000000));
    } else if (args.is("--export-bearings")) {
      o.export_bearings = args.value();
    } else if (args.is("--set")) {
      o.sets.push_back(args.value());
    } else if (args.is("--front-end")) {
      o.pairs.front_end = args.value();
      const auto& others = eval::comparisonFrontEndNames();
      if (o.pairs.front_end != "native" &&
          std::find(others.begin(), others.end(), o.pairs.front_end) == others.end()) {
        throw UsageError("--front-end must be native, orb or klt, not '" + o.pairs.front_end + "'");
      }
    } else if (args.is("--timing-sweep")) {
      o.sweep.csv_path = args.value();
    } else if (args.is("--sweep-hypotheses")) {
      o.sweep.hypotheses = args.intListValue(1, 10000000);
    } else if (args.is("--sweep-matches")) {
      o.sweep.matches = args.intListValue(8, 100000000);
    } else if (args.is("--sweep-at-matches")) {
      o.sweep.at_matches = static_cast<int>(args.intValue(8, 1000000));
    } else if (args.is("--sweep-at-hypotheses")) {
      o.sweep.at_hypotheses = static_cast<int>(args.intValue(1, 10000000));
    } else if (args.is("--sweep-repeats")) {
      o.sweep.repeats = static_cast<int>(args.intValue(1, 1000));
    } else if (args.is("--quiet")) {
      o.pairs.quiet = true;
    } else if (args.is("--raw-gyro")) {
      o.raw_gyro = true;
    } else if (args.isOption() || have_folder) {
      args.unexpected();
    } else {
      o.folder = args.current();
      have_folder = true;
    }
  }
  if (!have_folder) throw UsageError("no sequence folder given");
  if (moving_deg_given && !(o.pairs.moving_region > 0.0)) throw UsageError("--moving-deg needs --moving-region");
  for (const auto& m : o.methods) {
    const std::string problem = eval::methodProblem(m);
    if (!problem.empty()) throw UsageError(problem);
  }
  return o;
}

/// The pipeline settings: defaults, then every --set in order (names as in the settings table,
/// optionally prefixed with "front_end." or "estimator."), then the dedicated options.
VisualGyroSettings settingsFrom(const Options& o) {
  VisualGyroSettings settings;
  for (const std::string& assignment : o.sets) {
    const size_t eq = assignment.find('=');
    if (eq == std::string::npos || eq == 0) throw UsageError("--set expects key=value, got '" + assignment + "'");
    std::string key = assignment.substr(0, eq);
    for (const char* prefix : {"front_end.", "estimator."})
      if (key.rfind(prefix, 0) == 0) key = key.substr(std::string(prefix).size());
    const std::string problem = applySetting(&settings, key, assignment.substr(eq + 1));
    if (!problem.empty()) throw UsageError("--set " + problem);
  }
  if (o.hypotheses > 0) settings.estimator.hypotheses = o.hypotheses;
  if (o.has_seed) settings.estimator.seed = o.seed;
  if (!o.backend.empty()) parseBackendChoice(o.backend, &settings.estimator.backend);
  const std::string problem = validateVisualGyroSettings(settings);
  if (!problem.empty()) throw UsageError("settings: " + problem);
  settings.run_estimator = false;  // the methods run below, all on the same matches
  return settings;
}

Sequence loadUsableSequence(const std::string& folder, double scale) {
  Sequence seq;
  try {
    seq = loadSequence(folder);
    if (scale != 1.0) scaleSequence(&seq, scale);
  } catch (const std::exception& e) {
    throw DataError(e.what());
  }
  if (seq.image_paths.size() < 2) throw DataError(folder + ": fewer than two images");
  if (seq.stamps.size() != seq.image_paths.size()) throw DataError(folder + ": stamps and images differ in number");
  std::string problem = seq.camera.validate();
  if (!problem.empty()) throw DataError(folder + ": camera model: " + problem);
  problem = calibrationProblem(seq.camera);
  if (!problem.empty()) throw DataError(folder + ": implausible calibration: " + problem);
  return seq;
}

int run(int argc, char** argv) {
  Options o = parseOptions(argc, argv);
  // One thread: the figures compare front ends and estimators per thread. OpenCV would otherwise
  // spread some of its functions (ORB, brute-force matching, optical flow) over every core.
  cv::setNumThreads(1);
  const VisualGyroSettings settings = settingsFrom(o);
  const Sequence seq = loadUsableSequence(o.folder, o.scale);

  o.pairs.seed = o.has_seed ? o.seed : settings.estimator.seed;
  std::vector<eval::FramePair> pairs;
  try {
    pairs = eval::collectFramePairs(seq, settings, o.pairs);
  } catch (const std::invalid_argument& e) {
    throw DataError(e.what());
  }
  if (pairs.empty()) throw DataError(o.folder + ": no frame pairs to evaluate");
  if (!o.export_bearings.empty()) eval::exportBearings(pairs, o.export_bearings);

  eval::BaselineSettings base;
  base.threshold_rad = 1.0 / seq.camera.fx();  // 1 px-equivalent
  base.seed = settings.estimator.seed;

  // The estimators' covariance model follows the front end's positions.
  const bool refined_positions = eval::refinesPositions(o.pairs.front_end, settings);
  if (!o.sweep.csv_path.empty()) {
    o.sweep.methods = o.methods;
    o.sweep.seed = o.pairs.seed;
    o.sweep.refined_positions = refined_positions;
    o.sweep.match_footprint = matchFootprint(seq.camera);
    eval::timingSweep(seq.name, 1.0 / seq.camera.fx(), o.sweep, settings, base, pairs);
    return 0;
  }

  std::vector<eval::MethodSummary> summaries;
  for (const std::string& method : o.methods) {
    const std::unique_ptr<eval::MethodRunner> runner =
        eval::makeRunner(method, settings, base, refined_positions, matchFootprint(seq.camera), 1.0 / seq.camera.fx());
    summaries.push_back(eval::evaluateMethod(method, runner.get(), pairs));
    summaries.back().front_end = o.pairs.front_end;
    if (o.pairs.front_end == "native") summaries.back().matching = settings.front_end.matching;
  }
  // A gyro reads its bias and runs on its own clock: both are removed before it judges anything.
  ImuAlignment gyro_alignment;
  bool gyro_aligned = false;
  if (seq.truth == "gyro" && !o.raw_gyro) {
    try {
      gyro_alignment = eval::alignGyroTruth(seq, 0, &pairs, &summaries);
      gyro_aligned = true;
    } catch (const ImuAlignmentError& e) {
      std::cerr << "evaluate: the gyro reference is scored as recorded (bias included): it could not be aligned: "
                << e.what() << std::endl;
    }
  }
  if (!o.csv.empty()) eval::writeFrameCsv(o.csv, summaries);
  std::cerr.flush();
  eval::RunDescription description;
  description.dataset = seq.name;
  description.layout = seq.layout;
  description.truth = seq.truth;
  description.outliers = o.pairs.outliers;
  description.moving_region = o.pairs.moving_region;
  description.moving_deg = o.pairs.moving_region > 0.0 ? o.pairs.moving_deg : 0.0;
  description.degradation = o.pairs.degradation;
  description.scale = seq.image_scale;
  description.stride = o.pairs.stride;
  description.hypotheses = settings.estimator.hypotheses;
  description.gyro_alignment = gyro_aligned ? &gyro_alignment : nullptr;
  for (const auto& s : summaries) std::cout << eval::summaryText(description, s);
  for (const auto& s : summaries) std::cout << eval::summaryJson(description, s) << "\n";
  std::cout.flush();
  return 0;
}

}  // namespace
}  // namespace visual_gyro

int main(int argc, char** argv) {
  return visual_gyro::cli::runCommand("evaluate", visual_gyro::kUsage,
                                      [&] { return visual_gyro::run(argc, argv); });
}
