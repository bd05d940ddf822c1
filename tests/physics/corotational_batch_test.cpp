// The four-element kernel against the one-element functions it restates: every lane as
// deformation_gradient, polar_rotation, corotated_stress and R grad N would give it, for
// elements mildly and wildly deformed, inverted, flattened and non-finite; and an element's
// result the same bits whatever lane it was given in.

#include "incise/physics/corotational_batch.hpp"

#include <gtest/gtest.h>

#include <limits>
#include <random>
#include <vector>

namespace incise {
namespace {

struct Element {
  Corners x;
  TetRestShape shape;
  LameParameters lame;
  double stress_scale = 0.0;
  Eigen::Quaterniond start = Eigen::Quaterniond::Identity();
};

Eigen::Quaterniond random_quaternion(std::mt19937& random) {
  std::normal_distribution<double> normal;
  Eigen::Quaterniond q(normal(random), normal(random), normal(random), normal(random));
  q.normalize();
  return q;
}

/// Elements of random shape and material under deformations of the kinds a step meets: small
/// strain near a warm start, large rotation from a stale one, inversion, flattening.
Element random_element(std::mt19937& random, int kind) {
  std::uniform_real_distribution<double> uniform(-1.0, 1.0);
  Element element;
  Corners rest;
  do {
    for (Vec3& corner : rest) {
      corner = 0.01 * Vec3(uniform(random), uniform(random), uniform(random));
    }
    if ((rest[1] - rest[0]).cross(rest[2] - rest[0]).dot(rest[3] - rest[0]) < 0.0) {
      std::swap(rest[1], rest[2]);
    }
  } while ((rest[1] - rest[0]).cross(rest[2] - rest[0]).dot(rest[3] - rest[0]) < 1e-8);
  element.shape = tet_rest_shape(rest);
  element.lame = lame_parameters(1e3 * (1.0 + 9.0 * std::abs(uniform(random))),
                                 0.3 + 0.19 * std::abs(uniform(random)));
  element.stress_scale = -element.shape.volume * (0.1 + std::abs(uniform(random)));
  const Eigen::Quaterniond turn = random_quaternion(random);
  Mat3 stretch = Mat3::Identity();
  for (int k = 0; k < 9; ++k) {
    stretch(k) += (kind == 0 ? 0.02 : 0.4) * uniform(random);
  }
  if (kind == 2) {
    stretch.row(0) *= -1.0;  // inverted
  }
  if (kind == 3) {
    stretch.row(2) *= 1e-9;  // flattened almost to a plane
  }
  const Mat3 F = turn.toRotationMatrix() * stretch;
  const Vec3 shift(uniform(random), uniform(random), uniform(random));
  for (int a = 0; a < 4; ++a) {
    element.x[a] = F * rest[a] + shift;
  }
  // Kind 0 starts from a warm start 0.01 rad off the answer, as after a step; the others
  // from anywhere.
  const Eigen::Quaterniond answer(polar_rotation_svd(F));
  const Vec3 axis = Vec3(uniform(random), uniform(random), uniform(random)).normalized();
  element.start = kind == 0 ? answer * Eigen::Quaterniond(Eigen::AngleAxisd(0.01, axis))
                            : random_quaternion(random);
  return element;
}

void put(CorotatedBatch& batch, int lane, const Element& element) {
  for (int a = 0; a < 4; ++a) {
    set_lane_vector(batch.corners[a], lane, element.x[a]);
    set_lane_vector(batch.gradients[a], lane, element.shape.gradients[a]);
  }
  batch.mu[lane] = element.lame.mu;
  batch.lambda[lane] = element.lame.lambda;
  batch.stress_scale[lane] = element.stress_scale;
  set_lane_quaternion(batch, lane, element.start);
}

/// Checks lane `lane` against the one-element functions.
void expect_lane_matches(const CorotatedBatch& batch, int lane, const Element& element) {
  const Mat3 F = deformation_gradient(element.x, element.shape);
  Eigen::Quaterniond start = element.start;
  const Mat3 R = polar_rotation(F, start);
  const Mat3 stress = element.stress_scale * corotated_stress(F, R, element.lame);
  const double f_scale = 1.0 + F.norm();
  EXPECT_LT((lane_matrix(batch.deformation, lane) - F).norm(), 1e-12 * f_scale);
  EXPECT_LT((lane_matrix(batch.rotation, lane) - R).norm(), 1e-9) << "lane " << lane;
  EXPECT_LT((lane_matrix(batch.scaled_stress, lane) - stress).norm(), 1e-8 * (1.0 + stress.norm()))
      << "lane " << lane;
  const Eigen::Quaterniond found = lane_quaternion(batch, lane);
  EXPECT_NEAR(found.norm(), 1.0, 1e-12);
  EXPECT_LT((found.toRotationMatrix() - lane_matrix(batch.rotation, lane)).norm(), 1e-12);
  for (int a = 0; a < 4; ++a) {
    const Vec3 rotated = lane_vector(batch.rotated_gradients[a], lane);
    EXPECT_LT((rotated - R * element.shape.gradients[a]).norm(),
              1e-9 * element.shape.gradients[a].norm());
  }
}

using BatchKernel = void (*)(CorotatedBatch&, int);

class CorotatedBatchKernels : public testing::TestWithParam<BatchKernel> {};

// The dispatched kernel (AVX2 where the CPU has it) and the portable build.
INSTANTIATE_TEST_SUITE_P(BothBuilds, CorotatedBatchKernels,
                         testing::Values(&corotated_batch, &detail::corotated_batch_portable));

TEST_P(CorotatedBatchKernels, EveryLaneMatchesTheOneElementFunctions) {
  std::mt19937 random(7);
  for (int trial = 0; trial < 400; ++trial) {
    const int count = 1 + trial % kElementLanes;
    std::vector<Element> elements;
    CorotatedBatch batch{};
    for (int lane = 0; lane < count; ++lane) {
      elements.push_back(random_element(random, (trial / 4 + lane) % 4));
      put(batch, lane, elements.back());
    }
    GetParam()(batch, count);
    for (int lane = 0; lane < count; ++lane) {
      expect_lane_matches(batch, lane, elements[static_cast<std::size_t>(lane)]);
    }
  }
}

TEST(CorotatedBatch, AnElementsResultDoesNotDependOnItsLaneOrItsNeighbours) {
  std::mt19937 random(11);
  for (int kind = 0; kind < 4; ++kind) {
    const Element element = random_element(random, kind);
    CorotatedBatch first{};
    put(first, 0, element);
    corotated_batch(first, 1);
    for (int lane = 0; lane < kElementLanes; ++lane) {
      CorotatedBatch batch{};
      for (int other = 0; other < kElementLanes; ++other) {
        put(batch, other, other == lane ? element : random_element(random, (kind + other) % 4));
      }
      corotated_batch(batch, kElementLanes);
      for (int k = 0; k < 9; ++k) {
        EXPECT_EQ(batch.rotation[k][lane], first.rotation[k][0]) << kind;
        EXPECT_EQ(batch.scaled_stress[k][lane], first.scaled_stress[k][0]) << kind;
      }
    }
  }
}

TEST_P(CorotatedBatchKernels, ANonFiniteElementGetsTheIdentityAndLeavesTheOthersAlone) {
  std::mt19937 random(13);
  std::vector<Element> elements;
  CorotatedBatch batch{};
  for (int lane = 0; lane < kElementLanes; ++lane) {
    elements.push_back(random_element(random, 0));
    put(batch, lane, elements.back());
  }
  batch.corners[2][1][1] = std::numeric_limits<double>::quiet_NaN();
  batch.corners[0][0][3] = std::numeric_limits<double>::infinity();
  GetParam()(batch, kElementLanes);
  for (int lane : {1, 3}) {
    EXPECT_TRUE(lane_matrix(batch.rotation, lane).isIdentity()) << lane;
  }
  for (int lane : {0, 2}) {
    expect_lane_matches(batch, lane, elements[static_cast<std::size_t>(lane)]);
  }
}

using RowKernel = void (*)(const std::array<Mat3*, 4>&, const Vec3&, const Vec3&,
                           const std::array<Vec3, 4>&, const std::array<double, 4>&);

class WarpedRowKernels : public testing::TestWithParam<RowKernel> {};

INSTANTIATE_TEST_SUITE_P(BothBuilds, WarpedRowKernels,
                         testing::Values(&add_warped_stiffness_row,
                                         &detail::add_warped_stiffness_row_portable));

TEST_P(WarpedRowKernels, AddTheSameBlocksAsOneBlockAtATime) {
  std::mt19937 random(17);
  std::uniform_real_distribution<double> uniform(-1.0, 1.0);
  const auto random_vector = [&] {
    return Vec3(uniform(random), uniform(random), uniform(random));
  };
  for (int trial = 0; trial < 50; ++trial) {
    const Vec3 lambda_a = 1e3 * random_vector();
    const Vec3 mu_a = 1e2 * random_vector();
    std::array<Vec3, 4> rotated;
    std::array<double, 4> diagonal;
    // Each block starts from what earlier elements left in it; every entry is checked.
    std::array<Mat3, 4> blocks;
    std::array<Mat3, 4> expected;
    for (std::size_t b = 0; b < 4; ++b) {
      rotated[b] = 50.0 * random_vector();
      diagonal[b] = 1e3 * uniform(random);
      blocks[b] = 1e4 * Mat3::Random();
      expected[b] = blocks[b];
      add_warped_stiffness_block(expected[b], lambda_a, mu_a, rotated[b], diagonal[b]);
    }
    GetParam()({&blocks[0], &blocks[1], &blocks[2], &blocks[3]}, lambda_a, mu_a, rotated, diagonal);
    for (std::size_t b = 0; b < 4; ++b) {
      EXPECT_LT((blocks[b] - expected[b]).cwiseAbs().maxCoeff(), 1e-9 * expected[b].norm())
          << "block " << b << "\n"
          << blocks[b] << "\n"
          << expected[b];
    }
  }
}

}  // namespace
}  // namespace incise
