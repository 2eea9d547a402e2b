#include "timing_sweep.h"

#include <algorithm>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <limits>
#include <memory>

#include "method_runners.h"
#include "visual_gyro/random.h"

namespace visual_gyro {
namespace eval {
namespace {

/// Brings a pair to exactly `matches` matches: a random subset when it has more, else all of its
/// matches plus copies of random ones, each bearing turned by a random angle of about `jitter_rad`
/// (so no two are identical). Returns the fraction of real matches.
double resampleForTiming(int matches, uint64_t seed, double jitter_rad, FramePair* p) {
  const size_t n = p->previous.size();
  if (n >= static_cast<size_t>(matches)) {
    subsampleMatches(matches, seed, p);
    return 1.0;
  }
  SplitMix64 rng(seed * 0x2545F4914F6CDD1Dull + p->index);
  auto jitter = [&](const Eigen::Vector3d& b) {
    const Eigen::Vector3d noise(rng.normal(), rng.normal(), rng.normal());
    return Eigen::Vector3d(b + jitter_rad * noise).normalized();
  };
  while (p->previous.size() < static_cast<size_t>(matches)) {
    const size_t i = rng.below(n);
    p->previous.push_back(jitter(p->previous[i]));
    p->current.push_back(jitter(p->current[i]));
  }
  return static_cast<double>(n) / matches;
}

}  // namespace

void timingSweep(const std::string& dataset, double pixel_angle, const TimingSweepOptions& o,
                 const VisualGyroSettings& settings, const BaselineSettings& baseline,
                 const std::vector<FramePair>& pairs) {
  struct Point {
    const char* series;
    int hypotheses;  // 0: the method's own (baselines)
    int matches;
  };
  std::ofstream f(o.csv_path);
  if (!f) throw DataError("cannot write " + o.csv_path);
  f << "source,dataset,series,method,backend,hypotheses,matches,pairs,real_fraction,ms_mean,ms_median,ms_min,"
       "vote_ms_mean,vote_device_ms_mean,refine_ms_mean\n";
  std::cout << "timing sweep on " << dataset << " (" << pairs.size() << " pairs; per pair the fastest of "
            << o.repeats << " runs)\n";
  std::printf("%-10s %-22s %-6s %10s %8s %6s %6s %10s %10s\n", "series", "method", "backend", "hypotheses",
              "matches", "pairs", "real", "ms_mean", "ms_median");
  const double jitter_rad = 0.5 * pixel_angle;  // half a pixel
  for (const std::string& method : o.methods) {
    const bool own = isOwnMethod(method);
    std::vector<Point> points;
    if (own) {
      for (int h : o.hypotheses) points.push_back({"hypotheses", h, o.at_matches});
    } else {
      points.push_back({"hypotheses", 0, o.at_matches});
    }
    for (int m : o.matches) points.push_back({"matches", own ? o.at_hypotheses : 0, m});
    for (const Point& point : points) {
      VisualGyroSettings s = settings;
      if (point.hypotheses > 0) s.estimator.hypotheses = point.hypotheses;
      std::unique_ptr<MethodRunner> runner =
          makeRunner(method, s, baseline, o.refined_positions, o.match_footprint, pixel_angle);
      std::vector<double> ms;
      double real = 0.0, vote = 0.0, vote_device = 0.0, refine = 0.0;
      for (const FramePair& p0 : pairs) {
        if (p0.previous.size() < 8) continue;
        FramePair p = p0;
        real += resampleForTiming(point.matches, o.seed, jitter_rad, &p);
        // The fastest of a few runs: the machine is shared, the minimum is the estimator's own cost.
        MethodEstimate best;
        best.estimate_ms = std::numeric_limits<double>::infinity();
        for (int rep = 0; rep < o.repeats; ++rep) {
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
      f << "evaluate," << dataset << ',' << point.series << ',' << method << ',' << backendName(runner->backend()) << ','
        << point.hypotheses << ',' << point.matches << ',' << ms.size() << ',' << real << ',' << mean << ','
        << median << ',' << sorted.front() << ',' << meanOrEmpty(vote) << ',' << meanOrEmpty(vote_device) << ','
        << meanOrEmpty(refine) << '\n';
      std::printf("%-10s %-22s %-6s %10d %8d %6zu %6.2f %10.3f %10.3f\n", point.series, method.c_str(),
                  backendName(runner->backend()), point.hypotheses, point.matches, ms.size(), real, mean, median);
      std::fflush(stdout);
    }
  }
  if (!f) throw DataError("cannot write " + o.csv_path);
}

}  // namespace eval
}  // namespace visual_gyro
