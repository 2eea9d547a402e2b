// How evaluate makes its pairs harder: the independently moving region of --moving-region.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "frame_pairs.h"
#include "visual_gyro/geometry.h"

namespace visual_gyro {
namespace {

// A pure rotation seen by bearings spread over a grid: previous = R * current for every match.
eval::FramePair rotatedGrid(const Eigen::Matrix3d& R) {
  eval::FramePair p;
  for (int row = 0; row < 5; ++row)
    for (int column = 0; column < 8; ++column) {
      const Eigen::Vector3d current = Eigen::Vector3d(-0.4 + 0.1 * column, -0.2 + 0.1 * row, 1.0).normalized();
      p.current.push_back(current);
      p.previous.push_back(R * current);
    }
  return p;
}

TEST(FramePairs, MovingRegionTurnsTheRightmostMatchesByItsAngle) {
  const Eigen::Matrix3d R = so3Exp(Eigen::Vector3d(0.01, -0.02, 0.005));
  const eval::FramePair original = rotatedGrid(R);
  eval::FramePair moved = original;
  eval::moveRegion(0.25, 2.0, &moved);  // 10 of 40 matches: the two rightmost columns
  const Eigen::Matrix3d turn = so3Exp(2.0 * kDegToRad * Eigen::Vector3d::UnitY());
  double cut = -1.0;  // the leftmost previous x / z among the moved matches
  size_t count = 0;
  for (size_t i = 0; i < original.current.size(); ++i) {
    EXPECT_EQ(moved.previous[i], original.previous[i]) << "match " << i << ": the previous image is left alone";
    if (moved.current[i] == original.current[i]) continue;
    ++count;
    EXPECT_LT((moved.current[i] - turn * original.current[i]).norm(), 1e-12) << "match " << i;
    cut = cut < 0.0 ? original.previous[i].x() / original.previous[i].z()
                    : std::min(cut, original.previous[i].x() / original.previous[i].z());
  }
  ASSERT_EQ(count, 10u);
  for (size_t i = 0; i < original.current.size(); ++i)
    if (moved.current[i] == original.current[i])
      EXPECT_LT(original.previous[i].x() / original.previous[i].z(), cut) << "match " << i << " lies right of the region";
  // The moved matches now disagree with the camera's rotation by the region's own angle.
  for (size_t i = 0; i < original.current.size(); ++i)
    if (moved.current[i] != original.current[i])
      EXPECT_GT(std::acos(std::min(1.0, moved.previous[i].dot(R * moved.current[i]))), 1.5 * kDegToRad);
}

TEST(FramePairs, NoMovingRegionLeavesThePairAlone) {
  const eval::FramePair original = rotatedGrid(Eigen::Matrix3d::Identity());
  eval::FramePair moved = original;
  eval::moveRegion(0.0, 2.0, &moved);
  EXPECT_EQ(moved.current, original.current);
  eval::moveRegion(1.0, 0.0, &moved);
  EXPECT_EQ(moved.current, original.current);
}

}  // namespace
}  // namespace visual_gyro
