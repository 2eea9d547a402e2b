// Bin-for-bin comparison of two voters' results for the same VoteRequest (CPU gold vs CUDA).
// Header-only, plain C++ (used by cuda_voter_check and by test/test_cuda_voter.cpp).
//
// Why results may differ at all: host and device evaluate the same float expressions, but nvcc
// contracts a * b + c into fused multiply-adds (one rounding instead of two) while g++ without
// -march does not, and atan2f/asinf come from different math libraries. A hypothesis's voted value
// therefore differs by about 1e-7..1e-5 rad between CPU and GPU; it lands in another cell only when
// it lies that close to a bin edge, and a degeneracy test flips only when its quantity lies that
// close to the threshold. Ill-conditioned triples amplify the rounding by about sv0 / sv1, the
// ratio of the two largest singular values of Arun's H (outlier triples mostly: the yaw grid with
// centroid subtraction accepts some with sv1 / sv0 down to 1e-5, whose values then differ by up to
// ~1e-2 rad). The rule (see cuda/README.md):
//   - voted values of hypotheses both sides solved agree within value_scale / (sv1 / sv0);
//   - every hypothesis whose cell differs must be explained: a value within edge_margin of a bin
//     edge (window bounds included), or a tolerated value difference that straddles an edge, or a
//     degeneracy test of its triple within threshold_margin (relative) of its threshold;
//   - such hypotheses are at most max_mismatch_fraction of all;
//   - the GPU's histogram, counters and winner are exactly those implied by its own records, and its
//     cell sums agree with its records' sums up to float summation order;
//   - sum over cells |hist_gpu - hist_cpu| <= 2 * (mismatched hypotheses).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <sstream>
#include <string>
#include <vector>

#include "hypothesis_voter.h"

namespace visual_gyro {
namespace bearings {

/// Tolerances of compareVotes (radians unless stated).
struct CompareOptions {
  double edge_margin = 1e-4;             ///< "at a bin edge": closer than this to one
  double threshold_margin = 1e-4;        ///< "at a threshold": relative distance below this
  /// Values of a hypothesis solved on both sides must agree within value_scale / (sv1 / sv0), the
  /// conditioning of its H (sv0 >= sv1: the two largest singular values).
  double value_scale = 1e-5;
  double max_mismatch_fraction = 1e-3;   ///< of all hypotheses, may sit in different cells
};

/// What compareVotes found.
struct CompareReport {
  uint64_t hypotheses = 0;
  uint64_t mismatched = 0;         ///< hypotheses in different cells (or voted on one side only)
  uint64_t near_edge = 0;          ///< ... explained by a value at a bin edge
  uint64_t near_threshold = 0;     ///< ... explained by a degeneracy test at its threshold
  uint64_t ill_conditioned = 0;    ///< ... explained by a tolerated value difference across an edge
  uint64_t unexplained = 0;        ///< ... explained by neither (a bug)
  uint64_t value_differences = 0;  ///< solved on both sides, values differ beyond the tolerance
  double max_value_difference = 0.0;   ///< max |cpu - gpu| over hypotheses solved on both sides [rad]
  double max_scaled_difference = 0.0;  ///< max |cpu - gpu| * sv1 / sv0 (the rule's quantity) [rad]
  uint64_t histogram_l1 = 0;       ///< sum over cells |hist_gpu - hist_cpu|
  uint64_t cells_differing = 0;
  bool winner_equal = true;
  std::vector<std::string> problems;  ///< broken rules; empty when the comparison passed

  bool passed() const { return problems.empty(); }
  double mismatchFraction() const { return hypotheses ? static_cast<double>(mismatched) / hypotheses : 0.0; }
};

namespace detail {

inline bool solved(const hyp::HypothesisRecord& r) {
  return r.cell >= 0 || r.value[0] != 0.f || r.value[1] != 0.f || r.value[2] != 0.f;
}

/// Distance [rad] of a solved record's voted values to the nearest bin edge of the grid (window
/// bounds included).
inline double edgeDistance(const hyp::HypothesisRecord& r, const hyp::VoteGrid& g) {
  const int axes = g.kind == hyp::kVoteYaw ? 1 : 3;
  double best = 1e30;
  for (int a = 0; a < axes; ++a) {
    const double pos = (static_cast<double>(r.value[a]) - g.centre[a]) / g.bin_width + 0.5 * g.bins;
    const double edge = std::min<double>(std::max<double>(std::round(pos), 0.0), g.bins);
    best = std::min(best, std::fabs(pos - edge) * g.bin_width);
  }
  return best;
}

/// Loads hypothesis h's triple in double: p = previous-frame bearings, c = current-frame ones.
inline void loadTriple(const VoteRequest& q, uint32_t h, double p[3][3], double c[3][3]) {
  uint32_t idx[3];
  hyp::drawTriple(q.seed, h, q.matches, idx);
  for (int i = 0; i < 3; ++i) {
    const hyp::Vec3f& a = q.prev[idx[i]];
    const hyp::Vec3f& b = q.cur[idx[i]];
    p[i][0] = a.x;
    p[i][1] = a.y;
    p[i][2] = a.z;
    c[i][0] = b.x;
    c[i][1] = b.y;
    c[i][2] = b.z;
  }
}

/// sv1 / sv0 (second over largest singular value) of Arun's H for hypothesis h, in double: how
/// strongly the rotation's rounding errors are amplified (their size is about 1e-7 / ratio rad).
inline double conditionRatio(const VoteRequest& q, uint32_t h) {
  double p[3][3], c[3][3];
  loadTriple(q, h, p, c);
  if (q.triple.centroid_subtraction) {
    for (int k = 0; k < 3; ++k) {
      const double mp = (p[0][k] + p[1][k] + p[2][k]) / 3.0, mc = (c[0][k] + c[1][k] + c[2][k]) / 3.0;
      for (int i = 0; i < 3; ++i) p[i][k] -= mp, c[i][k] -= mc;
    }
  }
  double H[3][3] = {}, A[3][3] = {};
  for (int i = 0; i < 3; ++i)
    for (int r = 0; r < 3; ++r)
      for (int s = 0; s < 3; ++s) H[r][s] += c[i][r] * p[i][s];
  for (int r = 0; r < 3; ++r)
    for (int s = 0; s < 3; ++s)
      for (int k = 0; k < 3; ++k) A[r][s] += H[k][r] * H[k][s];
  // Cyclic Jacobi on the symmetric H^T H: its eigenvalues are the squared singular values.
  for (int sweep = 0; sweep < 30; ++sweep)
    for (int i = 0; i < 2; ++i)
      for (int j = i + 1; j < 3; ++j) {
        if (A[i][j] == 0.0) continue;
        const double angle = 0.5 * std::atan2(2.0 * A[i][j], A[j][j] - A[i][i]);
        const double cs = std::cos(angle), sn = std::sin(angle);
        for (int k = 0; k < 3; ++k) {
          const double x = A[k][i], y = A[k][j];
          A[k][i] = cs * x - sn * y;
          A[k][j] = sn * x + cs * y;
        }
        for (int k = 0; k < 3; ++k) {
          const double x = A[i][k], y = A[j][k];
          A[i][k] = cs * x - sn * y;
          A[j][k] = sn * x + cs * y;
        }
      }
  double e[3] = {A[0][0], A[1][1], A[2][2]};
  std::sort(e, e + 3);
  return e[2] > 0.0 ? std::sqrt(std::max(0.0, e[1]) / e[2]) : 0.0;
}

/// True when one of the triple's degeneracy tests is within `margin` (relative) of its threshold,
/// evaluated in double on the host.
inline bool nearThreshold(const VoteRequest& q, uint32_t h, double margin) {
  double p[3][3], c[3][3];
  loadTriple(q, h, p, c);
  auto dist = [](const double* a, const double* b) {
    return std::sqrt((a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) + (a[2] - b[2]) * (a[2] - b[2]));
  };
  auto area = [](const double v[3][3]) {
    double d1[3], d2[3];
    for (int k = 0; k < 3; ++k) d1[k] = v[1][k] - v[0][k], d2[k] = v[2][k] - v[0][k];
    const double x = d1[1] * d2[2] - d1[2] * d2[1], y = d1[2] * d2[0] - d1[0] * d2[2], z = d1[0] * d2[1] - d1[1] * d2[0];
    return 0.5 * std::sqrt(x * x + y * y + z * z);
  };
  auto near = [margin](double value, double threshold) {
    return std::fabs(value - threshold) <= margin * std::max(std::fabs(threshold), 1e-12);
  };
  const double lp[3] = {dist(p[0], p[1]), dist(p[0], p[2]), dist(p[1], p[2])};
  const double lc[3] = {dist(c[0], c[1]), dist(c[0], c[2]), dist(c[1], c[2])};
  const double shortest = std::min({lp[0], lp[1], lp[2], lc[0], lc[1], lc[2]});
  if (near(shortest, q.triple.min_separation)) return true;
  if (near(std::min(area(p), area(c)), q.triple.min_triangle_area)) return true;
  if (q.triple.max_angle_change > 0.f) {
    const double change = std::max({std::fabs(lp[0] - lc[0]), std::fabs(lp[1] - lc[1]), std::fabs(lp[2] - lc[2])});
    if (near(change, q.triple.max_angle_change)) return true;
  }
  if (!q.triple.centroid_subtraction) {
    // det(H) = det(P) det(Q) for H = sum p q^T: near zero, its sign (the reflection test) is rounding.
    auto det = [](const double v[3][3]) {
      return v[0][0] * (v[1][1] * v[2][2] - v[1][2] * v[2][1]) - v[0][1] * (v[1][0] * v[2][2] - v[1][2] * v[2][0]) +
             v[0][2] * (v[1][0] * v[2][1] - v[1][1] * v[2][0]);
    };
    if (std::fabs(det(p) * det(c)) <= margin * 1e-3) return true;
  }
  return false;
}

}  // namespace detail

/// Compares `gpu` against the gold `cpu` result for `request` (both computed with keep_records).
inline CompareReport compareVotes(const VoteRequest& request, const VoteResult& cpu, const VoteResult& gpu,
                                  const CompareOptions& options = CompareOptions()) {
  CompareReport report;
  report.hypotheses = request.hypotheses;
  const int32_t cells = hyp::cellCount(request.grid);
  auto problem = [&report](const std::string& text) { report.problems.push_back(text); };
  if (cpu.histogram.size() != static_cast<size_t>(cells) || gpu.histogram.size() != static_cast<size_t>(cells) ||
      gpu.cell_sums.size() != 3 * static_cast<size_t>(cells)) {
    problem("histogram or cell_sums of the wrong size");
    return report;
  }
  if (cpu.records.size() != request.hypotheses || gpu.records.size() != request.hypotheses) {
    problem("records missing (both voters need keep_records)");
    return report;
  }

  // The GPU's own consistency: its atomics, block merges and argmax must reproduce exactly what
  // its per-hypothesis records imply.
  std::vector<int32_t> rebuilt(cells, 0);
  std::vector<double> sums(3 * static_cast<size_t>(cells), 0.0), abs_sums(3 * static_cast<size_t>(cells), 0.0);
  uint32_t gpu_accepted = 0;
  for (const hyp::HypothesisRecord& r : gpu.records) {
    if (r.cell < 0) continue;
    if (r.cell >= cells) {
      problem("GPU record with cell out of range");
      return report;
    }
    ++rebuilt[r.cell];
    ++gpu_accepted;
    for (int a = 0; a < 3; ++a) {
      sums[3 * r.cell + a] += r.value[a];
      abs_sums[3 * r.cell + a] += std::fabs(r.value[a]);
    }
  }
  if (rebuilt != gpu.histogram) problem("GPU histogram differs from the histogram of its own records");
  if (gpu.accepted != gpu_accepted) problem("GPU accepted count differs from its records");
  uint64_t gpu_total = gpu.accepted;
  for (int s = 1; s < 6; ++s) gpu_total += gpu.rejected[s];
  if (gpu_total != request.hypotheses) problem("GPU accepted + rejected != hypotheses");
  int32_t argmax = -1, best = 0;
  for (int32_t c = 0; c < cells; ++c)
    if (gpu.histogram[c] > best) best = gpu.histogram[c], argmax = c;
  if (gpu.winner != argmax) problem("GPU winner is not the fullest cell (lowest index on ties)");
  size_t bad_sums = 0;
  for (size_t i = 0; i < sums.size(); ++i)
    if (std::fabs(gpu.cell_sums[i] - sums[i]) > 2e-5 * abs_sums[i] + 1e-6) ++bad_sums;
  if (bad_sums) problem(std::to_string(bad_sums) + " GPU cell sums differ from the sums of its records");

  // CPU versus GPU, hypothesis by hypothesis.
  for (uint32_t h = 0; h < request.hypotheses; ++h) {
    const hyp::HypothesisRecord& a = cpu.records[h];
    const hyp::HypothesisRecord& b = gpu.records[h];
    const bool a_solved = detail::solved(a), b_solved = detail::solved(b);
    double diff = 0.0;
    if (a_solved && b_solved) {
      for (int k = 0; k < 3; ++k) diff = std::max(diff, std::fabs(static_cast<double>(a.value[k]) - b.value[k]));
      report.max_value_difference = std::max(report.max_value_difference, diff);
      // The conditioning (a small SVD in double) is computed only for the few hypotheses that
      // differ by more than the tolerance of a perfectly conditioned one.
      if (diff > options.value_scale) {
        const double scaled = diff * detail::conditionRatio(request, h);
        report.max_scaled_difference = std::max(report.max_scaled_difference, scaled);
        if (scaled > options.value_scale) ++report.value_differences;
      } else {
        report.max_scaled_difference = std::max(report.max_scaled_difference, diff);
      }
    }
    if (a.cell == b.cell) continue;
    ++report.mismatched;
    double edge = 1e30;
    if (a_solved) edge = detail::edgeDistance(a, request.grid);
    if (b_solved) edge = std::min(edge, detail::edgeDistance(b, request.grid));
    if (edge <= options.edge_margin) {
      ++report.near_edge;
    } else if (a_solved && b_solved && edge <= diff) {
      ++report.ill_conditioned;  // an amplified (but tolerated, see above) difference crossed an edge
    } else if (a_solved != b_solved && detail::nearThreshold(request, h, options.threshold_margin)) {
      ++report.near_threshold;
    } else {
      ++report.unexplained;
    }
  }
  for (int32_t c = 0; c < cells; ++c) {
    const int64_t d = static_cast<int64_t>(gpu.histogram[c]) - cpu.histogram[c];
    if (d != 0) ++report.cells_differing;
    report.histogram_l1 += static_cast<uint64_t>(d < 0 ? -d : d);
  }
  report.winner_equal = cpu.winner == gpu.winner;

  std::ostringstream text;
  if (report.unexplained) {
    text << report.unexplained
         << " hypotheses in different cells neither at a bin edge nor at a degeneracy threshold";
    problem(text.str());
    text.str("");
  }
  if (report.value_differences) {
    text << report.value_differences << " hypotheses whose values differ by more than " << options.value_scale
         << " rad / (sv1 / sv0) (max difference * sv1 / sv0: " << report.max_scaled_difference << ")";
    problem(text.str());
    text.str("");
  }
  if (report.mismatched > options.max_mismatch_fraction * request.hypotheses) {
    text << report.mismatched << " of " << request.hypotheses << " hypotheses in different cells (more than "
         << options.max_mismatch_fraction << " of them)";
    problem(text.str());
    text.str("");
  }
  if (report.histogram_l1 > 2 * report.mismatched) problem("histograms differ by more than the moved hypotheses explain");
  const int64_t accepted_diff = static_cast<int64_t>(gpu.accepted) - cpu.accepted;
  if (static_cast<uint64_t>(accepted_diff < 0 ? -accepted_diff : accepted_diff) > report.mismatched)
    problem("accepted counts differ by more than the moved hypotheses explain");
  return report;
}

}  // namespace bearings
}  // namespace visual_gyro
