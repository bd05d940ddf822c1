#include "incise/cut/tet_grid.hpp"

#include <algorithm>
#include <cmath>

#include "incise/core/clamped_floor.hpp"
#include "incise/core/error.hpp"

namespace incise {

TetGrid::TetGrid(TetMesh& mesh, const VertexData<Vec3>* positions, double cell_size)
    : mesh_(&mesh), positions_(positions) {
  Vec3 low = Vec3::Zero();
  Vec3 high = Vec3::Zero();
  for (std::size_t v = 0; v < mesh.vertex_count(); ++v) {
    const Vec3& p = position(static_cast<VertexId>(v));
    low = v == 0 ? p : low.cwiseMin(p);
    high = v == 0 ? p : high.cwiseMax(p);
  }
  if (cell_size <= 0.0) {
    double sum = 0.0;
    for (std::size_t e = 0; e < mesh.edge_count(); ++e) {
      const auto& ends = mesh.edge(static_cast<EdgeId>(e));
      sum += (position(ends[0]) - position(ends[1])).norm();
    }
    cell_size = mesh.edge_count() > 0 ? sum / static_cast<double>(mesh.edge_count()) : 1.0;
  }
  // At most about 4 cells per tetrahedron, so memory stays proportional to the mesh.
  const Vec3 extent = (high - low).cwiseMax(Vec3::Constant(1e-12));
  const double budget = 4.0 * static_cast<double>(std::max<std::size_t>(mesh.tet_count(), 1));
  while (extent.x() / cell_size * extent.y() / cell_size * extent.z() / cell_size > budget) {
    cell_size *= 1.26;
  }
  cell_ = cell_size;
  origin_ = low;
  for (int k = 0; k < 3; ++k) {
    dims_[k] = std::max(1L, static_cast<long>(std::ceil(extent[k] / cell_)));
  }
  cells_.assign(static_cast<std::size_t>(dims_[0] * dims_[1] * dims_[2]), {});
  refit();
  mesh.add_observer(this);
}

void TetGrid::refit() {
  pending_.clear();
  for (auto& cell : cells_) {
    cell.clear();
  }
  for (std::size_t t = 0; t < mesh_->tet_count(); ++t) {
    insert(static_cast<TetId>(t), mesh_->tet(static_cast<TetId>(t)));
  }
}

TetGrid::~TetGrid() {
  if (mesh_ != nullptr) {
    mesh_->remove_observer(this);
  }
}

std::size_t TetGrid::cell_index(long i, long j, long k) const {
  return static_cast<std::size_t>((k * dims_[1] + j) * dims_[0] + i);
}

void TetGrid::cell_range(const Vec3& low, const Vec3& high, std::array<long, 3>& first,
                         std::array<long, 3>& last) const {
  // Points outside the grid fall into its border cells (a deformed body may leave the box the
  // grid was built on; that costs speed, not correctness). Clamped before the conversion: a
  // point far off (a blade pose in a path, a diverging body) has no cell number a long holds.
  const auto cell = [&](double x, int axis) {
    return clamped_floor((x - origin_[axis]) / cell_, 0, dims_[axis] - 1);
  };
  for (int k = 0; k < 3; ++k) {
    first[k] = cell(low[k], k);
    last[k] = cell(high[k], k);
  }
}

void TetGrid::bounds(const Tet& tet, Vec3& low, Vec3& high) const {
  low = high = position(tet[0]);
  for (int i = 1; i < 4; ++i) {
    low = low.cwiseMin(position(tet[i]));
    high = high.cwiseMax(position(tet[i]));
  }
}

template <typename Visit>
void TetGrid::for_each_cell_in_box(const Vec3& low, const Vec3& high, Visit visit) const {
  std::array<long, 3> first;
  std::array<long, 3> last;
  cell_range(low, high, first, last);
  for (long k = first[2]; k <= last[2]; ++k) {
    for (long j = first[1]; j <= last[1]; ++j) {
      for (long i = first[0]; i <= last[0]; ++i) {
        visit(cell_index(i, j, k));
      }
    }
  }
}

template <typename Visit>
void TetGrid::for_each_cell(const Tet& vertices, Visit visit) const {
  Vec3 low;
  Vec3 high;
  bounds(vertices, low, high);
  for_each_cell_in_box(low, high, [&](std::size_t cell) { visit(cells_[cell]); });
}

void TetGrid::insert(TetId tet, const Tet& vertices) const {
  for_each_cell(vertices, [tet](std::vector<TetId>& cell) { cell.push_back(tet); });
}

void TetGrid::erase(TetId tet, const Tet& vertices) {
  for_each_cell(vertices, [tet](std::vector<TetId>& cell) {
    const auto it = std::find(cell.begin(), cell.end(), tet);
    INCISE_ASSERT(it != cell.end(), "tet grid misses an entry");
    *it = cell.back();
    cell.pop_back();
  });
}

void TetGrid::rename(TetId from, TetId to, const Tet& vertices) {
  for_each_cell(vertices, [from, to](std::vector<TetId>& cell) {
    std::replace(cell.begin(), cell.end(), from, to);
  });
}

void TetGrid::file_pending() const {
  for (TetId tet : pending_) {
    insert(tet, mesh_->tet(tet));
  }
  pending_.clear();
}

void TetGrid::on_vertex_relocating(const TetMesh& mesh, VertexId vertex) {
  file_pending();
  for (TetId tet : mesh.vertex_tets(vertex)) {
    erase(tet, mesh.tet(tet));
    pending_.push_back(tet);
  }
}

void TetGrid::on_tet_added(const TetMesh& mesh, TetId tet) {
  file_pending();
  insert(tet, mesh.tet(tet));
}

bool TetGrid::unpend(TetId tet) {
  const auto it = std::find(pending_.begin(), pending_.end(), tet);
  if (it == pending_.end()) {
    return false;
  }
  *it = pending_.back();
  pending_.pop_back();
  return true;
}

// An edit may arrive while tetrahedra around a moved vertex wait to be filed (pending_): they
// are not in any cell, and the mesh already shows the edit, so they are handled by id here and
// never filed with corners they no longer have.

void TetGrid::on_tet_replaced(const TetMesh& mesh, TetId parent, std::span<const TetId> children,
                              const Tet& parent_vertices) {
  if (!unpend(parent)) {
    erase(parent, parent_vertices);
  }
  for (TetId child : children) {
    insert(child, mesh.tet(child));
  }
}

void TetGrid::on_tet_removed(const TetMesh& mesh, TetId removed, TetId moved_from,
                             const Tet& removed_vertices) {
  if (!unpend(removed)) {
    erase(removed, removed_vertices);
  }
  if (removed != moved_from) {
    if (unpend(moved_from)) {
      pending_.push_back(removed);
    } else {
      rename(moved_from, removed, mesh.tet(removed));
    }
  }
}

void TetGrid::on_tet_reshaped(const TetMesh& mesh, TetId tet, const Tet& old_vertices) {
  if (std::find(pending_.begin(), pending_.end(), tet) != pending_.end()) {
    return;  // filed later, at its new corners
  }
  erase(tet, old_vertices);
  insert(tet, mesh.tet(tet));
}

void TetGrid::query(const Vec3& low, const Vec3& high, std::vector<TetId>& out) const {
  file_pending();
  out.clear();
  seen_.clear(mesh_->tet_count());
  for_each_cell_in_box(low, high, [&](std::size_t cell) {
    for (TetId t : cells_[cell]) {
      if (seen_.insert(t)) {
        out.push_back(t);
      }
    }
  });
}

void TetGrid::save_state(StateWriter& out) const {
  out.tag("tet grid");
  out.value(origin_);
  out.value(cell_);
  out.value(dims_);
  out.nested(cells_);
  out.values(pending_);
}

void TetGrid::load_state(StateReader& in) {
  in.tag("tet grid");
  origin_ = in.value<Vec3>("grid origin");
  cell_ = in.value<double>("grid cell size");
  dims_ = in.value<decltype(dims_)>("grid dimensions");
  cells_ = in.nested<TetId>("grid cells");
  pending_ = in.values<TetId>("grid pending tetrahedra");
  std::size_t expected = 1;
  for (const auto d : dims_) {
    expected *= static_cast<std::size_t>(d);
  }
  if (!(cell_ > 0.0) || cells_.size() != expected) {
    in.fail("the tetrahedron grid", "its cells disagree with its dimensions");
  }
  seen_ = StampedSet{};
}

}  // namespace incise
