// Packed rows (core/packed_rows.hpp) and vertex marks (mesh/vertex_marks.hpp): the two pieces
// that let a model update only what an edit touched.

#include "incise/core/packed_rows.hpp"

#include <gtest/gtest.h>

#include <random>
#include <vector>

#include "incise/mesh/generators.hpp"
#include "incise/mesh/vertex_marks.hpp"

namespace incise {
namespace {

std::vector<int> as_vector(std::span<const int> row) {
  return {row.begin(), row.end()};
}

TEST(PackedRows, RowsRewrittenInAnyOrderReadBackAsWrittenAndCompactionKeepsThem) {
  std::mt19937 rng(3);
  std::vector<std::vector<int>> expected(50);
  PackedRows<int> rows;
  rows.assign(expected.size(), [&](std::size_t i) {
    expected[i].assign(i % 7, static_cast<int>(i));
    return std::span<const int>(expected[i]);
  });
  bool compacted = false;
  for (int edit = 0; edit < 2000; ++edit) {
    const std::size_t i = rng() % expected.size();
    std::vector<int> values(rng() % 12);
    for (int& v : values) {
      v = static_cast<int>(rng() % 1000);
    }
    const bool changed = values != expected[i];
    EXPECT_EQ(rows.set_row(i, values), changed);
    expected[i] = values;
    if (edit % 50 == 0) {
      expected.emplace_back();
      rows.add_rows(expected.size());
    }
    compacted = rows.compact_if_fragmented() || compacted;
    // Left behind never more than a quarter after a compaction check.
    ASSERT_LT(4 * (rows.storage().size() - rows.live()), rows.storage().size() + 4);
  }
  EXPECT_TRUE(compacted);
  ASSERT_EQ(rows.rows(), expected.size());
  std::size_t live = 0;
  for (std::size_t i = 0; i < expected.size(); ++i) {
    EXPECT_EQ(as_vector(rows.row(i)), expected[i]) << "row " << i;
    live += expected[i].size();
  }
  EXPECT_EQ(rows.live(), live);
}

TEST(PackedRows, ARowThatFitsStaysInPlaceAndOneThatGrowsMovesAlone) {
  PackedRows<int> rows;
  const std::vector<std::vector<int>> start{{1, 2, 3}, {4, 5}, {6}};
  rows.assign(3, [&](std::size_t i) { return std::span<const int>(start[i]); });
  const std::size_t first = rows.begin()[0];
  const std::vector<int> shorter{7, 8};
  EXPECT_TRUE(rows.set_row(0, shorter));
  EXPECT_EQ(rows.begin()[0], first);  // in place
  const std::vector<int> longer{1, 2, 3, 4, 5};
  const std::size_t second = rows.begin()[1];
  EXPECT_TRUE(rows.set_row(2, longer));
  EXPECT_GE(rows.begin()[2], 6u);      // moved past the packed rows
  EXPECT_EQ(rows.begin()[1], second);  // the others stay
  EXPECT_EQ(as_vector(rows.row(1)), (std::vector<int>{4, 5}));
  EXPECT_EQ(as_vector(rows.row(2)), longer);
}

TEST(VertexMarks, MarkWhatAnEditTouchedIncludingARenumberedTetrahedron) {
  BoxGridOptions grid;
  grid.cells = {2, 2, 2};
  TetMesh mesh = make_box_grid(grid);
  VertexMarks marks(mesh);
  EXPECT_TRUE(marks.empty());
  const auto first = static_cast<TetId>(0);
  const Tet removed = mesh.tet(first);
  const Tet last = mesh.tet(static_cast<TetId>(mesh.tet_count() - 1));
  mesh.remove_tet(first);  // the last tetrahedron takes id 0
  for (VertexId v : removed) {
    EXPECT_TRUE(marks.is_marked(v)) << v;
  }
  for (VertexId v : last) {
    EXPECT_TRUE(marks.is_marked(v)) << v << ": the renumbered tetrahedron's vertex";
  }
  EXPECT_LT(marks.size(), mesh.vertex_count());
  marks.clear();
  EXPECT_TRUE(marks.empty());
  EXPECT_FALSE(marks.is_marked(removed[0]));
  marks.mark_all();
  EXPECT_EQ(marks.size(), mesh.vertex_count());
}

}  // namespace
}  // namespace incise
