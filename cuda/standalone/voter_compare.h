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
//     degeneracy test of its triple within threshold_margin (relative) of its threshold; one
//     unexplained hypothesis fails the frame;
//   - explained ones are at most max_explained_fraction of all (judgeCellDifferences says why);
//   - the winners are equal, or the CPU's votes for its winner exceed its votes in the GPU's
//     winning cell by no more than the explained hypotheses can shift (2 votes each);
//   - the GPU's histogram, counters and winner are exactly those implied by its own records, and its
//     cell sums agree with its records' sums up to float summation order;
//   - sum over cells |hist_gpu - hist_cpu| <= 2 * (mismatched hypotheses).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <istream>
#include <sstream>
#include <stdexcept>
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
  /// Of all hypotheses, at most this fraction may sit in different cells for explained reasons
  /// (bin edge, threshold, tolerated difference); unexplained ones are not tolerated at all.
  double max_explained_fraction = 1e-2;
};

/// How the hypotheses of one frame moved between the CPU's and the GPU's cells, and the two
/// winners: what the verdict of judgeCellDifferences is made from. compareVotes measures it;
/// one row of cuda_voter_check's CSV holds it (columns kCellDifferenceColumns).
struct CellDifferences {
  uint64_t hypotheses = 0;
  uint64_t mismatched = 0;       ///< hypotheses in different cells (or voted on one side only)
  uint64_t near_edge = 0;        ///< ... explained by a value at a bin edge
  uint64_t near_threshold = 0;   ///< ... explained by a degeneracy test at its threshold
  uint64_t ill_conditioned = 0;  ///< ... explained by a tolerated value difference across an edge
  uint64_t unexplained = 0;      ///< ... explained by neither (a bug)
  int32_t cpu_winner = -1;       ///< winning cell index (-1: no votes)
  int32_t gpu_winner = -1;
  /// The CPU's votes for its winner minus its votes in the GPU's winning cell (a cell of -1 has
  /// none); -1 when unknown (CSV files written before the column existed).
  int64_t winner_margin = -1;

  uint64_t explained() const { return near_edge + near_threshold + ill_conditioned; }
};

/// The verdict on a frame's moved hypotheses and winners: the broken rules, empty when it passes.
/// The one rule of cuda_voter_check, of compareVotes and of the tests that re-score CSV files.
inline std::vector<std::string> judgeCellDifferences(const CellDifferences& d, const CompareOptions& options) {
  std::vector<std::string> problems;
  std::ostringstream text;
  auto problem = [&problems, &text]() {
    problems.push_back(text.str());
    text.str("");
  };
  if (d.explained() + d.unexplained != d.mismatched || d.mismatched > d.hypotheses) {
    text << "inconsistent counts: " << d.mismatched << " moved of " << d.hypotheses << " but " << d.explained()
         << " explained + " << d.unexplained << " unexplained";
    problem();
  }
  if (d.unexplained > 0) {
    text << d.unexplained << " hypotheses in different cells neither at a bin edge nor at a degeneracy threshold";
    problem();
  }
  // Explained moves are still bounded, loosely. Rounding (about 1e-7..1e-6 rad for well-conditioned
  // triples, at most value_scale = 1e-5 rad after scaling by the conditioning) moves a hypothesis
  // only when its value lies that close to an edge or threshold, so even when the accepted
  // hypotheses cluster on an edge they scatter over the pixel noise (~1e-4..1e-3 rad) and only a
  // small share of them can move: the worst frame measured, euroc_v101_static on the rotation grid
  // (a static camera: its inliers sit on the edges at zero), moved 0.19 % on an NVIDIA H200. Far
  // more explained moves mean the device computes cells or degeneracy tests differently (a cell
  // formula in lower precision, a threshold off by less than the margin), which each hypothesis's
  // explanation alone cannot reveal. 1 % lies five times above that worst frame.
  if (static_cast<double>(d.explained()) > options.max_explained_fraction * static_cast<double>(d.hypotheses)) {
    text << d.explained() << " of " << d.hypotheses << " hypotheses in different cells at edges or thresholds (more than "
         << options.max_explained_fraction << " of them)";
    problem();
  }
  // A move shifts two cells' counts by one each, so explained moves alone can turn the CPU's winner
  // into the GPU's only when the CPU's vote margin between the two cells is at most twice their number.
  if (d.cpu_winner != d.gpu_winner) {
    text << "winners differ (CPU cell " << d.cpu_winner << ", GPU cell " << d.gpu_winner << ")";
    if (d.unexplained > 0) {
      text << " with unexplained moves";
      problem();
    } else if (d.winner_margin < 0) {
      text << " and the CPU's vote margin between them is unknown";
      problem();
    } else if (static_cast<uint64_t>(d.winner_margin) > 2 * d.explained()) {
      text << " by a CPU margin of " << d.winner_margin << " votes, more than " << d.explained()
           << " moved hypotheses explain";
      problem();
    }
  }
  return problems;
}

/// The rule in one line, as the tools print it.
inline std::string describeRule(const CompareOptions& o) {
  std::ostringstream text;
  text << "CPU and GPU values of a hypothesis agree within " << o.value_scale
       << " rad / (sv1/sv0 of its H); a hypothesis may change cell only when a value is within " << o.edge_margin
       << " rad of a bin edge (or the tolerated difference straddles one) or a degeneracy test is within "
       << o.threshold_margin << " (relative) of its threshold, none otherwise, and such explained moves are at most "
       << o.max_explained_fraction
       << " of the hypotheses; winners are equal or differ by a CPU vote margin the explained moves cover;"
          " the GPU histogram, counters and winner equal those of its own records exactly";
  return text.str();
}

/// Columns of cuda_voter_check's CSV that hold a CellDifferences, in the order cellDifferencesCsv writes.
constexpr const char* kCellDifferenceColumns[] = {"hypotheses",     "mismatched",  "near_edge",  "near_threshold",
                                                  "ill_conditioned", "unexplained", "cpu_winner", "gpu_winner",
                                                  "winner_margin"};

/// The kCellDifferenceColumns names, comma-separated (a CSV header's part).
inline std::string cellDifferencesCsvHeader() {
  std::string header;
  for (const char* column : kCellDifferenceColumns) header += (header.empty() ? "" : ",") + std::string(column);
  return header;
}

/// `d` as the comma-separated values of kCellDifferenceColumns.
inline std::string cellDifferencesCsv(const CellDifferences& d) {
  std::ostringstream row;
  row << d.hypotheses << ',' << d.mismatched << ',' << d.near_edge << ',' << d.near_threshold << ','
      << d.ill_conditioned << ',' << d.unexplained << ',' << d.cpu_winner << ',' << d.gpu_winner << ','
      << d.winner_margin;
  return row.str();
}

/// One row of a cuda_voter_check CSV: its fields by column name, and its CellDifferences.
struct CsvFrameRow {
  std::vector<std::pair<std::string, std::string>> fields;  ///< (column, value) in file order
  CellDifferences differences;
  /// The value of `column`, or "" when the file has no such column.
  std::string field(const std::string& column) const {
    for (const auto& f : fields)
      if (f.first == column) return f.second;
    return "";
  }
};

/// Reads a cuda_voter_check CSV (header line, then one row per frame and grid). Columns are found
/// by name; winner_margin may be missing (then -1), every other kCellDifferenceColumns entry must
/// be there. Throws std::runtime_error naming the line for a missing column, a short row or a
/// field that is not a whole number.
inline std::vector<CsvFrameRow> readVoterCheckCsv(std::istream& in) {
  auto split = [](const std::string& line) {
    std::vector<std::string> out;
    std::stringstream ss(line);
    std::string item;
    while (std::getline(ss, item, ',')) out.push_back(item);
    if (!line.empty() && line.back() == ',') out.emplace_back();
    return out;
  };
  std::string line;
  if (!std::getline(in, line)) throw std::runtime_error("voter check CSV: empty");
  const std::vector<std::string> header = split(line);
  for (const char* column : kCellDifferenceColumns)
    if (std::string(column) != "winner_margin" && std::find(header.begin(), header.end(), column) == header.end())
      throw std::runtime_error(std::string("voter check CSV: no column ") + column);
  std::vector<CsvFrameRow> rows;
  for (size_t number = 2; std::getline(in, line); ++number) {
    if (line.empty()) continue;
    const std::vector<std::string> values = split(line);
    if (values.size() != header.size())
      throw std::runtime_error("voter check CSV line " + std::to_string(number) + ": " + std::to_string(values.size()) +
                               " fields, the header has " + std::to_string(header.size()));
    CsvFrameRow row;
    for (size_t i = 0; i < header.size(); ++i) row.fields.emplace_back(header[i], values[i]);
    auto number_of = [&](const char* column, long long missing) -> long long {
      const std::string text = row.field(column);
      if (std::find(header.begin(), header.end(), column) == header.end()) return missing;
      size_t used = 0;
      long long v = 0;
      try {
        v = std::stoll(text, &used);
      } catch (const std::exception&) {
        used = 0;
      }
      if (text.empty() || used != text.size())
        throw std::runtime_error("voter check CSV line " + std::to_string(number) + ": " + column + " '" + text +
                                 "' is not a whole number");
      return v;
    };
    CellDifferences& d = row.differences;
    d.hypotheses = static_cast<uint64_t>(number_of("hypotheses", 0));
    d.mismatched = static_cast<uint64_t>(number_of("mismatched", 0));
    d.near_edge = static_cast<uint64_t>(number_of("near_edge", 0));
    d.near_threshold = static_cast<uint64_t>(number_of("near_threshold", 0));
    d.ill_conditioned = static_cast<uint64_t>(number_of("ill_conditioned", 0));
    d.unexplained = static_cast<uint64_t>(number_of("unexplained", 0));
    d.cpu_winner = static_cast<int32_t>(number_of("cpu_winner", -1));
    d.gpu_winner = static_cast<int32_t>(number_of("gpu_winner", -1));
    d.winner_margin = number_of("winner_margin", -1);
    rows.push_back(std::move(row));
  }
  return rows;
}

/// What compareVotes found: the moved hypotheses and winners (judged by judgeCellDifferences), the
/// value differences and the histograms.
struct CompareReport : CellDifferences {
  uint64_t value_differences = 0;  ///< solved on both sides, values differ beyond the tolerance
  double max_value_difference = 0.0;   ///< max |cpu - gpu| over hypotheses solved on both sides [rad]
  double max_scaled_difference = 0.0;  ///< max |cpu - gpu| * sv1 / sv0 (the rule's quantity) [rad]
  uint64_t histogram_l1 = 0;       ///< sum over cells |hist_gpu - hist_cpu|
  uint64_t cells_differing = 0;
  std::vector<std::string> problems;  ///< broken rules; empty when the comparison passed

  bool passed() const { return problems.empty(); }
  bool winnersEqual() const { return cpu_winner == gpu_winner; }
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

/// The GPU's own consistency: its atomics, block merges and argmax must reproduce exactly what its
/// per-hypothesis records imply. Appends the broken rules to *problems; false when a record's cell
/// is out of range (nothing else can be compared then).
inline bool gpuSelfConsistent(const VoteRequest& request, const VoteResult& gpu, int32_t cells,
                              std::vector<std::string>* problems) {
  auto problem = [problems](const std::string& text) { problems->push_back(text); };
  std::vector<int32_t> rebuilt(cells, 0);
  std::vector<double> sums(3 * static_cast<size_t>(cells), 0.0), abs_sums(3 * static_cast<size_t>(cells), 0.0);
  uint32_t gpu_accepted = 0;
  for (const hyp::HypothesisRecord& r : gpu.records) {
    if (r.cell < 0) continue;
    if (r.cell >= cells) {
      problem("GPU record with cell out of range");
      return false;
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
  return true;
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

  if (!detail::gpuSelfConsistent(request, gpu, cells, &report.problems)) return report;

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
  report.cpu_winner = cpu.winner;
  report.gpu_winner = gpu.winner;
  auto votes = [&cpu, cells](int32_t cell) -> int64_t { return cell >= 0 && cell < cells ? cpu.histogram[cell] : 0; };
  report.winner_margin = votes(cpu.winner) - votes(gpu.winner);

  for (const std::string& p : judgeCellDifferences(report, options)) problem(p);
  std::ostringstream text;
  if (report.value_differences) {
    text << report.value_differences << " hypotheses whose values differ by more than " << options.value_scale
         << " rad / (sv1 / sv0) (max difference * sv1 / sv0: " << report.max_scaled_difference << ")";
    problem(text.str());
  }
  if (report.histogram_l1 > 2 * report.mismatched) problem("histograms differ by more than the moved hypotheses explain");
  const int64_t accepted_diff = static_cast<int64_t>(gpu.accepted) - cpu.accepted;
  if (static_cast<uint64_t>(accepted_diff < 0 ? -accepted_diff : accepted_diff) > report.mismatched)
    problem("accepted counts differ by more than the moved hypotheses explain");
  return report;
}

}  // namespace bearings
}  // namespace visual_gyro
