// The mesh's flat edge index against std::unordered_map under random inserts, overwrites and
// erases: small tables, so probes wrap around the end and erases shift runs back across it.

#include "incise/mesh/edge_index.hpp"

#include <gtest/gtest.h>

#include <random>
#include <unordered_map>

#include "incise/mesh/tet_mesh.hpp"

namespace incise {
namespace {

TEST(EdgeIndex, AgreesWithAHashMapUnderRandomEdits) {
  for (const int vertices : {6, 40, 3000}) {
    std::mt19937 random(static_cast<unsigned>(vertices));
    std::uniform_int_distribution<int> vertex(0, vertices - 1);
    std::uniform_int_distribution<int> action(0, 9);
    EdgeIndex index;
    std::unordered_map<std::uint64_t, EdgeId> reference;
    for (int step = 0; step < 20000; ++step) {
      const int a = vertex(random);
      const int b = vertex(random);
      const std::uint64_t key = edge_key(a, b);
      const int what = action(random);
      if (what < 5) {
        const auto [stored, inserted] = index.try_emplace(key, step);
        const auto [it, expected] = reference.try_emplace(key, step);
        ASSERT_EQ(inserted, expected) << "step " << step;
        ASSERT_EQ(stored, it->second) << "step " << step;
      } else if (what < 6) {
        index.assign(key, -step - 2);
        reference[key] = -step - 2;
      } else if (what < 9) {
        ASSERT_EQ(index.erase(key), reference.erase(key) == 1) << "step " << step;
      } else {
        const auto it = reference.find(key);
        ASSERT_EQ(index.find(key), it == reference.end() ? kInvalidId : it->second);
      }
      ASSERT_EQ(index.size(), reference.size());
    }
    // Every key still reachable after all the backward shifts, and no other.
    for (int a = 0; a < std::min(vertices, 200); ++a) {
      for (int b = a; b < std::min(vertices, 200); ++b) {
        const auto it = reference.find(edge_key(a, b));
        ASSERT_EQ(index.find(edge_key(a, b)), it == reference.end() ? kInvalidId : it->second);
      }
    }
    EdgeIndex moved = std::move(index);
    EXPECT_EQ(moved.size(), reference.size());
    EXPECT_EQ(index.size(), 0u);  // NOLINT(bugprone-use-after-move): moved-from is empty
    EXPECT_EQ(index.find(edge_key(0, 1)), kInvalidId);
    moved.clear();
    EXPECT_EQ(moved.size(), 0u);
    EXPECT_EQ(moved.find(edge_key(0, 1)), kInvalidId);
  }
}

}  // namespace
}  // namespace incise
