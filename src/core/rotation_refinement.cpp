#include "rotation_refinement.h"
#include "match_passes.h"
#include "visual_gyro/geometry.h"
#include "visual_gyro/random.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <tuple>
#include <utility>

#include <Eigen/Dense>

namespace visual_gyro {

namespace {

constexpr double kRotationGateScale = 1.25;
// The model choice (translationExplainsMore): a general motion must explain this fraction of its
// inliers more than the pure rotation does, or significantly (this many standard deviations of a
// binomial count) more than this share of the matches the pure rotation leaves unexplained.
constexpr double kTranslationGain = 0.15;
constexpr double kUnexplainedShare = 0.5;
constexpr double kShareSignificance = 3.0;
// Levenberg-Marquardt stops when a step turns the rotation by less than this [rad] (3e-4 deg:
// two orders of magnitude below the smallest rotation error on any sequence).
constexpr double kConvergedRotation = 5e-6;
// The row skew: Gauss-Newton steps from the rigid fit (twice as many Levenberg-Marquardt steps
// under general motion).
constexpr int kRowSkewIterations = 5;
// The skew's systems: 6 (pure rotation) or 8 (general motion) parameters, on the stack.
using SkewMatrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, 8, 8>;
using SkewVector = Eigen::Matrix<double, Eigen::Dynamic, 1, 0, 8, 1>;

// Two unit vectors orthogonal to t: the tangent plane in which t is updated.
Eigen::Matrix<double, 3, 2> tangentBasis(const Eigen::Vector3d& t) {
  const Eigen::Vector3d helper =
      std::abs(t.x()) < 0.9 ? Eigen::Vector3d::UnitX() : Eigen::Vector3d::UnitY();
  Eigen::Matrix<double, 3, 2> B;
  B.col(0) = t.cross(helper).normalized();
  B.col(1) = t.cross(B.col(0));
  return B;
}

// Whether match i's bearings are in the same hemisphere at the last rotateAll's rotation.
inline bool usable(const FrameMatches::Scratch& s, size_t i) { return s.facing[i] > 0.0; }

// A rolling shutter exposes the rows one after another, so the two exposures of a point lie
// further apart or closer in time by its row; while the rate changes within the pair (a hand's
// shake) the rotation between them changes with the row, to first order linearly. Match i's
// rotation is R exp(s_i e): s_i its row (matchRow, geometry.h), e the change per unit of s
// (RefinedRotation::row_skew). A global shutter has e = 0.
inline double matchRow(const FrameMatches& m, size_t i) { return visual_gyro::matchRow(m.previous(i), m.current(i)); }

// exp(w) c to second order in w (|w| is a few hundredths of a radian at most).
inline Eigen::Vector3d deskewed(const Eigen::Vector3d& c, const Eigen::Vector3d& w) {
  const Eigen::Vector3d wc = w.cross(c);
  return c + wc + 0.5 * w.cross(wc);
}

// The normal equations of the pure-rotation residuals n = b_prev x R exp(s e) b_cur in the step
// (R exp(d), e + de); the rigid ones with e = 0 (and their first block alone). With
// K = [p]x [R c_s]x = R c_s p^T - (p . R c_s) I (c_s = exp(s e) b_cur): J_d = -K R and
// J_de = s J_d (to first order), so J^T J has the blocks s^k R^T K^T K R (k = 0, 1, 2) and J^T n
// the blocks s^k R^T (p . R c_s) n, summed in the rotated frame and turned back once.
struct RowSkewEquations {
  Eigen::Matrix3d information[3] = {Eigen::Matrix3d::Zero(), Eigen::Matrix3d::Zero(), Eigen::Matrix3d::Zero()};
  Eigen::Vector3d gradient[2] = {Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero()};
  double sum_sq = 0.0;  // unweighted squared residuals of the matches added
  int used = 0;

  void add(const Eigen::Vector3d& p, const Eigen::Vector3d& rc, const Eigen::Vector3d& n, double s, double w) {
    // K^T K = |Rc|^2 p p^T - (p.Rc)(p Rc^T + Rc p^T) + (p.Rc)^2 I, once per match.
    const double d = p.dot(rc);
    Eigen::Matrix3d KtK = rc.squaredNorm() * p * p.transpose();
    KtK.noalias() -= d * (p * rc.transpose() + rc * p.transpose());
    KtK.diagonal().array() += d * d;
    information[0].noalias() += w * KtK;
    information[1].noalias() += (w * s) * KtK;
    information[2].noalias() += (w * s * s) * KtK;
    const Eigen::Vector3d g = (w * d) * n;
    gradient[0] += g;
    gradient[1] += s * g;
    sum_sq += n.squaredNorm();
    ++used;
  }
  Eigen::Matrix<double, 6, 6> hessian(const Eigen::Matrix3d& R) const {
    Eigen::Matrix<double, 6, 6> H;
    H.topLeftCorner<3, 3>() = R.transpose() * information[0] * R;
    H.topRightCorner<3, 3>() = R.transpose() * information[1] * R;
    H.bottomLeftCorner<3, 3>() = H.topRightCorner<3, 3>().transpose();
    H.bottomRightCorner<3, 3>() = R.transpose() * information[2] * R;
    return H;
  }
  Eigen::Matrix<double, 6, 1> rhs(const Eigen::Matrix3d& R) const {
    Eigen::Matrix<double, 6, 1> g;
    g << R.transpose() * gradient[0], R.transpose() * gradient[1];
    return g;
  }
};

// Match i's rotated current bearing R exp(s e) b_cur, s its row (matchRow).
inline Eigen::Vector3d skewRotated(const FrameMatches& m, size_t i, double s, const Eigen::Matrix3d& R,
                                   const Eigen::Vector3d& e) {
  return R * deskewed(m.current(i), s * e);
}

// The equations of the matches in the same hemisphere within `gate` [rad] at (R, e), Huber-weighted
// beyond `huber` (0: unweighted); with `group`, each match within a group (>= 0) goes to
// by_group[group[i]] instead.
RowSkewEquations rowSkewEquations(const FrameMatches& m, const Eigen::Matrix3d& R, const Eigen::Vector3d& e,
                                  double gate, double huber, const std::vector<int>* group = nullptr,
                                  RowSkewEquations* by_group = nullptr) {
  RowSkewEquations eq;
  for (size_t i = 0; i < m.size(); ++i) {
    if (group != nullptr && (*group)[i] < 0) continue;
    const double s = matchRow(m, i);
    const Eigen::Vector3d p = m.previous(i), rc = skewRotated(m, i, s, R, e), n = p.cross(rc);
    const double r = n.norm();
    if (!(p.dot(rc) > 0.0) || !(r < gate)) continue;
    (group != nullptr ? by_group[(*group)[i]] : eq).add(p, rc, n, s, huber > 0.0 && r > huber ? huber / r : 1.0);
  }
  return eq;
}

// The matches and the scratch's arrays of the last rotateAll, for the passes.
passes::MatchArrays matchArrays(const FrameMatches& m) {
  const FrameMatches::Scratch& s = m.scratch;
  return {m.px.data(), m.py.data(), m.pz.data(), s.rx.data(), s.ry.data(),
          s.rz.data(), s.nx.data(), s.ny.data(), s.nz.data(), s.facing.data()};
}

// R b_cur, b_prev x R b_cur and the hemisphere test of every match into the scratch arrays: the
// one pass per rotation that the counting and gating loops then read. Matches whose bearings
// point into opposite half-spaces after the rotation cannot be one point. A rotation equal to the
// last one's (a refinement starting where a verification ended, a round whose steps were all
// rejected) finds its results already there.
void rotateAll(FrameMatches& m, const Eigen::Matrix3d& R) {
  FrameMatches::Scratch& s = m.scratch;
  if (s.rotated && s.rotation == R) return;
  const size_t n = m.size();
  for (std::vector<double>* v : {&s.rx, &s.ry, &s.rz, &s.nx, &s.ny, &s.nz}) v->resize(n);
  s.facing.resize(n);
  const double rows[9] = {R(0, 0), R(0, 1), R(0, 2), R(1, 0), R(1, 1), R(1, 2), R(2, 0), R(2, 1), R(2, 2)};
  passes::passes().rotate(n, rows, m.px.data(), m.py.data(), m.pz.data(), m.cx.data(), m.cy.data(), m.cz.data(),
                          s.rx.data(), s.ry.data(), s.rz.data(), s.nx.data(), s.ny.data(), s.nz.data(),
                          s.facing.data());
  s.rotation = R;
  s.rotated = true;
  s.counting = false;
}

// The usable matches of the last rotateAll in the counting arrays (even indices, then odd ones).
// The translation counts of a verification (up to some seventy per rotation) then read
// contiguous arrays with no hemisphere test, and the sampled counts only the first group.
void prepareCounting(FrameMatches& m) {
  FrameMatches::Scratch& s = m.scratch;
  if (s.counting) return;
  const size_t n = m.size();
  for (std::vector<double>* v : {&s.qnx, &s.qny, &s.qnz, &s.qpx, &s.qpy, &s.qpz, &s.qrx, &s.qry, &s.qrz})
    v->resize(n);
  s.odd_start = (n + 1) / 2;
  // Without branches: each match is written at the group's next place, which only a usable one
  // then takes (a group's place never reaches the next group: it counts the group's matches before).
  size_t next[2] = {0, s.odd_start};
  for (size_t first = 0; first < 2; ++first) {
    size_t k = next[first];
    for (size_t i = first; i < n; i += 2) {
      s.qnx[k] = s.nx[i];
      s.qny[k] = s.ny[i];
      s.qnz[k] = s.nz[i];
      s.qpx[k] = m.px[i];
      s.qpy[k] = m.py[i];
      s.qpz[k] = m.pz[i];
      s.qrx[k] = s.rx[i];
      s.qry[k] = s.ry[i];
      s.qrz[k] = s.rz[i];
      k += usable(s, i);
    }
    next[first] = k;
  }
  s.even_count = next[0];
  s.odd_count = next[1] - s.odd_start;
  s.counting = true;
}

// Epipolar inliers of translation t among the counting arrays' matches: the first group only when
// `sampled` (every other match), else both. Only a count above `beat` is of use to the caller: the
// count stops, returning something no larger, as soon as the matches left cannot lift it above
// `beat` (most sampled translations are wrong and are given up after a fraction of the matches).
// Checked once per block, so that the loop within a block has no early exit.
int countEpipolarInliers(const FrameMatches& m, const Eigen::Vector3d& t, double gate, bool sampled, int beat) {
  constexpr size_t kBlock = 64;
  const FrameMatches::Scratch& s = m.scratch;
  const passes::MatchArrays arrays = {s.qpx.data(), s.qpy.data(), s.qpz.data(), s.qrx.data(), s.qry.data(),
                                      s.qrz.data(), s.qnx.data(), s.qny.data(), s.qnz.data(), nullptr};
  const auto count_within = passes::passes().countWithinGate;
  const double gate2 = gate * gate;
  const size_t groups[2][2] = {{0, s.even_count}, {s.odd_start, s.odd_start + s.odd_count}};
  size_t left = s.even_count + (sampled ? 0 : s.odd_count);
  int count = 0;
  for (int g = 0; g < (sampled ? 1 : 2); ++g) {
    for (size_t block = groups[g][0]; block < groups[g][1]; block += kBlock) {
      if (count + static_cast<int>(left) <= beat) return count;
      const size_t end = std::min(groups[g][1], block + kBlock);
      count += count_within(arrays, block, end, t.data(), gate2);
      left -= end - block;
    }
  }
  return count;
}

// kGateSigmas robust sigmas (1.4826 MAD) of the residuals below the threshold, clamped to
// [threshold / 8, threshold], at the rotation of the last rotateAll. With t == nullptr the residual
// is the pure-rotation one |b x R b'|. The median is taken of the squared residuals (the same
// match's), which need no square root per match.
double adaptiveGate(FrameMatches& m, const Eigen::Vector3d* t, double threshold) {
  FrameMatches::Scratch& s = m.scratch;
  const size_t n = m.size();
  std::vector<double>& squared = s.residuals;
  // The residuals of every match in one vectorised pass, then those of the usable matches below
  // the threshold kept (in index order) without a branch.
  s.weights.resize(n);
  passes::passes().residuals2(matchArrays(m), n, t != nullptr ? t->data() : nullptr, s.weights.data());
  squared.resize(n);
  const double threshold2 = threshold * threshold;
  size_t kept = 0;
  for (size_t i = 0; i < n; ++i) {
    squared[kept] = s.weights[i];
    kept += usable(s, i) && s.weights[i] < threshold2;
  }
  squared.resize(kept);
  if (squared.size() < 10) return threshold;
  const double median = passes::selectKth(squared.data(), squared.size(), squared.size() / 2);
  // The 2-D pure-rotation residual's median is ~1.18 sigma, the 1-D |r|'s 0.67 sigma.
  const double sigma = std::sqrt(median) / (t != nullptr ? 0.6745 : 1.1774);
  return std::clamp(kGateSigmas * sigma, threshold / 8.0, threshold);
}

// The covariance sigma^2 A^-1 of a fit's rotation (A's first three parameters; the others, such as
// a translation or a skew, marginalised out), sigma^2 = cost / dof, and of a general motion's
// translation (the next two parameters) the larger standard deviation. False, the covariance left
// as it was, where A is singular.
template <typename Matrix>
bool setFitCovariance(const Matrix& A, double cost, int dof, RefinedRotation* out) {
  const double sigma2 = cost / std::max(1, dof);
  out->residual_sigma = std::sqrt(sigma2);
  const Eigen::FullPivLU<Matrix> lu(A);
  if (!lu.isInvertible()) return false;
  const Matrix covariance = sigma2 * lu.inverse();
  // The inverse of a nearly singular A is symmetric only up to its rounding, and a covariance
  // must be symmetric exactly (a fusion filter may test it).
  const Eigen::Matrix3d rotation = covariance.template topLeftCorner<3, 3>();
  out->covariance = 0.5 * (rotation + rotation.transpose());
  if constexpr (Matrix::RowsAtCompileTime == Eigen::Dynamic || Matrix::RowsAtCompileTime >= 5) {
    if (A.rows() >= 5) {
      const Eigen::Matrix2d translation = covariance.template block<2, 2>(3, 3);
      out->translation_sigma = std::sqrt(Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d>(translation).eigenvalues()(1));
    }
  }
  return true;
}

// The rotation and the covariance of a pure-rotation fit at (R, e): the covariance of (d, de) from
// the unweighted inliers at the full gate, the rotation's block with the skew's marginalised out
// (a Schur complement) when `skewed`.
void setPureRotationFit(FrameMatches& m, const Eigen::Matrix3d& R, const Eigen::Vector3d& e, bool skewed,
                        double threshold, RefinedRotation* out) {
  const RowSkewEquations eq = rowSkewEquations(m, R, e, kRotationGateScale * threshold, 0.0);
  const Eigen::Matrix<double, 6, 6> H = eq.hessian(R);
  Eigen::Matrix3d information = H.topLeftCorner<3, 3>();
  if (skewed) {
    const Eigen::FullPivLU<Eigen::Matrix3d> skew_block(H.bottomRightCorner<3, 3>());
    if (skew_block.isInvertible())
      information -= H.topRightCorner<3, 3>() * skew_block.inverse() * H.bottomLeftCorner<3, 3>();
  }
  out->rotation = R;
  out->row_skew = e;
  out->pure_rotation = true;
  out->matches = static_cast<int>(m.size());
  if (!setFitCovariance(information, eq.sum_sq, 2 * eq.used - (skewed ? 6 : 3), out)) out->covariance.setIdentity();
  if (!skewed) {
    out->inliers = eq.used;
    const size_t outside = m.size() - static_cast<size_t>(eq.used);
    out->truncated_cost = eq.sum_sq + static_cast<double>(outside) * kRotationGateScale * threshold *
                                          kRotationGateScale * threshold;
  }
}

RefinedRotation refinePureRotation(FrameMatches& m, Eigen::Matrix3d R, double threshold, int iterations) {
  const size_t n = m.size();
  FrameMatches::Scratch& s = m.scratch;
  RefinedRotation out;
  for (int it = 0; it < std::max(1, iterations); ++it) {
    rotateAll(m, R);
    const double gate_width = it > 0 ? adaptiveGate(m, nullptr, threshold) : 1.6 * threshold;
    const double gate2 = (kRotationGateScale * gate_width) * (kRotationGateScale * gate_width);
    // Weighted Kabsch: the closed-form minimiser of sum w |b_prev - R b_cur|^2. The Huber weights
    // (zero outside the gate, where they then add exact zeros) come from one vectorised pass; the
    // sums run in index order.
    s.weights.resize(n);
    passes::passes().huberWeights(matchArrays(m), n, gate2, 0.5 * gate_width, s.weights.data());
    double h[3][3] = {};
    int used = 0;
    for (size_t i = 0; i < n; ++i) {
      const double w = s.weights[i];
      const double wc[3] = {w * m.cx[i], w * m.cy[i], w * m.cz[i]};
      for (int r = 0; r < 3; ++r) {
        h[r][0] += wc[r] * m.px[i];
        h[r][1] += wc[r] * m.py[i];
        h[r][2] += wc[r] * m.pz[i];
      }
      used += w != 0.0;
    }
    Eigen::Matrix3d H;
    H << h[0][0], h[0][1], h[0][2], h[1][0], h[1][1], h[1][2], h[2][0], h[2][1], h[2][2];
    if (used < 3) break;
    Eigen::JacobiSVD<Eigen::Matrix3d> svd(H, Eigen::ComputeFullU | Eigen::ComputeFullV);
    Eigen::Matrix3d D = Eigen::Matrix3d::Identity();
    D(2, 2) = (svd.matrixV() * svd.matrixU().transpose()).determinant() < 0 ? -1.0 : 1.0;
    const Eigen::Matrix3d next = svd.matrixV() * D * svd.matrixU().transpose();
    const double change = Eigen::AngleAxisd(R.transpose() * next).angle();
    R = next;
    if (change < 1e-10) break;
  }
  setPureRotationFit(m, R, Eigen::Vector3d::Zero(), false, threshold, &out);
  return out;
}

// The normal equations of the epipolar residuals in the step (R exp(d), t + B tau).
struct NormalEquations {
  Eigen::Matrix<double, 5, 5> A;
  Eigen::Matrix<double, 5, 1> g;
  Eigen::Matrix<double, 3, 2> B;  // tangent basis of t the step's last two entries refer to
  double cost = 0.0;              // Tukey cost, or the sum of squared residuals (kInliers)
  int used = 0;                   // matches summed, or those within the gate (kInliers)
};

// kTukey: Tukey-weighted residuals with cut-off `gate`, for Levenberg-Marquardt; kInliers:
// unweighted residuals below `gate`, for the covariance.
enum class Weighting { kTukey, kInliers };

// Gathers every stride-th match whose keep[i] is not zero (every match when keep is nullptr) into
// the six arrays `to` (b_prev, then b_cur), padded with zero bearings to whole chunks, where the
// summing pass of this CPU wants them (passes::PassTable). Returns the number gathered.
size_t gatherMatches(const FrameMatches& m, const double* keep, size_t stride, std::vector<double>* const to[6]) {
  const size_t n = m.size();
  const bool interleaved = passes::passes().interleaved;
  const size_t capacity = (n + passes::kChunk - 1) / passes::kChunk * passes::kChunk;
  double* out[6];
  for (int a = 0; a < 6; ++a) {
    if (to[a]->size() < capacity) to[a]->resize(capacity);
    out[a] = to[a]->data();
  }
  const double* const from[6] = {m.px.data(), m.py.data(), m.pz.data(), m.cx.data(), m.cy.data(), m.cz.data()};
  // Without branches (whether a match is kept is close to a coin toss in the wide first rounds):
  // each match is written at the next place, which only a kept one then takes; the place a last
  // dropped match took is padding, zeroed below with the rest of its chunk.
  size_t count = 0;
  for (size_t i = 0; i < n; i += stride) {
    const size_t at = passes::gatheredPosition(count, interleaved);
    for (int a = 0; a < 6; ++a) out[a][at] = from[a][i];
    count += keep == nullptr || keep[i] != 0.0;
  }
  const size_t padded = (count + passes::kChunk - 1) / passes::kChunk * passes::kChunk;
  for (size_t k = count; k < padded; ++k) {
    for (int a = 0; a < 6; ++a) out[a][passes::gatheredPosition(k, interleaved)] = 0.0;
  }
  return count;
}

// Matches gathered for the summing passes: b_prev (p) and b_cur (c), `count` of them.
struct Gathered {
  const double *px, *py, *pz, *cx, *cy, *cz;
  size_t count;
};

// The matches the last gatherMatches put into the scratch.
Gathered gatheredInScratch(const FrameMatches& m) {
  const FrameMatches::Scratch& s = m.scratch;
  return {s.gpx.data(), s.gpy.data(), s.gpz.data(), s.gcx.data(), s.gcy.data(), s.gcz.data(), s.gathered};
}

// Every match of the frame, gathered on the frame's first call (each refinement's covariance
// pass reads them all).
Gathered gatheredAll(FrameMatches& m) {
  if (!m.all_gathered) {
    std::vector<double>* const all[6] = {&m.all_px, &m.all_py, &m.all_pz, &m.all_cx, &m.all_cy, &m.all_cz};
    gatherMatches(m, nullptr, 1, all);
    m.all_gathered = true;
  }
  return {m.all_px.data(), m.all_py.data(), m.all_pz.data(), m.all_cx.data(), m.all_cy.data(), m.all_cz.data(),
          m.size()};
}

// One pass over the gathered matches gives both the cost at (R, t) and the normal equations for
// the next step, so an accepted Levenberg-Marquardt step costs one pass over the matches.
// Row of d(t . (p x R exp(d) c))/d(d, tau): t^T [p]x R (-[c]x) = -((R^T (t x p)) x c)^T
// = -(R^T ((t x p) x Rc))^T for the rotation, n^T B for the tangent-plane translation step; the
// sums are taken with the rotation part's R^T left out and it is applied once at the end. This
// runs for every gated match in every iteration, so the matches are processed in fixed-size
// chunks of vectorised arithmetic (passes::PassTable::sumEpipolar) and only the 15 distinct
// entries of the symmetric matrix are summed. The padding's zero bearings have zero residual and
// Jacobian: they add nothing.
void accumulateEpipolar(const Gathered& g, const Eigen::Matrix3d& R, const Eigen::Vector3d& t, double gate,
                        Weighting weighting, NormalEquations* ne) {
  const Eigen::Matrix<double, 3, 2> B = tangentBasis(t);
  const double rows[9] = {R(0, 0), R(0, 1), R(0, 2), R(1, 0), R(1, 1), R(1, 2), R(2, 0), R(2, 1), R(2, 2)};
  passes::EpipolarSums sums;
  passes::passes().sumEpipolar(g.px, g.py, g.pz, g.cx, g.cy, g.cz, g.count, rows, t.data(), B.data(), gate,
                               weighting == Weighting::kTukey, &sums);
  Eigen::Matrix<double, 5, 5> A;
  int k = 0;
  for (int row = 0; row < 5; ++row)
    for (int col = row; col < 5; ++col) A(row, col) = A(col, row) = sums.a[k++];
  Eigen::Matrix<double, 5, 5> T = Eigen::Matrix<double, 5, 5>::Identity();
  T.topLeftCorner<3, 3>() = R.transpose();
  ne->A.noalias() = T * A * T.transpose();
  ne->g.noalias() = T * Eigen::Map<const Eigen::Matrix<double, 5, 1>>(sums.g);
  ne->B = B;
  ne->cost = sums.cost;
  ne->used = sums.used;
}

// The Tukey cost accumulateEpipolar gives at (R, t), alone.
double tukeyCost(const Gathered& g, const Eigen::Matrix3d& R, const Eigen::Vector3d& t, double gate) {
  const double rows[9] = {R(0, 0), R(0, 1), R(0, 2), R(1, 0), R(1, 1), R(1, 2), R(2, 0), R(2, 1), R(2, 2)};
  return passes::passes().tukeyCost(g.px, g.py, g.pz, g.cx, g.cy, g.cz, g.count, rows, t.data(), gate);
}

RefinedRotation refineGeneral(FrameMatches& m, Eigen::Matrix3d R, Eigen::Vector3d t, double threshold,
                              int iterations) {
  const size_t n = m.size();
  FrameMatches::Scratch& s = m.scratch;
  RefinedRotation out;
  double lambda = 1e-6;
  // The inlier gate is fixed per outer round (residuals of the round's start), so each
  // Levenberg-Marquardt step compares costs over the same matches.
  // The first round's wider gate lets a start rotation that is off by a few thresholds (a biased
  // rotation-only vote) still gather its true inliers.
  // Later rounds shrink the gate to kGateSigmas robust sigmas of the inliers' residuals (never
  // above the threshold): under forward motion a wrong match near the epipole satisfies the
  // epipolar constraint almost as well as a right one, and the yaw/lateral-translation ambiguity
  // turns the few that slip through a fixed gate into a visible rotation bias.
  const double schedule[] = {6.0 * threshold, 2.0 * threshold, 0.0};
  const int rounds = static_cast<int>(sizeof(schedule) / sizeof(schedule[0]));
  for (int round = 0; round < rounds; ++round) {
    rotateAll(m, R);
    double gate_width = schedule[round];
    if (gate_width == 0.0) gate_width = adaptiveGate(m, &t, threshold);
    // The wide early gates only need to move the start into the basin: a few steps suffice.
    const bool last = round + 1 == rounds;
    const int round_iterations = last ? iterations : std::min(iterations, 2);
    // ... on every other match: enough to find the basin; the last round uses them all.
    const size_t stride = last || n < 300 ? 1 : 2;
    // The usable matches within the gate (a non-zero weight), gathered for the summing passes.
    s.weights.resize(n);
    passes::passes().gateWeights(matchArrays(m), n, t.data(), gate_width * gate_width, s.weights.data());
    NormalEquations here, there;
    std::vector<double>* const to[6] = {&s.gpx, &s.gpy, &s.gpz, &s.gcx, &s.gcy, &s.gcz};
    s.gathered = gatherMatches(m, s.weights.data(), stride, to);
    const Gathered gated = gatheredInScratch(m);
    accumulateEpipolar(gated, R, t, gate_width, Weighting::kTukey, &here);
    for (int it = 0; it < round_iterations && here.used >= 6; ++it) {
      // Levenberg-Marquardt damping: under (nearly) pure rotation the translation direction is
      // unobservable and J^T W J is singular in those two columns.
      Eigen::Matrix<double, 5, 5> damped = here.A;
      damped.diagonal() += lambda * (here.A.diagonal().array() + 1e-12).matrix();
      const Eigen::Matrix<double, 5, 1> step = damped.ldlt().solve(-here.g);
      if (!step.allFinite()) break;
      const Eigen::Matrix3d R_new = R * so3Exp(step.head<3>());
      const Eigen::Vector3d t_new = (t + here.B * step.tail<2>()).normalized();
      // Converged once the rotation moves by less than kConvergedRotation. A rejected step that
      // small ends the round as well: near the minimum the cost with the Sampson scale held fixed
      // and the true cost differ by more than such a step gains, so further, more damped steps
      // are rejected in turn (each a pass over the matches) and would move the rotation less still.
      const bool converged = step.head<3>().norm() < kConvergedRotation;
      // The round's last step is only accepted or rejected: its cost decides, the normal
      // equations at its end would not be used (the next round starts from its own).
      if (converged || it + 1 == round_iterations) {
        there.cost = tukeyCost(gated, R_new, t_new, gate_width);
      } else {
        accumulateEpipolar(gated, R_new, t_new, gate_width, Weighting::kTukey, &there);
      }
      if (there.cost <= here.cost) {
        R = R_new;
        t = t_new;
        std::swap(here, there);
        lambda = std::max(1e-9, lambda * 0.3);
      } else {
        lambda *= 10.0;
        if (lambda > 1e6) break;
      }
      if (converged) break;
    }
  }
  // Covariance: sigma^2 (J^T W J)^-1 at the solution, over the final inliers.
  NormalEquations final_fit;
  accumulateEpipolar(gatheredAll(m), R, t, threshold, Weighting::kInliers, &final_fit);
  const int inliers = final_fit.used;
  out.rotation = R;
  out.translation = t;
  out.inliers = inliers;
  out.matches = static_cast<int>(m.size());
  out.truncated_cost = final_fit.cost + static_cast<double>(m.size() - static_cast<size_t>(inliers)) * threshold * threshold;
  setFitCovariance(final_fit.A, final_fit.cost, inliers - 5, &out);
  return out;
}

/// fittedTranslationCost()'s truncated cost of `translation` for the normals in the scratch (those
/// of the rotation last applied by rotateAll), so that several translations are costed without
/// rotating the matches again.
double truncatedCostOfNormals(FrameMatches& m, const Eigen::Vector3d& translation, double threshold) {
  const size_t n = m.size();
  FrameMatches::Scratch& s = m.scratch;
  s.residuals.resize(n);
  passes::passes().residuals2(matchArrays(m), n, translation.data(), s.residuals.data());
  const double gate2 = threshold * threshold;
  double cost = 0.0;
  for (size_t i = 0; i < n; ++i) cost += usable(s, i) ? std::min(s.residuals[i], gate2) : gate2;
  return cost;
}

/// Least-squares refit of the translation: the eigenvector of the smallest eigenvalue of
/// sum n n^T over the inliers of `translation`, each normal scaled to its angular residual, for
/// the normals in the scratch (those of the rotation last applied by rotateAll). The squared scale
/// needs no square root. The weights (the squared scale of the inliers, zero for the others, which
/// then add exact zeros) come from one vectorised pass; the sums run in index order. The
/// eigensolver reads the lower triangle only, so only that is summed. Its sign is the
/// eigensolver's.
Eigen::Vector3d refitTranslation(FrameMatches& m, const Eigen::Vector3d& translation, double threshold) {
  const size_t n = m.size();
  FrameMatches::Scratch& s = m.scratch;
  s.weights.resize(n);
  passes::passes().gateWeights(matchArrays(m), n, translation.data(), threshold * threshold, s.weights.data());
  double m00 = 0.0, m10 = 0.0, m11 = 0.0, m20 = 0.0, m21 = 0.0, m22 = 0.0;
  for (size_t i = 0; i < n; ++i) {
    const double sx = s.weights[i] * s.nx[i], sy = s.weights[i] * s.ny[i], sz = s.weights[i] * s.nz[i];
    m00 += sx * s.nx[i];
    m10 += sy * s.nx[i];
    m11 += sy * s.ny[i];
    m20 += sz * s.nx[i];
    m21 += sz * s.ny[i];
    m22 += sz * s.nz[i];
  }
  Eigen::Matrix3d M;
  M << m00, m10, m20, m10, m11, m21, m20, m21, m22;
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(M);
  return eig.eigenvectors().col(0);
}

}  // namespace

void FrameMatches::assign(const std::vector<Eigen::Vector3d>& previous, const std::vector<Eigen::Vector3d>& current) {
  clear();
  for (size_t i = 0; i < previous.size(); ++i) append(previous[i], current[i]);
}

void FrameMatches::assignWithout(const FrameMatches& from, const std::vector<int>& group, int left_out) {
  clear();
  for (size_t i = 0; i < from.size(); ++i)
    if (group[i] != left_out) append(from.previous(i), from.current(i));
}

void FrameMatches::clear() {
  for (std::vector<double>* v : {&px, &py, &pz, &cx, &cy, &cz}) v->clear();
  all_gathered = false;
  scratch.rotated = false;
  scratch.counting = false;
}

void FrameMatches::append(const Eigen::Vector3d& previous, const Eigen::Vector3d& current) {
  px.push_back(previous.x());
  py.push_back(previous.y());
  pz.push_back(previous.z());
  cx.push_back(current.x());
  cy.push_back(current.y());
  cz.push_back(current.z());
}

VerifiedRotation verifyRotation(FrameMatches& m, const Eigen::Matrix3d& rotation, double threshold,
                                uint64_t seed) {
  const size_t n = m.size();
  FrameMatches::Scratch& s = m.scratch;
  VerifiedRotation out;
  out.rotation = rotation;
  rotateAll(m, rotation);
  std::vector<uint32_t>& moving = s.moving;  // matches a pure rotation does not explain: they carry t
  // The pure-rotation residual is 2-D, the epipolar one 1-D: at equal false-rejection rates
  // (95 %: 2.45 vs 1.96 sigma) the 2-D gate is 1.25 times wider. Without branches (whether a
  // match is explained is close to a coin toss under translation): every match is written at the
  // list's end, which only a usable match outside the gate then takes.
  const double rotation_gate2 = (kRotationGateScale * threshold) * (kRotationGateScale * threshold);
  moving.resize(n);
  size_t moved = 0;
  for (size_t i = 0; i < n; ++i) {
    const bool explained = s.nx[i] * s.nx[i] + s.ny[i] * s.ny[i] + s.nz[i] * s.nz[i] < rotation_gate2;
    moving[moved] = static_cast<uint32_t>(i);
    moved += usable(s, i) & !explained;
    out.rotation_inliers += usable(s, i) & explained;
  }
  moving.resize(moved);
  out.epipolar_inliers = out.rotation_inliers;
  auto normal = [&](size_t i) { return Eigen::Vector3d(s.nx[i], s.ny[i], s.nz[i]); };
  // Samples are scored on every other match (counts doubled); the winner is recounted on all.
  const bool sampled = n >= 200;
  const int sample_stride = sampled ? 2 : 1;
  // A translation can at best add the moving matches to the rotation inliers; when they are too
  // few to pass the margin of the model choice (kTranslationGain), the search is skipped. Their
  // share could still pass it, but opening the search to that moved no case of the score
  // measurably, for more samples on every still frame.
  const bool translation_can_win =
      moving.size() >= 2 && moving.size() >= kTranslationGain * out.rotation_inliers;
  if (translation_can_win) {
    prepareCounting(m);
    SplitMix64 rng(seed ^ 0x5452414E534C4154ull);  // "TRANSLAT"
    // 2-point samples among the moving matches, stopped adaptively: once the best translation
    // explains a fraction w of them, log(0.01) / log(1 - w^2) samples find a clean pair with 99 %
    // probability (at most 64, enough for 50 % wrong matches); the best is then refitted.
    int trials = 64;
    for (int trial = 0; trial < trials; ++trial) {
      const size_t a = moving[rng.next() % moving.size()];
      const size_t b = moving[rng.next() % moving.size()];
      const Eigen::Vector3d t_raw = normal(a).cross(normal(b));
      if (t_raw.norm() < 1e-9) continue;
      const Eigen::Vector3d t = t_raw.normalized();
      const int beat = out.epipolar_inliers / sample_stride;
      const int count = sample_stride * countEpipolarInliers(m, t, threshold, sampled, beat);
      if (count > out.epipolar_inliers) {
        out.epipolar_inliers = count;
        out.translation = t;
        const double w = std::clamp(static_cast<double>(count - out.rotation_inliers) / moving.size(), 0.01, 0.99);
        trials = std::clamp(static_cast<int>(std::ceil(std::log(0.01) / std::log(1.0 - w * w))), 8, 64);
      }
    }
    if (!out.translation.isZero())
      out.epipolar_inliers = countEpipolarInliers(m, out.translation, threshold, false, -1);
    // Least-squares refits, repeated while the support grows.
    for (int refit = 0; refit < 3 && !out.translation.isZero(); ++refit) {
      const Eigen::Vector3d refitted = refitTranslation(m, out.translation, threshold);
      const int count = countEpipolarInliers(m, refitted, threshold, false, out.epipolar_inliers);
      if (count <= out.epipolar_inliers) break;
      out.epipolar_inliers = count;
      out.translation = refitted;
    }
  }
  out.inliers = std::max(out.epipolar_inliers, out.rotation_inliers);
  return out;
}

double fittedTranslationCost(FrameMatches& m, const Eigen::Matrix3d& rotation, Eigen::Vector3d* translation,
                             double threshold, int refits) {
  // The matches are rotated once; every cost and refit reads the same normals.
  rotateAll(m, rotation);
  double cost = truncatedCostOfNormals(m, *translation, threshold);
  for (int refit = 0; refit < refits; ++refit) {
    Eigen::Vector3d refitted = refitTranslation(m, *translation, threshold);
    // The eigenvector's sign is arbitrary; the translation's is not (points in front).
    if (refitted.dot(*translation) < 0.0) refitted = -refitted;
    const double refitted_cost = truncatedCostOfNormals(m, refitted, threshold);
    if (!(refitted_cost < cost)) break;
    cost = refitted_cost;
    *translation = refitted;
  }
  return cost;
}

namespace {

// A translation shows in two ways. Where the pure rotation leaves many wrong matches unexplained
// (near structure, dim footage, injected outliers) only a margin of the general motion's inliers
// tells it from the wrong matches that a translation chosen among them explains by chance; the
// share test alone took euroc_mh01_shake with half its matches wrong from 0.02 to 1.1 deg. Where
// the rotation leaves few, its misses are mostly noise tails, of which a translation's two more
// parameters absorb some (a hand-held room held still: 4-61 %), while a translation that is there
// explains nearly all of them (the room moved by +-5 cm: 81-97 %) though they are only a few per
// cent of the inliers, under the margin.
bool translationExplainsMore(int general, int pure, int matches) {
  const int extra = general - pure;
  if (extra >= kTranslationGain * general) return true;
  const int unexplained = matches - pure;
  if (unexplained <= 0) return false;
  const double expected = kUnexplainedShare * unexplained;
  const double deviation = std::sqrt(unexplained * kUnexplainedShare * (1.0 - kUnexplainedShare));
  return extra - expected > kShareSignificance * deviation;
}

}  // namespace

bool explainsBetter(const RefinedRotation& a, const RefinedRotation& b) {
  if (a.pure_rotation == b.pure_rotation) return a.truncated_cost < b.truncated_cost;
  const RefinedRotation& general = a.pure_rotation ? b : a;
  const RefinedRotation& pure = a.pure_rotation ? a : b;
  const bool general_wins = translationExplainsMore(general.inliers, pure.inliers, pure.matches);
  return a.pure_rotation ? !general_wins : general_wins;
}

RefinedRotation refineRotation(FrameMatches& matches, const VerifiedRotation& start, double threshold,
                               int iterations) {
  // Model selection: translation is only worth estimating when it explains clearly more matches
  // than a pure rotation does; otherwise its two extra degrees of freedom just absorb rotation
  // error (the rotation/translation ambiguity of narrow fields of view).
  const bool pure = start.translation.isZero() ||
                    !translationExplainsMore(start.epipolar_inliers, start.rotation_inliers,
                                             static_cast<int>(matches.size()));
  if (pure) return refinePureRotation(matches, start.rotation, threshold, iterations);
  return refineGeneral(matches, start.rotation, start.translation, threshold, iterations);
}

RefinedRotation refineMotion(FrameMatches& matches, const Eigen::Matrix3d& rotation,
                             const Eigen::Vector3d& translation, double threshold, int iterations) {
  return refineGeneral(matches, rotation, translation.normalized(), threshold, iterations);
}

namespace {

// Most groups per axis of a jackknife, and so most groups in all.
constexpr int kMaxGroupsPerAxis = 4;
constexpr int kMaxGroups = kMaxGroupsPerAxis * kMaxGroupsPerAxis;

// Groups per axis of a jackknife over `count` matches: kMaxGroupsPerAxis at most, at least
// kMinJackknifeGroupSize matches a group (below 2, no jackknife).
int jackknifeGroupsPerAxis(size_t count) {
  return std::min(kMaxGroupsPerAxis, static_cast<int>(std::sqrt(static_cast<double>(count) / kMinJackknifeGroupSize)));
}

// The jackknives' partition of the matches listed in *order (which it reorders): k strips of equal
// count across x of the previous bearing, each cut into k groups of equal count along y.
// (*group)[i] becomes match i's group, strip * k + part, or -1 for a match not listed. Only which
// range of ranks a match falls in matters, so successive partitions (linear time) serve where
// sorts did; ties are broken by index, so the groups are fully determined.
void spatialGroups(const FrameMatches& m, int k, std::vector<uint32_t>* order, std::vector<int>* group) {
  const size_t count = order->size();
  const auto by_x = [&](uint32_t a, uint32_t b) { return m.px[a] < m.px[b] || (m.px[a] == m.px[b] && a < b); };
  const auto by_y = [&](uint32_t a, uint32_t b) { return m.py[a] < m.py[b] || (m.py[a] == m.py[b] && a < b); };
  // Strip s holds the ranks from floor(s count / k); within a strip of `length`, rank j belongs to
  // group floor(j k / length), so group p starts at rank ceil(p length / k).
  const auto stripStart = [k, count](int strip) { return strip * count / k; };
  const auto partStart = [k](size_t length, int part) { return (part * length + k - 1) / k; };
  for (int strip = 1; strip < k; ++strip) {
    std::nth_element(order->begin() + stripStart(strip - 1), order->begin() + stripStart(strip), order->end(), by_x);
  }
  group->assign(m.size(), -1);
  for (int strip = 0; strip < k; ++strip) {
    const auto begin = order->begin() + stripStart(strip), end = order->begin() + stripStart(strip + 1);
    const size_t length = end - begin;
    for (int part = 1; part < k; ++part) {
      std::nth_element(begin + partStart(length, part - 1), begin + partStart(length, part), end, by_y);
    }
    for (int part = 0; part < k; ++part) {
      for (auto it = begin + partStart(length, part); it != begin + partStart(length, part + 1); ++it) {
        (*group)[*it] = strip * k + part;
      }
    }
  }
}

// Match i's Sampson-normalised epipolar residual t . (b_prev x rc) / |grad| for its rotated current
// bearing rc, and the scale 1 / |grad| (refineGeneral's, passes::epipolarChunk's).
inline double sampsonScale(const Eigen::Vector3d& p, const Eigen::Vector3d& rc, const Eigen::Vector3d& t) {
  const double tp = t.dot(p), trc = t.dot(rc);
  return 1.0 / std::sqrt(std::max(1.0 - 0.5 * (tp * tp + trc * trc), 1e-6));
}

// Each match's squared residual under `refined` into scratch.residuals, its rotation's rotateAll
// done: the pure-rotation one (with the row skew where fitted) or the epipolar one.
void squaredResidualsOf(FrameMatches& m, const RefinedRotation& refined) {
  const size_t n = m.size();
  FrameMatches::Scratch& s = m.scratch;
  const bool pure = !isGeneralMotion(refined);
  rotateAll(m, refined.rotation);
  s.residuals.resize(n);
  passes::passes().residuals2(matchArrays(m), n, pure ? nullptr : refined.translation.data(), s.residuals.data());
  if (refined.row_skew.isZero()) return;
  for (size_t i = 0; i < n; ++i) {
    const Eigen::Vector3d p = m.previous(i), rc = skewRotated(m, i, matchRow(m, i), refined.rotation, refined.row_skew);
    const double r = pure ? p.cross(rc).norm() : refined.translation.dot(p.cross(rc)) * sampsonScale(p, rc, refined.translation);
    s.residuals[i] = r * r;
  }
}

// The normal equations of the Sampson-normalised epipolar residuals r = t . (b_prev x R exp(s e)
// b_cur) / |grad| in the step (R exp(d), t + B tau, e + de), as refineGeneral's (the Sampson scale
// held fixed within a step) with the skew's three columns s J_d, summed in the rotated frame.
struct SkewedEpipolarEquations {
  Eigen::Matrix<double, 8, 8> A = Eigen::Matrix<double, 8, 8>::Zero();
  Eigen::Matrix<double, 8, 1> g = Eigen::Matrix<double, 8, 1>::Zero();
  double cost = 0.0;  // Tukey cost (kTukey) or the inliers' squared residuals (kInliers)
  int used = 0;

  void add(const Eigen::Vector3d& p, const Eigen::Vector3d& rc, const Eigen::Vector3d& t,
           const Eigen::Matrix<double, 3, 2>& B, double s, double gate, Weighting weighting) {
    const Eigen::Vector3d n = p.cross(rc);
    const double scale = sampsonScale(p, rc, t), r = t.dot(n) * scale;
    double w = 0.0;
    if (weighting == Weighting::kTukey) {
      const double u2 = std::min(1.0, (r / gate) * (r / gate));
      w = (1.0 - u2) * (1.0 - u2);
      cost += gate * gate / 6.0 * (1.0 - (1.0 - u2) * (1.0 - u2) * (1.0 - u2));
      ++used;
    } else if (std::abs(r) < gate && p.dot(rc) > 0.0) {
      w = 1.0;
      cost += r * r;
      ++used;
    }
    if (w == 0.0) return;
    const Eigen::Vector3d jd = rc.cross(t.cross(p));
    Eigen::Matrix<double, 8, 1> j;
    j << jd, n.dot(B.col(0)), n.dot(B.col(1)), s * jd;
    A.noalias() += (w * scale * scale) * j * j.transpose();
    g.noalias() += (w * r * scale) * j;
  }
  // A and g of the step (the rotation's and the skew's columns turned back from the rotated frame).
  std::pair<SkewMatrix, SkewVector> system(const Eigen::Matrix3d& R) const {
    Eigen::Matrix<double, 8, 8> T = Eigen::Matrix<double, 8, 8>::Identity();
    T.topLeftCorner<3, 3>() = R.transpose();
    T.bottomRightCorner<3, 3>() = R.transpose();
    return {T * A * T.transpose(), T * g};
  }
};

// The equations of every match at (R, t, e); with `group`, each match within a group (>= 0) goes
// to (*by_group)[group[i]] instead.
SkewedEpipolarEquations skewedEpipolarEquations(const FrameMatches& m, const Eigen::Matrix3d& R,
                                                const Eigen::Vector3d& t, const Eigen::Vector3d& e, double gate,
                                                Weighting weighting, const std::vector<int>* group = nullptr,
                                                SkewedEpipolarEquations* by_group = nullptr) {
  SkewedEpipolarEquations eq;
  const Eigen::Matrix<double, 3, 2> B = tangentBasis(t);
  for (size_t i = 0; i < m.size(); ++i) {
    if (group != nullptr && (*group)[i] < 0) continue;
    SkewedEpipolarEquations& to = group != nullptr ? by_group[(*group)[i]] : eq;
    const double s = matchRow(m, i);
    to.add(m.previous(i), skewRotated(m, i, s, R, e), t, B, s, gate, weighting);
  }
  return eq;
}

// fitRowSkew for a general motion: Levenberg-Marquardt on (R, t, e) from the refinement, at its
// adaptive gate with Tukey weights, as refineGeneral's last round.
void fitGeneralRowSkew(FrameMatches& m, double threshold, Eigen::Matrix3d* R, Eigen::Vector3d* t,
                       Eigen::Vector3d* e) {
  rotateAll(m, *R);
  const double gate = adaptiveGate(m, t, threshold);
  SkewedEpipolarEquations here = skewedEpipolarEquations(m, *R, *t, *e, gate, Weighting::kTukey);
  double lambda = 1e-6;
  for (int it = 0; it < 2 * kRowSkewIterations; ++it) {
    auto [A, g] = here.system(*R);
    A.diagonal() += lambda * (A.diagonal().array() + 1e-12).matrix();
    const SkewVector step = A.ldlt().solve(-g);
    if (!step.allFinite()) return;
    const Eigen::Matrix3d R_new = *R * so3Exp(step.head<3>());
    const Eigen::Vector3d t_new = (*t + tangentBasis(*t) * step.segment<2>(3)).normalized();
    const Eigen::Vector3d e_new = *e + step.tail<3>();
    const SkewedEpipolarEquations there = skewedEpipolarEquations(m, R_new, t_new, e_new, gate, Weighting::kTukey);
    if (there.cost <= here.cost) {
      *R = R_new, *t = t_new, *e = e_new;
      here = there;
      lambda = std::max(1e-9, lambda * 0.3);
    } else if ((lambda *= 10.0) > 1e6) {
      return;
    }
    if (step.head<3>().norm() < kConvergedRotation && step.tail<3>().norm() < kConvergedRotation) return;
  }
}

// fitRowSkew for a pure rotation: Gauss-Newton steps on (R, e) from the rigid fit, at its adaptive
// gate with its Huber weights. False where the rows do not determine e.
bool fitPureRowSkew(FrameMatches& m, double threshold, Eigen::Matrix3d* R, Eigen::Vector3d* e) {
  rotateAll(m, *R);
  const double gate_width = adaptiveGate(m, nullptr, threshold);
  for (int it = 0; it < kRowSkewIterations; ++it) {
    const RowSkewEquations eq = rowSkewEquations(m, *R, *e, kRotationGateScale * gate_width, 0.5 * gate_width);
    const Eigen::FullPivLU<Eigen::Matrix<double, 6, 6>> lu(eq.hessian(*R));
    if (!lu.isInvertible()) return false;
    const Eigen::Matrix<double, 6, 1> step = lu.solve(-eq.rhs(*R));
    if (!step.allFinite()) return false;
    *R = *R * so3Exp(step.head<3>());
    *e += step.tail<3>();
    if (step.norm() < kConvergedRotation) break;
  }
  return true;
}

// The full inlier gate of `fit` [rad]: the 2-D pure-rotation residual's is kRotationGateScale times
// the epipolar one's.
double fullGate(const RefinedRotation& fit, double threshold) {
  const bool pure = !isGeneralMotion(fit);
  return pure ? kRotationGateScale * threshold : threshold;
}

// The inliers of `fit` at its full gate, in index order, into scratch.order (its residuals those
// of squaredResidualsOf); returns their count, and with `near` how many usable matches lie between
// one and kNearMissGates gates.
size_t selectInliers(FrameMatches& m, const RefinedRotation& fit, double threshold, size_t* near = nullptr) {
  FrameMatches::Scratch& s = m.scratch;
  const size_t n = m.size();
  squaredResidualsOf(m, fit);
  const double gate = fullGate(fit, threshold);
  const double inside2 = gate * gate, near2 = kNearMissGates * kNearMissGates * inside2;
  s.order.resize(n);
  size_t count = 0, near_count = 0;
  for (size_t i = 0; i < n; ++i) {
    s.order[count] = static_cast<uint32_t>(i);
    const bool counted = usable(s, i);
    count += counted & (s.residuals[i] < inside2);
    near_count += counted & (s.residuals[i] >= inside2) & (s.residuals[i] < near2);
  }
  s.order.resize(count);
  if (near != nullptr) *near = near_count;
  return count;
}

// Each of `groups` spatial groups' (group[i], -1: none) normal equations in the row skew's model
// (pure: rotation, skew; general: rotation, translation, skew) at the fit, from its unweighted
// inliers at the full gate; the skew held at the fit's (its three parameters, the last, left out)
// unless `fit_skew`.
struct GroupSystems {
  std::array<SkewMatrix, kMaxGroups> A;
  std::array<SkewVector, kMaxGroups> g;
  int dim = 0;
  bool fit_skew = true;
};

GroupSystems groupSystems(const FrameMatches& m, const RefinedRotation& fit, double threshold,
                          const std::vector<int>& group, int groups, bool fit_skew) {
  GroupSystems out;
  const bool pure = !isGeneralMotion(fit);
  out.dim = pure ? 6 : 8;
  out.fit_skew = fit_skew;
  if (pure) {
    std::array<RowSkewEquations, kMaxGroups> by_group;
    rowSkewEquations(m, fit.rotation, fit.row_skew, kRotationGateScale * threshold, 0.0, &group, by_group.data());
    for (int k = 0; k < groups; ++k) out.A[k] = by_group[k].hessian(fit.rotation), out.g[k] = by_group[k].rhs(fit.rotation);
  } else {
    std::array<SkewedEpipolarEquations, kMaxGroups> by_group;
    skewedEpipolarEquations(m, fit.rotation, fit.translation, fit.row_skew, threshold, Weighting::kInliers, &group,
                            by_group.data());
    for (int k = 0; k < groups; ++k) std::tie(out.A[k], out.g[k]) = by_group[k].system(fit.rotation);
  }
  for (int k = 0; k < groups && !fit_skew; ++k) {
    out.A[k].bottomRows(3).setZero();
    out.A[k].rightCols(3).setZero();
    out.g[k].tail(3).setZero();
  }
  return out;
}

// The group jackknife of groups [first, first + count) of `systems`: the Gauss-Newton step of
// them all from the fit, and the covariance of its parameters as the spread of the
// leave-one-group-out steps (the full step cancels about their mean, so the spread holds at a fit
// that is no minimum in the skew: a rigid one).
struct GroupJackknife {
  SkewVector step;
  SkewMatrix spread;
};

GroupJackknife jackknifeOver(const GroupSystems& systems, int first, int count) {
  const int dim = systems.dim;
  SkewMatrix A_all = SkewMatrix::Zero(dim, dim);
  SkewVector g_all = SkewVector::Zero(dim);
  for (int k = first; k < first + count; ++k) A_all += systems.A[k], g_all += systems.g[k];
  if (!systems.fit_skew) A_all.bottomRightCorner(3, 3).setIdentity();
  const auto solve = [](SkewMatrix a, const SkewVector& b) -> SkewVector {
    a.diagonal().array() += 1e-12 * (a.diagonal().array().abs() + 1e-12);
    return a.ldlt().solve(-b);
  };
  GroupJackknife out;
  out.step = solve(A_all, g_all);
  Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, 8, kMaxGroups> steps(dim, count);
  for (int k = 0; k < count; ++k) steps.col(k) = solve(A_all - systems.A[first + k], g_all - systems.g[first + k]);
  const SkewVector mean = steps.rowwise().mean();
  out.spread = SkewMatrix::Zero(dim, dim);
  for (int k = 0; k < count; ++k) out.spread.noalias() += (steps.col(k) - mean) * (steps.col(k) - mean).transpose();
  out.spread *= static_cast<double>(count - 1) / count;
  return out;
}

GroupJackknife groupJackknife(const FrameMatches& m, const RefinedRotation& fit, double threshold,
                              const std::vector<int>& group, int groups, bool fit_skew) {
  return jackknifeOver(groupSystems(m, fit, threshold, group, groups, fit_skew), 0, groups);
}

// Hotelling's T^2 = e^T S^-1 e; NaN where e or S is unusable.
double hotellingT2(const Eigen::Vector3d& e, const Eigen::Matrix3d& S) {
  const Eigen::FullPivLU<Eigen::Matrix3d> lu(S);
  if (!e.allFinite() || !lu.isInvertible()) return std::numeric_limits<double>::quiet_NaN();
  return e.dot(lu.inverse() * e);
}

// The inliers of `fit` (scratch.order) in kMaxGroups spatial groups (scratch.group); false with too
// few inliers for them.
bool groupInliers(FrameMatches& m, const RefinedRotation& fit, double threshold) {
  FrameMatches::Scratch& s = m.scratch;
  if (jackknifeGroupsPerAxis(selectInliers(m, fit, threshold)) < kMaxGroupsPerAxis) return false;
  spatialGroups(m, kMaxGroupsPerAxis, &s.order, &s.group);
  return true;
}

// The covariance of a general fit with a skew: sigma^2 (J^T J)^-1 over the unweighted inliers at
// the full gate, its rotation block (the translation and the skew marginalised out).
bool setGeneralSkewFit(FrameMatches& m, double threshold, RefinedRotation* fit) {
  const SkewedEpipolarEquations eq =
      skewedEpipolarEquations(m, fit->rotation, fit->translation, fit->row_skew, threshold, Weighting::kInliers);
  return setFitCovariance(eq.system(fit->rotation).first, eq.cost, eq.used - 8, fit);
}

}  // namespace

// The jackknife sees the errors neighbouring matches share, which the statistical covariance does
// not: a global shutter's spurious skews reach statistical chi^2 values in the hundreds.
// A rolling shutter turns every column of a row alike; an object moving through one side of the
// view (a person walking past, water) changes the rows' rotation there alone, and the rigid fit of
// the whole image can then call for a skew as well (a global-shutter hand-held room with 45 % of its
// matches moving by 2 deg a pair: T^2 up to 175, and the stream taken for a rolling shutter, 1.2
// deg off). So the skews the two halves of the view call for, each with its own rotation, must
// agree: through a rolling shutter their difference stays within the same T^2 bound (at most 21 on
// the rendered rolling-shutter rooms and the near drone), where the moving object's reached 225-357.
double rowSkewSignificance(FrameMatches& m, const RefinedRotation& rigid, double threshold) {
  if (!groupInliers(m, rigid, threshold)) return std::numeric_limits<double>::quiet_NaN();
  const GroupSystems systems = groupSystems(m, rigid, threshold, m.scratch.group, kMaxGroups, true);
  const GroupJackknife whole = jackknifeOver(systems, 0, kMaxGroups);
  const double significance = hotellingT2(whole.step.tail<3>(), whole.spread.bottomRightCorner<3, 3>());
  // Below the bound the frame calls for no skew whatever the halves say.
  if (!(significance > kRowSkewSignificance)) return significance;
  // spatialGroups numbers the groups strip by strip from the left: the first half is the left half.
  const GroupJackknife left = jackknifeOver(systems, 0, kMaxGroups / 2);
  const GroupJackknife right = jackknifeOver(systems, kMaxGroups / 2, kMaxGroups / 2);
  const double disagreement =
      hotellingT2(left.step.tail<3>() - right.step.tail<3>(),
                  left.spread.bottomRightCorner<3, 3>() + right.spread.bottomRightCorner<3, 3>());
  return disagreement > kRowSkewSignificance ? 0.0 : significance;
}

bool fitRowSkew(FrameMatches& m, RefinedRotation* refined, double threshold) {
  RefinedRotation fit = *refined;
  fit.row_skew.setZero();
  if (fit.pure_rotation) {
    if (!fitPureRowSkew(m, threshold, &fit.rotation, &fit.row_skew)) return false;
    setPureRotationFit(m, fit.rotation, fit.row_skew, true, threshold, &fit);
  } else {
    fitGeneralRowSkew(m, threshold, &fit.rotation, &fit.translation, &fit.row_skew);
    if (!setGeneralSkewFit(m, threshold, &fit)) return false;
  }
  if (fit.row_skew.isZero()) return false;
  *refined = fit;
  return true;
}

double inlierHullArea(FrameMatches& m, const RefinedRotation& refined, double threshold) {
  FrameMatches::Scratch& s = m.scratch;
  selectInliers(m, refined, threshold);
  std::vector<std::array<double, 2>>& points = s.plane;
  points.clear();
  for (const uint32_t i : s.order) {
    if (m.pz[i] >= kMinHullDepth) points.push_back({m.px[i] / m.pz[i], m.py[i] / m.pz[i]});
  }
  if (points.size() < 3) return 0.0;
  // Andrew's monotone chain: the lower hull left to right, then the upper one back.
  std::sort(points.begin(), points.end());
  const auto turn = [](const std::array<double, 2>& o, const std::array<double, 2>& a, const std::array<double, 2>& b) {
    return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0]);
  };
  std::vector<std::array<double, 2>>& hull = s.hull;
  hull.resize(2 * points.size());
  size_t k = 0;
  for (size_t i = 0; i < points.size(); ++i) {
    while (k >= 2 && turn(hull[k - 2], hull[k - 1], points[i]) <= 0.0) --k;
    hull[k++] = points[i];
  }
  for (size_t i = points.size() - 1, lower = k + 1; i-- > 0;) {
    while (k >= lower && turn(hull[k - 2], hull[k - 1], points[i]) <= 0.0) --k;
    hull[k++] = points[i];
  }
  // The chain ends where it began; the shoelace formula over its k - 1 distinct corners.
  double twice = 0.0;
  for (size_t i = 0; i + 1 < k; ++i) twice += hull[i][0] * hull[i + 1][1] - hull[i + 1][0] * hull[i][1];
  return 0.5 * std::abs(twice);
}

JackknifeSpread jackknifeSpread(FrameMatches& m, const RefinedRotation& refined, double threshold) {
  JackknifeSpread out;
  FrameMatches::Scratch& s = m.scratch;
  size_t near = 0;
  const size_t count = selectInliers(m, refined, threshold, &near);
  out.near_miss_share = static_cast<double>(near) / static_cast<double>(std::max<size_t>(1, count));
  const int k = jackknifeGroupsPerAxis(count);
  if (k < 2) return out;
  spatialGroups(m, k, &s.order, &s.group);
  // A fitted row skew (never exactly zero) takes part as fitRowSkew fitted it.
  const bool skewed = !refined.row_skew.isZero();
  const GroupJackknife jack = groupJackknife(m, refined, threshold, s.group, k * k, skewed);
  if (!jack.spread.allFinite()) return out;
  out.covariance = jack.spread.topLeftCorner<3, 3>();
  out.groups = k * k;
  return out;
}

JackknifeSpread refitJackknifeSpread(FrameMatches& m, FrameMatches* rest, const RefinedRotation& refined,
                                     double threshold, int iterations) {
  JackknifeSpread out;
  const size_t n = m.size();
  FrameMatches::Scratch& s = m.scratch;
  const int k = jackknifeGroupsPerAxis(n);
  if (k < 2) return out;
  // jackknifeSpread's partition, over every match.
  std::vector<uint32_t>& order = s.all_order;
  order.resize(n);
  for (size_t i = 0; i < n; ++i) order[i] = static_cast<uint32_t>(i);
  std::vector<int>& group = s.all_group;
  spatialGroups(m, k, &order, &group);
  const int groups = k * k;
  std::array<Eigen::Vector3d, kMaxGroups> moved;
  const bool pure = !isGeneralMotion(refined);
  for (int g = 0; g < groups; ++g) {
    rest->assignWithout(m, group, g);
    RefinedRotation again = pure ? refinePureRotation(*rest, refined.rotation, threshold, iterations)
                                 : refineMotion(*rest, refined.rotation, refined.translation, threshold, iterations);
    if (!refined.row_skew.isZero()) fitRowSkew(*rest, &again, threshold);
    moved[g] = so3Log(refined.rotation.transpose() * again.rotation);
    if (!moved[g].allFinite()) return out;
  }
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (int g = 0; g < groups; ++g) mean += moved[g];
  mean /= groups;
  Eigen::Matrix3d spread = Eigen::Matrix3d::Zero();
  for (int g = 0; g < groups; ++g) spread.noalias() += (moved[g] - mean) * (moved[g] - mean).transpose();
  out.covariance = spread * (static_cast<double>(groups - 1) / groups);
  out.groups = groups;
  return out;
}

}  // namespace visual_gyro
