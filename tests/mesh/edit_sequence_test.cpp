// Long random sequences of edits: after every edit the incrementally maintained adjacency must
// equal the one rebuilt from scratch, and every attribute must hold the value its rule specifies.

#include <gtest/gtest.h>

#include <algorithm>
#include <map>
#include <random>

#include "incise/core/error.hpp"
#include "incise/mesh/attributes.hpp"
#include "incise/mesh/generators.hpp"
#include "incise/mesh/operations.hpp"
#include "incise/mesh/tet_mesh.hpp"
#include "incise/mesh/validate.hpp"

namespace incise {
namespace {

double edge_length(const TetMesh& mesh, EdgeId e) {
  const auto& ends = mesh.edge(e);
  return (mesh.rest_position(ends[0]) - mesh.rest_position(ends[1])).norm();
}

/// A mesh with attributes whose correct values are known independently at all times.
struct TrackedMesh {
  explicit TrackedMesh(TetMesh initial)
      : mesh(std::move(initial)),
        position(mesh, Vec3::Zero()),
        length(mesh, -1.0, EdgeRule::kScale),
        volume(mesh, -1.0, TetRule::kDefault),
        ancestor(mesh, -1, TetRule::kCopy) {
    for (std::size_t v = 0; v < mesh.vertex_count(); ++v) {
      position[static_cast<VertexId>(v)] = mesh.rest_position(static_cast<VertexId>(v));
    }
    for (std::size_t e = 0; e < mesh.edge_count(); ++e) {
      length[static_cast<EdgeId>(e)] = edge_length(mesh, static_cast<EdgeId>(e));
    }
    for (std::size_t t = 0; t < mesh.tet_count(); ++t) {
      volume[static_cast<TetId>(t)] = signed_volume(mesh, static_cast<TetId>(t));
      ancestor[static_cast<TetId>(t)] = static_cast<int>(t);
      ancestor_volume[static_cast<int>(t)] = volume[static_cast<TetId>(t)];
    }
    // Edges without a parent edge get their length computed; pieces of split edges must get
    // theirs from the kScale rule alone.
    length.set_hook([](EdgeData<double>& data, const EdgeOrigin& origin) {
      if (origin.parent == kInvalidId) {
        data[origin.edge] = edge_length(*data.mesh(), origin.edge);
      }
    });
    volume.set_hook(
        [](TetData<double>& data, TetId, std::span<const TetId> children, const double&) {
          for (TetId child : children) {
            data[child] = signed_volume(*data.mesh(), child);
          }
        });
  }

  void check(const std::string& after) const {
    ASSERT_EQ(mesh.compare_with_rebuilt_adjacency(), "") << "after " << after;
    ASSERT_EQ(position.size(), mesh.vertex_count());
    ASSERT_EQ(length.size(), mesh.edge_count());
    ASSERT_EQ(volume.size(), mesh.tet_count());
    for (std::size_t v = 0; v < mesh.vertex_count(); ++v) {
      ASSERT_TRUE(position[static_cast<VertexId>(v)].isApprox(
          mesh.rest_position(static_cast<VertexId>(v)), 1e-12))
          << "vertex " << v << " after " << after;
    }
    for (std::size_t e = 0; e < mesh.edge_count(); ++e) {
      ASSERT_NEAR(length[static_cast<EdgeId>(e)], edge_length(mesh, static_cast<EdgeId>(e)), 1e-12)
          << "edge " << e << " after " << after;
    }
    for (std::size_t t = 0; t < mesh.tet_count(); ++t) {
      ASSERT_NEAR(volume[static_cast<TetId>(t)], signed_volume(mesh, static_cast<TetId>(t)), 1e-15)
          << "tet " << t << " after " << after;
    }
  }

  TetMesh mesh;
  VertexData<Vec3> position;
  EdgeData<double> length;
  TetData<double> volume;
  TetData<int> ancestor;
  std::map<int, double> ancestor_volume;
};

class RandomEdits : public ::testing::TestWithParam<std::tuple<unsigned, int>> {};

TEST_P(RandomEdits, AdjacencyAndAttributesStayExact) {
  const auto [seed, tets_per_cell] = GetParam();
  std::mt19937 rng(seed);
  BoxGridOptions options;
  options.cells = {3, 2, 2};
  options.size = Vec3(0.03, 0.02, 0.02);
  options.tets_per_cell = tets_per_cell;
  TrackedMesh tracked(make_box_grid(options));
  TetMesh& mesh = tracked.mesh;
  tracked.check("construction");

  std::uniform_real_distribution<double> unit(0.0, 1.0);
  auto pick = [&](std::size_t n) {
    return static_cast<std::int32_t>(std::uniform_int_distribution<std::size_t>(0, n - 1)(rng));
  };
  auto simplex_weights = [&](auto& weights) {
    double sum = 0.0;
    for (double& w : weights) {
      w = 0.1 + unit(rng);
      sum += w;
    }
    for (double& w : weights) {
      w /= sum;
    }
    weights.back() = 1.0;
    for (std::size_t i = 0; i + 1 < weights.size(); ++i) {
      weights.back() -= weights[i];
    }
  };

  std::vector<Tet> removed;
  bool conserving = true;  // no removal or re-adding yet: volume per ancestor is conserved
  const int operations = 600;
  for (int step = 0; step < operations; ++step) {
    const double choice = unit(rng);
    std::string what;
    if (choice < 0.3) {
      (void)split_edge(mesh, pick(mesh.edge_count()), 0.2 + 0.6 * unit(rng));
      what = "split_edge";
    } else if (choice < 0.5) {
      std::array<double, 3> weights{};
      simplex_weights(weights);
      (void)split_face(mesh, pick(mesh.tet_count()), pick(4), weights);
      what = "split_face";
    } else if (choice < 0.7) {
      std::array<double, 4> weights{};
      simplex_weights(weights);
      (void)split_tet(mesh, pick(mesh.tet_count()), weights);
      what = "split_tet";
    } else if (choice < 0.85 || !conserving) {
      const VertexId v = pick(mesh.vertex_count());
      std::vector<TetId> around(mesh.vertex_tets(v).begin(), mesh.vertex_tets(v).end());
      std::shuffle(around.begin(), around.end(), rng);
      if (!around.empty()) {
        around.resize(1 + static_cast<std::size_t>(pick(around.size())));
      }
      mesh.duplicate_vertex(v, around);
      what = "duplicate_vertex";
    }
    if (what.empty() || (step > operations / 2 && choice > 0.95)) {
      if (!removed.empty() && unit(rng) < 0.5) {
        const auto index = static_cast<std::size_t>(pick(removed.size()));
        const TetId t = mesh.add_tet(removed[index]);
        tracked.volume[t] = signed_volume(mesh, t);
        removed.erase(removed.begin() + static_cast<std::ptrdiff_t>(index));
        what = "add_tet";
      } else if (mesh.tet_count() > 1) {
        const TetId t = pick(mesh.tet_count());
        removed.push_back(mesh.tet(t));
        mesh.remove_tet(t);
        what = "remove_tet";
      }
      conserving = false;
    }
    tracked.check(what + " at step " + std::to_string(step));
    if (::testing::Test::HasFatalFailure()) {
      return;
    }
    if (conserving) {
      // Splits never change what each original tetrahedron covers.
      std::map<int, double> sums;
      for (std::size_t t = 0; t < mesh.tet_count(); ++t) {
        sums[tracked.ancestor[static_cast<TetId>(t)]] += signed_volume(mesh, static_cast<TetId>(t));
      }
      for (const auto& [id, original] : tracked.ancestor_volume) {
        ASSERT_NEAR(sums[id], original, 1e-12 * original) << "ancestor " << id;
      }
    }
  }
  EXPECT_GT(mesh.tet_count(), 500u);
}

INSTANTIATE_TEST_SUITE_P(Seeds, RandomEdits,
                         ::testing::Combine(::testing::Values(1u, 2u, 3u),
                                            ::testing::Values(5, 6)));

/// `steps` random splits (of an edge at `edge_fraction`, a face or a tetrahedron).
void split_at_random(TetMesh& mesh, std::mt19937& rng, int steps, double edge_fraction) {
  for (int step = 0; step < steps; ++step) {
    const auto t = static_cast<TetId>(rng() % mesh.tet_count());
    switch (rng() % 3) {
      case 0:
        (void)split_edge(mesh, mesh.tet_edges(t)[rng() % 6], edge_fraction);
        break;
      case 1:
        (void)split_face(mesh, t, static_cast<int>(rng() % 4), {0.3, 0.3, 0.4});
        break;
      default:
        (void)split_tet(mesh, t, {0.25, 0.25, 0.25, 0.25});
    }
  }
}

TEST(RandomEdits, CollapsesKeepTheAdjacencyExact) {
  // A grid split up at random, then random edges collapsed (the cutter's blade-line vertices
  // are collapsed a hundred times a pose): after each collapse the adjacency the edit kept
  // equals the one rebuilt from scratch, and a refused one changes nothing.
  std::mt19937 rng(7);
  BoxGridOptions options;
  options.cells = {3, 3, 2};
  TetMesh mesh = make_box_grid(options);
  split_at_random(mesh, rng, 400, 0.3);
  int collapsed = 0;
  int refused = 0;
  for (int step = 0; step < 600; ++step) {
    const auto t = static_cast<TetId>(rng() % mesh.tet_count());
    const auto& ends = tet_local::kEdges[rng() % 6];
    const VertexId vertex = mesh.tet(t)[ends[0]];
    const VertexId target = mesh.tet(t)[ends[1]];
    const std::uint64_t revision = mesh.revision();
    try {
      mesh.collapse_vertex(vertex, target);
      ++collapsed;
      EXPECT_TRUE(mesh.vertex_tets(vertex).empty());
    } catch (const InputError&) {
      ++refused;
      ASSERT_EQ(mesh.revision(), revision);
    }
    ASSERT_EQ(mesh.compare_with_rebuilt_adjacency(), "") << "after collapse " << step;
  }
  EXPECT_GT(collapsed, 100);
  EXPECT_GT(refused, 10);
}

TEST(RandomEdits, SplitsKeepTheMeshValid) {
  std::mt19937 rng(42);
  BoxGridOptions options;
  options.cells = {2, 2, 2};
  TetMesh mesh = make_box_grid(options);
  const double volume = total_volume(mesh);
  split_at_random(mesh, rng, 300, 0.5);
  const auto report = validate(mesh, {.degenerate_tolerance = 0.0});
  EXPECT_TRUE(report.ok()) << report.describe();
  EXPECT_NEAR(total_volume(mesh), volume, 1e-12);
}

}  // namespace
}  // namespace incise
