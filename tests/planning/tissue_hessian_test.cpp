// The planning Hessian's assembly (src/planning/tissue_pattern.cpp, an internal header, tested
// white-box): each prism's tetrahedra and volume term gathered as blocks on and above the
// diagonal and added through targets looked up once must give the matrix that the element
// functions, each checked against finite differences elsewhere, give when scattered plainly.

#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>
#include <random>
#include <vector>

#include "../../src/planning/tissue_pattern.hpp"
#include "incise/physics/stable_neo_hookean.hpp"
#include "incise/planning/layered_tissue.hpp"
#include "incise/planning/prism.hpp"
#include "tissue_support.hpp"

namespace {

using namespace incise;
using namespace incise::planning;

/// A sparse matrix's lower triangle as the dense symmetric matrix.
Eigen::MatrixXd dense_symmetric(const DirectFactorization::SparseMatrix& lower) {
  const Eigen::MatrixXd l = Eigen::MatrixXd(lower);
  Eigen::MatrixXd full = l + l.transpose();
  full.diagonal() = l.diagonal();
  return full;
}

/// The prisms' Hessian (tetrahedra and volume term) over the soft points, dense, from the
/// element functions' full matrices scattered entry by entry.
Eigen::MatrixXd plain_hessian(const LayeredTissue& tissue, const std::vector<int>& row, int rows,
                              std::span<const Vec3> x, bool convex) {
  Eigen::MatrixXd h = Eigen::MatrixXd::Zero(rows, rows);
  const auto add = [&](int a, int b, const Mat3& block) {
    const int ra = row[static_cast<std::size_t>(a)];
    const int rb = row[static_cast<std::size_t>(b)];
    if (ra >= 0 && rb >= 0) {
      h.block<3, 3>(ra, rb) += block;
    }
  };
  for (const Prism& prism : tissue.prisms) {
    for (const PrismTet& tet : prism.tets) {
      if (tet.rest.volume == 0.0) {
        continue;
      }
      const ElementMatrix k =
          neo_hookean_stiffness(tet_corners(prism, tet, x), tet.rest, prism.material, convex);
      for (int a = 0; a < 4; ++a) {
        for (int b = 0; b < 4; ++b) {
          add(prism.points[tet.corners[static_cast<std::size_t>(a)]],
              prism.points[tet.corners[static_cast<std::size_t>(b)]], k.block<3, 3>(3 * a, 3 * b));
        }
      }
    }
    PrismPoints corners;
    for (std::size_t i = 0; i < 6; ++i) {
      corners[i] = x[static_cast<std::size_t>(prism.points[i])];
    }
    const std::array<Vec3, 6> dv = prism_volume_gradient(corners);
    const double weight = tissue.volume_weight / std::abs(prism.rest_volume);
    const PrismHessian curvature = prism_volume_hessian(corners);
    const double change = prism_volume(corners) - prism.rest_volume;
    for (int i = 0; i < 6; ++i) {
      for (int j = 0; j < 6; ++j) {
        Mat3 block =
            weight * dv[static_cast<std::size_t>(i)] * dv[static_cast<std::size_t>(j)].transpose();
        if (!convex) {
          block += weight * change * curvature.block<3, 3>(3 * i, 3 * j);
        }
        add(prism.points[static_cast<std::size_t>(i)], prism.points[static_cast<std::size_t>(j)],
            block);
      }
    }
  }
  return h;
}

TEST(TissueHessian, PrismBlocksAddedThroughTheirTargetsGiveThePlainlyScatteredMatrix) {
  LayeredTissueOptions o;
  o.elasticity = TissueElasticity::kContinuum;
  o.layers = 2;
  o.materials = {LayerMaterial{2e4, 1050.0}};
  o.volume_weight = 1e4;
  o.max_thickness = 0.03;
  const LayeredTissue tissue =
      build_layered_tissue(incise::testing::sphere(0.05, 2), incise::testing::sphere(0.04, 2), o);
  std::vector<int> row(tissue.point_count(), -1);
  int rows = 0;
  for (std::size_t i = 0; i < row.size(); ++i) {
    if (tissue.kind[i] == PointKind::kSoft) {
      row[i] = rows;
      rows += 3;
    }
  }
  ASSERT_GT(rows, 0);
  // Positions off the rest state (every term nonzero, the determinant's curvature too).
  std::mt19937 random(11);
  std::uniform_real_distribution<double> offset(-0.002, 0.002);  // m
  std::vector<Vec3> x = tissue.rest;
  for (Vec3& p : x) {
    p += Vec3(offset(random), offset(random), offset(random));
  }
  const CouplingPattern pattern = coupling_pattern(tissue);
  PointBlockMatrix matrix(row, rows, pattern.pairs);
  const std::vector<PointBlockMatrix::Target> targets = prism_targets(tissue, pattern, matrix);
  for (const bool convex : {false, true}) {
    SCOPED_TRACE(convex ? "convex" : "exact");
    matrix.clear();
    add_prism_hessians(tissue, targets, x, {.tets = true, .volume = true, .convex = convex},
                       matrix);
    const Eigen::MatrixXd assembled = dense_symmetric(matrix.matrix());
    const Eigen::MatrixXd expected = plain_hessian(tissue, row, rows, x, convex);
    EXPECT_LT((assembled - expected).cwiseAbs().maxCoeff(), 1e-9 * expected.cwiseAbs().maxCoeff());
    // Its diagonal through damp_diagonal (relative 1, absolute 2: d -> 2 d + 2).
    matrix.damp_diagonal(1.0, 2.0);
    const Eigen::MatrixXd damped = dense_symmetric(matrix.matrix());
    EXPECT_LT(((damped - assembled).diagonal() - (assembled.diagonal().array() + 2.0).matrix())
                  .cwiseAbs()
                  .maxCoeff(),
              1e-9 * expected.cwiseAbs().maxCoeff());
    Eigen::MatrixXd off_diagonal = damped - assembled;
    off_diagonal.diagonal().setZero();
    EXPECT_EQ(off_diagonal.cwiseAbs().maxCoeff(), 0.0);
  }
}

}  // namespace
