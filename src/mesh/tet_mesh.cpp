#include "incise/mesh/tet_mesh.hpp"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <sstream>
#include <string>

#include "incise/core/error.hpp"
#include "incise/core/growth.hpp"

namespace incise {
namespace {
constexpr const char* kObservedMove =
    "a mesh that attributes or models observe cannot be moved: they hold its address "
    "(build the mesh, move it into place, then attach them)";
}  // namespace

std::uint64_t edge_key(VertexId a, VertexId b) {
  if (a > b) {
    std::swap(a, b);
  }
  return (static_cast<std::uint64_t>(static_cast<std::uint32_t>(a)) << 32U) |
         static_cast<std::uint32_t>(b);
}

std::array<Vec3, 4> rest_corners(const TetMesh& mesh, TetId tet) {
  const Tet& corners = mesh.tet(tet);
  return {mesh.rest_position(corners[0]), mesh.rest_position(corners[1]),
          mesh.rest_position(corners[2]), mesh.rest_position(corners[3])};
}

namespace {

bool contains(const Tet& tet, VertexId vertex) {
  return std::find(tet.begin(), tet.end(), vertex) != tet.end();
}

void erase_one(std::vector<TetId>& list, TetId value) {
  const auto it = std::find(list.begin(), list.end(), value);
  INCISE_ASSERT(it != list.end(), "adjacency list misses an entry");
  *it = list.back();
  list.pop_back();
}

void replace_one(std::vector<TetId>& list, TetId from, TetId to) {
  const auto it = std::find(list.begin(), list.end(), from);
  INCISE_ASSERT(it != list.end(), "adjacency list misses an entry");
  *it = to;
}

/// Where `vertex` is in `tet` (0-3), or -1.
int local_index_in(const Tet& tet, VertexId vertex) {
  for (int i = 0; i < 4; ++i) {
    if (tet[i] == vertex) {
      return i;
    }
  }
  return -1;
}

/// The tet_local::kEdges index of the edge between local vertices a and b.
int local_edge(int a, int b) {
  for (int k = 0; k < 6; ++k) {
    const auto& e = tet_local::kEdges[k];
    if ((e[0] == a && e[1] == b) || (e[0] == b && e[1] == a)) {
      return k;
    }
  }
  return -1;
}

/// Local face index of `tet` whose vertices are {a, b, c}: the vertex not among them.
int face_opposite(const Tet& tet, VertexId a, VertexId b, VertexId c) {
  for (int i = 0; i < 4; ++i) {
    if (tet[i] != a && tet[i] != b && tet[i] != c) {
      return i;
    }
  }
  return -1;
}

/// The smallest vertex id set that a vertex stands for: duplicates stand for their original,
/// combinations for their parents. Used to find the edge a new edge was cut from.
void support_of(const std::vector<VertexOrigin>& origins, VertexId vertex,
                std::vector<VertexId>& out) {
  while (origins[vertex].kind == VertexOrigin::Kind::kDuplicate) {
    vertex = origins[vertex].parents[0];
  }
  const VertexOrigin& origin = origins[vertex];
  if (origin.kind == VertexOrigin::Kind::kCombination) {
    for (int i = 0; i < origin.parent_count; ++i) {
      if (origin.weights[i] > 0.0) {
        VertexId parent = origin.parents[i];
        while (origins[parent].kind == VertexOrigin::Kind::kDuplicate) {
          parent = origins[parent].parents[0];
        }
        out.push_back(parent);
      }
    }
  } else {
    out.push_back(vertex);
  }
}

}  // namespace

TetMesh::TetMesh(std::vector<Vec3> rest_positions, std::vector<Tet> tets)
    : TetMesh(std::move(rest_positions), std::move(tets), {}) {}

TetMesh::TetMesh(std::vector<Vec3> rest_positions, std::vector<Tet> tets, std::vector<int> labels)
    : rest_positions_(std::move(rest_positions)),
      tets_(std::move(tets)),
      tet_labels_(std::move(labels)) {
  if (tet_labels_.empty()) {
    tet_labels_.assign(tets_.size(), 0);
  }
  tet_fractions_.assign(tets_.size(), 1.0);
  if (tet_labels_.size() != tets_.size()) {
    throw InputError(std::to_string(tet_labels_.size()) + " region labels for " +
                     std::to_string(tets_.size()) + " tetrahedra");
  }
  vertex_origins_.assign(rest_positions_.size(), VertexOrigin{});
  for (std::size_t t = 0; t < tets_.size(); ++t) {
    for (int i = 0; i < 4; ++i) {
      const VertexId v = tets_[t][i];
      if (v < 0 || static_cast<std::size_t>(v) >= rest_positions_.size()) {
        throw InputError("tetrahedron " + std::to_string(t) + " refers to vertex " +
                         std::to_string(v) + ", but there are only " +
                         std::to_string(rest_positions_.size()) + " vertices");
      }
      for (int j = 0; j < i; ++j) {
        if (tets_[t][j] == v) {
          throw InputError("tetrahedron " + std::to_string(t) + " uses vertex " +
                           std::to_string(v) + " twice");
        }
      }
    }
  }
  build_adjacency();
}

TetMesh::TetMesh(const TetMesh& other)
    : rest_positions_(other.rest_positions_),
      vertex_origins_(other.vertex_origins_),
      tets_(other.tets_),
      tet_labels_(other.tet_labels_),
      tet_fractions_(other.tet_fractions_),
      tet_neighbors_(other.tet_neighbors_),
      tet_edges_(other.tet_edges_),
      vertex_tets_(other.vertex_tets_),
      edges_(other.edges_),
      edge_tets_(other.edge_tets_),
      edge_index_(other.edge_index_),
      revision_(other.revision_) {}

TetMesh& TetMesh::operator=(const TetMesh& other) {
  // Observers followed the mesh being overwritten; the move assignment detaches them.
  if (this != &other) {
    TetMesh copy(other);
    *this = std::move(copy);
  }
  return *this;
}

TetMesh::TetMesh(TetMesh&& other)
    : rest_positions_(std::move(unobserved(other).rest_positions_)),
      vertex_origins_(std::move(other.vertex_origins_)),
      tets_(std::move(other.tets_)),
      tet_labels_(std::move(other.tet_labels_)),
      tet_fractions_(std::move(other.tet_fractions_)),
      tet_neighbors_(std::move(other.tet_neighbors_)),
      tet_edges_(std::move(other.tet_edges_)),
      vertex_tets_(std::move(other.vertex_tets_)),
      edges_(std::move(other.edges_)),
      edge_tets_(std::move(other.edge_tets_)),
      edge_index_(std::move(other.edge_index_)),
      revision_(other.revision_) {}

TetMesh& TetMesh::unobserved(TetMesh& mesh) {
  if (!mesh.observers_.empty()) {
    throw InternalError(kObservedMove);  // checked before any member moves
  }
  return mesh;
}

TetMesh& TetMesh::operator=(TetMesh&& other) {
  if (this != &other) {
    if (!observers_.empty() || !other.observers_.empty()) {
      throw InternalError(kObservedMove);
    }
    rest_positions_ = std::move(other.rest_positions_);
    vertex_origins_ = std::move(other.vertex_origins_);
    tets_ = std::move(other.tets_);
    tet_labels_ = std::move(other.tet_labels_);
    tet_fractions_ = std::move(other.tet_fractions_);
    tet_neighbors_ = std::move(other.tet_neighbors_);
    tet_edges_ = std::move(other.tet_edges_);
    vertex_tets_ = std::move(other.vertex_tets_);
    edges_ = std::move(other.edges_);
    edge_tets_ = std::move(other.edge_tets_);
    edge_index_ = std::move(other.edge_index_);
    revision_ = other.revision_ + 1;
  }
  return *this;
}

TetMesh::~TetMesh() {
  for (MeshObserver* observer : observers_) {
    observer->on_mesh_destroyed();
  }
}

void TetMesh::add_observer(MeshObserver* observer) {
  INCISE_ASSERT(observer != nullptr, "null observer");
  observers_.push_back(observer);
}

void TetMesh::remove_observer(MeshObserver* observer) {
  observers_.erase(std::remove(observers_.begin(), observers_.end(), observer), observers_.end());
}

void TetMesh::replace_observer(MeshObserver* old_observer, MeshObserver* new_observer) {
  std::replace(observers_.begin(), observers_.end(), old_observer, new_observer);
}

EdgeId TetMesh::find_edge(VertexId a, VertexId b) const {
  return edge_index_.find(edge_key(a, b));
}

int TetMesh::local_index(TetId tet, VertexId vertex) const {
  const Tet& vertices = tets_[tet];
  for (int i = 0; i < 4; ++i) {
    if (vertices[i] == vertex) {
      return i;
    }
  }
  return -1;
}

// ---- bulk build ---------------------------------------------------------------------------

void TetMesh::build_adjacency() {
  const std::size_t tet_count = tets_.size();
  vertex_tets_.assign(rest_positions_.size(), {});
  std::vector<std::uint32_t> valence(rest_positions_.size(), 0);
  for (const Tet& tet : tets_) {
    for (VertexId v : tet) {
      ++valence[v];
    }
  }
  for (std::size_t v = 0; v < valence.size(); ++v) {
    vertex_tets_[v].reserve(valence[v]);
  }
  for (std::size_t t = 0; t < tet_count; ++t) {
    for (VertexId v : tets_[t]) {
      vertex_tets_[v].push_back(static_cast<TetId>(t));
    }
  }

  // Edges: sort (key, tet, local edge) and number unique keys in key order.
  struct EdgeSlot {
    std::uint64_t key;
    TetId tet;
    int local;
  };
  std::vector<EdgeSlot> edge_slots;
  edge_slots.reserve(tet_count * 6);
  for (std::size_t t = 0; t < tet_count; ++t) {
    for (int k = 0; k < 6; ++k) {
      const auto& e = tet_local::kEdges[k];
      edge_slots.push_back({edge_key(tets_[t][e[0]], tets_[t][e[1]]), static_cast<TetId>(t), k});
    }
  }
  std::sort(edge_slots.begin(), edge_slots.end(),
            [](const EdgeSlot& x, const EdgeSlot& y) { return x.key < y.key; });
  edges_.clear();
  edge_tets_.clear();
  edge_index_.clear();
  edge_index_.reserve(edge_slots.size() / 4);
  tet_edges_.assign(tet_count, {});
  for (std::size_t i = 0; i < edge_slots.size();) {
    std::size_t j = i;
    const auto id = static_cast<EdgeId>(edges_.size());
    std::vector<TetId> around;
    while (j < edge_slots.size() && edge_slots[j].key == edge_slots[i].key) {
      around.push_back(edge_slots[j].tet);
      tet_edges_[edge_slots[j].tet][edge_slots[j].local] = id;
      ++j;
    }
    edges_.push_back({static_cast<VertexId>(edge_slots[i].key >> 32U),
                      static_cast<VertexId>(edge_slots[i].key & 0xffffffffU)});
    edge_tets_.push_back(std::move(around));
    edge_index_.assign(edge_slots[i].key, id);
    i = j;
  }

  // Faces: sort by sorted vertex triple; groups of 1 are boundary, 2 neighbours, more invalid.
  struct FaceSlot {
    std::array<VertexId, 3> key;
    TetId tet;
    int local;
  };
  std::vector<FaceSlot> face_slots;
  face_slots.reserve(tet_count * 4);
  for (std::size_t t = 0; t < tet_count; ++t) {
    for (int f = 0; f < 4; ++f) {
      const auto& face = tet_local::kFaces[f];
      std::array<VertexId, 3> key{tets_[t][face[0]], tets_[t][face[1]], tets_[t][face[2]]};
      std::sort(key.begin(), key.end());
      face_slots.push_back({key, static_cast<TetId>(t), f});
    }
  }
  std::sort(face_slots.begin(), face_slots.end(),
            [](const FaceSlot& x, const FaceSlot& y) { return x.key < y.key; });
  tet_neighbors_.assign(tet_count, {kBoundaryFace, kBoundaryFace, kBoundaryFace, kBoundaryFace});
  for (std::size_t i = 0; i < face_slots.size();) {
    std::size_t j = i;
    while (j < face_slots.size() && face_slots[j].key == face_slots[i].key) {
      ++j;
    }
    if (j - i == 2) {
      tet_neighbors_[face_slots[i].tet][face_slots[i].local] = face_slots[i + 1].tet;
      tet_neighbors_[face_slots[i + 1].tet][face_slots[i + 1].local] = face_slots[i].tet;
    } else if (j - i > 2) {
      for (std::size_t k = i; k < j; ++k) {
        tet_neighbors_[face_slots[k].tet][face_slots[k].local] = kNonManifoldFace;
      }
    }
    i = j;
  }
  reserve_all_for_edits();
}

void TetMesh::reserve_all_for_edits() {
  reserve_for_edits(rest_positions_);
  reserve_for_edits(vertex_origins_);
  reserve_for_edits(tets_);
  reserve_for_edits(tet_labels_);
  reserve_for_edits(tet_fractions_);
  reserve_for_edits(tet_neighbors_);
  reserve_for_edits(tet_edges_);
  reserve_for_edits(vertex_tets_);
  reserve_for_edits(edges_);
  reserve_for_edits(edge_tets_);
  edge_index_.reserve(capacity_for_hashed_keys(edges_.size()));
}

// ---- incremental maintenance -------------------------------------------------------------

void TetMesh::update_face(VertexId a, VertexId b, VertexId c) {
  // Scan the shortest vertex -> tets list for tetrahedra holding all three vertices.
  VertexId pivot = a;
  if (vertex_tets_[b].size() < vertex_tets_[pivot].size()) {
    pivot = b;
  }
  if (vertex_tets_[c].size() < vertex_tets_[pivot].size()) {
    pivot = c;
  }
  std::array<TetId, 8> sharing{};
  std::size_t count = 0;
  std::vector<TetId> overflow;
  for (TetId t : vertex_tets_[pivot]) {
    const Tet& tet = tets_[t];
    if (contains(tet, a) && contains(tet, b) && contains(tet, c)) {
      if (count < sharing.size()) {
        sharing[count] = t;
      } else {
        overflow.push_back(t);
      }
      ++count;
    }
  }
  auto set_neighbor = [&](TetId t, TetId value) {
    tet_neighbors_[t][face_opposite(tets_[t], a, b, c)] = value;
  };
  if (count == 1) {
    set_neighbor(sharing[0], kBoundaryFace);
  } else if (count == 2) {
    set_neighbor(sharing[0], sharing[1]);
    set_neighbor(sharing[1], sharing[0]);
  } else if (count > 2) {
    for (std::size_t k = 0; k < std::min(count, sharing.size()); ++k) {
      set_neighbor(sharing[k], kNonManifoldFace);
    }
    for (TetId t : overflow) {
      set_neighbor(t, kNonManifoldFace);
    }
  }
}

EdgeId TetMesh::find_or_create_edge(VertexId a, VertexId b) {
  const std::uint64_t key = edge_key(a, b);
  const auto [edge, inserted] = edge_index_.try_emplace(key, static_cast<EdgeId>(edges_.size()));
  if (inserted) {
    edges_.push_back({std::min(a, b), std::max(a, b)});
    edge_tets_.emplace_back();
    edit_created_edges_.push_back(edge);
  }
  return edge;
}

void TetMesh::attach(TetId t) {
  const Tet& tet = tets_[t];
  for (VertexId v : tet) {
    vertex_tets_[v].push_back(t);
  }
  for (int k = 0; k < 6; ++k) {
    const auto& e = tet_local::kEdges[k];
    const EdgeId edge = find_or_create_edge(tet[e[0]], tet[e[1]]);
    edge_tets_[edge].push_back(t);
    tet_edges_[t][k] = edge;
  }
  tet_neighbors_[t] = {kBoundaryFace, kBoundaryFace, kBoundaryFace, kBoundaryFace};
  for (const auto& face : tet_local::kFaces) {
    update_face(tet[face[0]], tet[face[1]], tet[face[2]]);
  }
}

void TetMesh::leave_lists(TetId t) {
  for (VertexId v : tets_[t]) {
    erase_one(vertex_tets_[v], t);
  }
  for (const EdgeId edge : tet_edges_[t]) {
    erase_one(edge_tets_[edge], t);
    if (edge_tets_[edge].empty()) {
      edit_unused_edges_.push_back(edge);
    }
  }
}

void TetMesh::move_corner(TetId t, int at, VertexId with) {
  tets_[t][static_cast<std::size_t>(at)] = with;
  const Tet& tet = tets_[t];
  for (VertexId v : tet) {
    vertex_tets_[v].push_back(t);
  }
  for (int k = 0; k < 6; ++k) {
    const auto& e = tet_local::kEdges[k];
    const EdgeId edge =
        e[0] == at || e[1] == at ? find_or_create_edge(tet[e[0]], tet[e[1]]) : tet_edges_[t][k];
    edge_tets_[edge].push_back(t);
    tet_edges_[t][k] = edge;
  }
}

void TetMesh::detach(TetId t) {
  const Tet& tet = tets_[t];
  leave_lists(t);
  tet_edges_[t] = {kInvalidId, kInvalidId, kInvalidId, kInvalidId, kInvalidId, kInvalidId};
  for (const auto& face : tet_local::kFaces) {
    update_face(tet[face[0]], tet[face[1]], tet[face[2]]);
  }
  tet_neighbors_[t] = {kBoundaryFace, kBoundaryFace, kBoundaryFace, kBoundaryFace};
}

EdgeOrigin TetMesh::edge_parent(EdgeId edge) const {
  EdgeOrigin origin{edge, kInvalidId, 0.0};
  std::vector<VertexId> support;
  support_of(vertex_origins_, edges_[edge][0], support);
  support_of(vertex_origins_, edges_[edge][1], support);
  std::sort(support.begin(), support.end());
  support.erase(std::unique(support.begin(), support.end()), support.end());
  if (support.size() != 2) {
    return origin;
  }
  const EdgeId parent = find_edge(support[0], support[1]);
  if (parent == kInvalidId || parent == edge) {
    return origin;
  }
  const double parent_length = (rest_positions_[support[0]] - rest_positions_[support[1]]).norm();
  const double length =
      (rest_positions_[edges_[edge][0]] - rest_positions_[edges_[edge][1]]).norm();
  origin.parent = parent;
  origin.fraction = parent_length > 0.0 ? length / parent_length : 0.0;
  return origin;
}

void TetMesh::finish_edit() {
  ++revision_;
  // New edges first, while edges that went unused still hold their attribute values.
  std::vector<EdgeOrigin> created;
  created.reserve(edit_created_edges_.size());
  for (EdgeId edge : edit_created_edges_) {
    created.push_back(edge_parent(edge));
  }
  edit_created_edges_.clear();
  if (!created.empty()) {
    for (MeshObserver* observer : observers_) {
      observer->on_edges_created(*this, created);
    }
  }
  // Drop edges without tetrahedra, highest id first so the last edge is always a live one.
  std::sort(edit_unused_edges_.begin(), edit_unused_edges_.end(), std::greater<>());
  edit_unused_edges_.erase(std::unique(edit_unused_edges_.begin(), edit_unused_edges_.end()),
                           edit_unused_edges_.end());
  for (EdgeId edge : edit_unused_edges_) {
    if (!edge_tets_[edge].empty()) {
      continue;  // revived by a later attach in the same edit
    }
    const auto last = static_cast<EdgeId>(edges_.size() - 1);
    edge_index_.erase(edge_key(edges_[edge][0], edges_[edge][1]));
    if (edge != last) {
      edges_[edge] = edges_[last];
      edge_tets_[edge] = std::move(edge_tets_[last]);
      edge_index_.assign(edge_key(edges_[edge][0], edges_[edge][1]), edge);
      for (TetId t : edge_tets_[edge]) {
        std::replace(tet_edges_[t].begin(), tet_edges_[t].end(), last, edge);
      }
    }
    edges_.pop_back();
    edge_tets_.pop_back();
    for (MeshObserver* observer : observers_) {
      observer->on_edge_removed(*this, edge, last);
    }
  }
  edit_unused_edges_.clear();
}

void TetMesh::check_tet_ids(const Tet& tet) const {
  for (int i = 0; i < 4; ++i) {
    if (tet[i] < 0 || static_cast<std::size_t>(tet[i]) >= rest_positions_.size()) {
      throw InputError("tetrahedron refers to vertex " + std::to_string(tet[i]) +
                       ", but there are only " + std::to_string(rest_positions_.size()) +
                       " vertices");
    }
    for (int j = 0; j < i; ++j) {
      if (tet[i] == tet[j]) {
        throw InputError("tetrahedron uses vertex " + std::to_string(tet[i]) + " twice");
      }
    }
  }
}

// ---- public edits --------------------------------------------------------------------------

void TetMesh::append_vertex(const Vec3& rest_position, const VertexOrigin& origin) {
  rest_positions_.push_back(rest_position);
  vertex_origins_.push_back(origin);
  vertex_tets_.emplace_back();
  const auto vertex = static_cast<VertexId>(rest_positions_.size() - 1);
  for (MeshObserver* observer : observers_) {
    observer->on_vertex_added(*this, vertex, origin);
  }
}

VertexId TetMesh::add_vertex(const Vec3& rest_position) {
  append_vertex(rest_position, VertexOrigin{});
  ++revision_;
  return static_cast<VertexId>(rest_positions_.size() - 1);
}

VertexOrigin TetMesh::combination(const char* operation, std::span<const VertexId> parents,
                                  std::span<const double> weights, Vec3& position) const {
  if (parents.empty() || parents.size() > 4 || parents.size() != weights.size()) {
    throw InputError(std::string(operation) + " needs 1 to 4 parents with one weight each");
  }
  VertexOrigin origin;
  origin.kind = VertexOrigin::Kind::kCombination;
  origin.parent_count = static_cast<std::uint8_t>(parents.size());
  position = Vec3::Zero();
  double weight_sum = 0.0;
  for (std::size_t i = 0; i < parents.size(); ++i) {
    if (parents[i] < 0 || static_cast<std::size_t>(parents[i]) >= rest_positions_.size()) {
      throw InputError(std::string(operation) + ": parent vertex " + std::to_string(parents[i]) +
                       " does not exist");
    }
    if (!(weights[i] >= 0.0) || !std::isfinite(weights[i])) {
      throw InputError(std::string(operation) + ": weight " + std::to_string(weights[i]) +
                       " is negative or not finite");
    }
    origin.parents[i] = parents[i];
    origin.weights[i] = weights[i];
    position += weights[i] * rest_positions_[parents[i]];
    weight_sum += weights[i];
  }
  if (std::abs(weight_sum - 1.0) > 1e-9) {
    throw InputError(std::string(operation) + ": weights sum to " + std::to_string(weight_sum) +
                     ", not 1");
  }
  return origin;
}

VertexId TetMesh::add_vertex(std::span<const VertexId> parents, std::span<const double> weights) {
  Vec3 position;
  const VertexOrigin origin = combination("add_vertex", parents, weights, position);
  append_vertex(position, origin);
  ++revision_;
  return static_cast<VertexId>(rest_positions_.size() - 1);
}

void TetMesh::relocate_vertex(VertexId vertex, std::span<const VertexId> parents,
                              std::span<const double> weights) {
  if (vertex < 0 || static_cast<std::size_t>(vertex) >= rest_positions_.size()) {
    throw InputError("relocate_vertex: vertex " + std::to_string(vertex) + " does not exist");
  }
  Vec3 position;
  const VertexOrigin origin = combination("relocate_vertex", parents, weights, position);
  for (MeshObserver* observer : observers_) {
    observer->on_vertex_relocating(*this, vertex);
  }
  rest_positions_[vertex] = position;
  vertex_origins_[vertex] = origin;
  ++revision_;
  for (MeshObserver* observer : observers_) {
    observer->on_vertex_relocated(*this, vertex, origin);
  }
}

VertexId TetMesh::duplicate_vertex(VertexId original, std::span<const TetId> tets_to_move) {
  if (original < 0 || static_cast<std::size_t>(original) >= rest_positions_.size()) {
    throw InputError("duplicate_vertex: vertex " + std::to_string(original) + " does not exist");
  }
  for (TetId t : tets_to_move) {
    if (t < 0 || static_cast<std::size_t>(t) >= tets_.size() || !contains(tets_[t], original)) {
      throw InputError("duplicate_vertex: tetrahedron " + std::to_string(t) +
                       " does not use vertex " + std::to_string(original));
    }
  }
  std::vector<TetId> distinct(tets_to_move.begin(), tets_to_move.end());
  std::sort(distinct.begin(), distinct.end());
  if (std::adjacent_find(distinct.begin(), distinct.end()) != distinct.end()) {
    throw InputError("duplicate_vertex: a tetrahedron is listed twice");
  }
  VertexOrigin origin;
  origin.kind = VertexOrigin::Kind::kDuplicate;
  origin.parent_count = 1;
  origin.parents[0] = original;
  origin.weights[0] = 1.0;
  const Vec3 position = rest_positions_[original];
  append_vertex(position, origin);
  const auto copy = static_cast<VertexId>(rest_positions_.size() - 1);
  // As detaching the moved tetrahedra and attaching them again would (the same lists in the
  // same order, the same new edge ids), touching only what runs through the vertex: their
  // edges and faces not through it stay. A face through it between a moved tetrahedron and
  // one that stays is no longer shared: both sides become boundary. A face held by more than
  // two tetrahedra is matched by scanning as before.
  for (TetId t : tets_to_move) {
    leave_lists(t);
  }
  for (TetId t : tets_to_move) {
    move_corner(t, local_index(t, original), copy);
  }
  for (TetId t : tets_to_move) {
    const int at = local_index(t, copy);
    for (int f = 0; f < 4; ++f) {
      const TetId neighbor = tet_neighbors_[t][f];
      if (f == at || neighbor == kBoundaryFace ||
          (neighbor >= 0 && contains(tets_[neighbor], copy))) {
        continue;  // not through the vertex, open already, or shared with a moved one
      }
      const auto& face = tet_local::kFaces[f];
      const std::array<VertexId, 3> now{tets_[t][face[0]], tets_[t][face[1]], tets_[t][face[2]]};
      std::array<VertexId, 3> before = now;
      std::replace(before.begin(), before.end(), copy, original);
      if (neighbor >= 0) {
        tet_neighbors_[t][f] = kBoundaryFace;
        tet_neighbors_[neighbor][face_opposite(tets_[neighbor], before[0], before[1], before[2])] =
            kBoundaryFace;
      } else {
        update_face(now[0], now[1], now[2]);
        update_face(before[0], before[1], before[2]);
      }
    }
  }
  for (TetId t : tets_to_move) {
    Tet old_vertices = tets_[t];
    std::replace(old_vertices.begin(), old_vertices.end(), copy, original);
    for (MeshObserver* observer : observers_) {
      observer->on_tet_reconnected(*this, t, old_vertices);
    }
  }
  finish_edit();
  return copy;
}

TetId TetMesh::add_tet(const Tet& tet, int label) {
  check_tet_ids(tet);
  const auto id = static_cast<TetId>(tets_.size());
  tets_.push_back(tet);
  tet_labels_.push_back(label);
  tet_fractions_.push_back(1.0);
  tet_neighbors_.push_back({kBoundaryFace, kBoundaryFace, kBoundaryFace, kBoundaryFace});
  tet_edges_.push_back({kInvalidId, kInvalidId, kInvalidId, kInvalidId, kInvalidId, kInvalidId});
  attach(id);
  for (MeshObserver* observer : observers_) {
    observer->on_tet_added(*this, id);
  }
  finish_edit();
  return id;
}

std::vector<TetId> TetMesh::replace_tet(TetId parent, std::span<const Tet> children) {
  if (parent < 0 || static_cast<std::size_t>(parent) >= tets_.size()) {
    throw InputError("replace_tet: tetrahedron " + std::to_string(parent) + " does not exist");
  }
  if (children.empty()) {
    throw InputError("replace_tet: no children given (use remove_tet to delete)");
  }
  for (const Tet& child : children) {
    check_tet_ids(child);
  }
  const Tet parent_vertices = tets_[parent];
  const std::array<TetId, 4> parent_neighbors = tet_neighbors_[parent];
  const std::array<EdgeId, 6> parent_edges = tet_edges_[parent];
  // The parent's faces, and which child keeps each whole. Where each is kept by at most one
  // child and none is non-manifold, the edit is the one detaching the parent and attaching
  // the children would make (the same lists in the same order, the same new edge ids), with
  // less work: a kept face takes the parent's neighbour without a scan, and an edge between
  // two of the parent's vertices is the parent's (no hash probe).
  std::array<std::array<VertexId, 3>, 4> parent_faces{};
  for (int f = 0; f < 4; ++f) {
    const auto& face = tet_local::kFaces[f];
    parent_faces[f] = {parent_vertices[face[0]], parent_vertices[face[1]],
                       parent_vertices[face[2]]};
    std::sort(parent_faces[f].begin(), parent_faces[f].end());
  }
  const auto parent_face_of = [&](const Tet& tet, int f) {
    const auto& face = tet_local::kFaces[f];
    std::array<VertexId, 3> key{tet[face[0]], tet[face[1]], tet[face[2]]};
    std::sort(key.begin(), key.end());
    return static_cast<int>(std::find(parent_faces.begin(), parent_faces.end(), key) -
                            parent_faces.begin());  // 4: none
  };
  std::array<int, 4> kept{};
  for (const Tet& child : children) {
    for (int f = 0; f < 4; ++f) {
      const int p = parent_face_of(child, f);
      if (p < 4) {
        ++kept[p];
      }
    }
  }
  bool plain = true;
  for (int f = 0; f < 4; ++f) {
    plain =
        plain && kept[f] <= 1 && (parent_neighbors[f] >= 0 || parent_neighbors[f] == kBoundaryFace);
  }
  if (!plain) {
    detach(parent);
  } else {
    leave_lists(parent);
    tet_edges_[parent] = {kInvalidId, kInvalidId, kInvalidId, kInvalidId, kInvalidId, kInvalidId};
    // The neighbours' faces are open until a child takes them.
    for (int f = 0; f < 4; ++f) {
      const TetId neighbor = parent_neighbors[f];
      if (neighbor >= 0) {
        tet_neighbors_[neighbor][face_opposite(tets_[neighbor], parent_faces[f][0],
                                               parent_faces[f][1], parent_faces[f][2])] =
            kBoundaryFace;
      }
    }
    tet_neighbors_[parent] = {kBoundaryFace, kBoundaryFace, kBoundaryFace, kBoundaryFace};
  }
  std::vector<TetId> ids;
  ids.reserve(children.size());
  tets_[parent] = children[0];
  ids.push_back(parent);
  for (std::size_t i = 1; i < children.size(); ++i) {
    ids.push_back(static_cast<TetId>(tets_.size()));
    tets_.push_back(children[i]);
    tet_labels_.push_back(tet_labels_[parent]);
    tet_fractions_.push_back(tet_fractions_[parent]);
    tet_neighbors_.push_back({kBoundaryFace, kBoundaryFace, kBoundaryFace, kBoundaryFace});
    tet_edges_.push_back({kInvalidId, kInvalidId, kInvalidId, kInvalidId, kInvalidId, kInvalidId});
  }
  for (TetId id : ids) {
    if (!plain) {
      attach(id);
      continue;
    }
    const Tet& tet = tets_[id];
    for (VertexId v : tet) {
      vertex_tets_[v].push_back(id);
    }
    for (int k = 0; k < 6; ++k) {
      const auto& e = tet_local::kEdges[k];
      const int a = local_index_in(parent_vertices, tet[e[0]]);
      const int b = local_index_in(parent_vertices, tet[e[1]]);
      const EdgeId edge = a >= 0 && b >= 0 ? parent_edges[local_edge(a, b)]
                                           : find_or_create_edge(tet[e[0]], tet[e[1]]);
      edge_tets_[edge].push_back(id);
      tet_edges_[id][k] = edge;
    }
    for (int f = 0; f < 4; ++f) {
      const int p = parent_face_of(tet, f);
      if (p == 4) {
        const auto& face = tet_local::kFaces[f];
        update_face(tet[face[0]], tet[face[1]], tet[face[2]]);
      } else if (parent_neighbors[p] >= 0) {
        const TetId neighbor = parent_neighbors[p];
        tet_neighbors_[id][f] = neighbor;
        tet_neighbors_[neighbor][face_opposite(tets_[neighbor], parent_faces[p][0],
                                               parent_faces[p][1], parent_faces[p][2])] = id;
      }
    }
  }
  for (MeshObserver* observer : observers_) {
    observer->on_tet_replaced(*this, parent, ids, parent_vertices);
  }
  finish_edit();
  return ids;
}

TetId TetMesh::erase_detached(TetId t) {
  const auto last = static_cast<TetId>(tets_.size() - 1);
  if (t != last) {
    tets_[t] = tets_[last];
    tet_labels_[t] = tet_labels_[last];
    tet_fractions_[t] = tet_fractions_[last];
    tet_neighbors_[t] = tet_neighbors_[last];
    tet_edges_[t] = tet_edges_[last];
    for (VertexId v : tets_[t]) {
      replace_one(vertex_tets_[v], last, t);
    }
    for (EdgeId e : tet_edges_[t]) {
      replace_one(edge_tets_[e], last, t);
    }
    for (TetId neighbor : tet_neighbors_[t]) {
      if (neighbor >= 0) {
        std::replace(tet_neighbors_[neighbor].begin(), tet_neighbors_[neighbor].end(), last, t);
      }
    }
  }
  tets_.pop_back();
  tet_labels_.pop_back();
  tet_fractions_.pop_back();
  tet_neighbors_.pop_back();
  tet_edges_.pop_back();
  return last;
}

void TetMesh::remove_tet(TetId t) {
  if (t < 0 || static_cast<std::size_t>(t) >= tets_.size()) {
    throw InputError("remove_tet: tetrahedron " + std::to_string(t) + " does not exist");
  }
  const Tet removed_vertices = tets_[t];
  detach(t);
  const TetId last = erase_detached(t);
  for (MeshObserver* observer : observers_) {
    observer->on_tet_removed(*this, t, last, removed_vertices);
  }
  finish_edit();
}

void TetMesh::collapse_vertex(VertexId vertex, VertexId target) {
  const auto exists = [&](VertexId v) {
    return v >= 0 && static_cast<std::size_t>(v) < rest_positions_.size();
  };
  const auto where = [&] {  // made only for a message: a collapse runs a hundred times a pose
    return "collapse_vertex(" + std::to_string(vertex) + ", " + std::to_string(target) + "): ";
  };
  if (!exists(vertex) || !exists(target) || vertex == target) {
    throw InputError(where() + "two distinct existing vertices needed");
  }
  if (find_edge(vertex, target) == kInvalidId) {
    throw InputError(where() + "not an edge");
  }
  // Which tetrahedra go and which change, and who takes each one's material.
  const std::vector<TetId> star(vertex_tets_[vertex].begin(), vertex_tets_[vertex].end());
  std::vector<TetId> removed;
  std::vector<TetId> reshaped;
  for (TetId t : star) {
    (contains(tets_[t], target) ? removed : reshaped).push_back(t);
  }
  std::vector<TetId> into;
  for (TetId t : removed) {
    const TetId across = tet_neighbors_[t][local_index(t, target)];
    if (across < 0 || contains(tets_[across], target)) {
      throw InputError(where() + "tetrahedron " + std::to_string(t) +
                       " has no neighbour to absorb it (the collapse would change the boundary)");
    }
    into.push_back(across);
  }
  // The link condition: no tetrahedron twice, no face on three tetrahedra, around the target.
  // Every tetrahedron there holds the target, so it is its other three vertices (a triangle of
  // the target's link) and a face through the target is an edge of that triangle.
  std::vector<std::array<VertexId, 3>> triangles;
  std::vector<std::uint64_t> link_edges;
  const auto add_link = [&](const Tet& tet) {
    std::array<VertexId, 3> triangle{};
    std::size_t n = 0;
    for (VertexId v : tet) {
      if (v != target) {
        triangle[n++] = v;
      }
    }
    std::sort(triangle.begin(), triangle.end());
    triangles.push_back(triangle);
    link_edges.insert(link_edges.end(),
                      {edge_key(triangle[0], triangle[1]), edge_key(triangle[0], triangle[2]),
                       edge_key(triangle[1], triangle[2])});
  };
  triangles.reserve(vertex_tets_[target].size() + reshaped.size());
  link_edges.reserve(3 * triangles.capacity());
  for (TetId t : vertex_tets_[target]) {
    if (!contains(tets_[t], vertex)) {
      add_link(tets_[t]);
    }
  }
  for (TetId t : reshaped) {
    Tet moved = tets_[t];
    std::replace(moved.begin(), moved.end(), vertex, target);
    add_link(moved);
  }
  std::sort(triangles.begin(), triangles.end());
  std::sort(link_edges.begin(), link_edges.end());
  if (std::adjacent_find(triangles.begin(), triangles.end()) != triangles.end()) {
    throw InputError(where() + "a tetrahedron would be repeated");
  }
  for (std::size_t k = 2; k < link_edges.size(); ++k) {
    if (link_edges[k] == link_edges[k - 2]) {
      throw InputError(where() + "a face would be shared by three tetrahedra");
    }
  }

  // The edit, as detaching the star and attaching the reshaped tetrahedra again would make it
  // (the same lists in the same order, the same new edge ids), but touching only what runs
  // through the vertex: the reshaped tetrahedra keep their edges and faces not through it, and
  // only their faces through the target are matched again. A face not through the vertex
  // keeps its neighbour: a removed tetrahedron holds the vertex and the target, so it meets a
  // reshaped one only across a face through the vertex. The removed ones' faces opposite the
  // vertex are matched with their absorbers' through the target.
  for (TetId t : star) {
    leave_lists(t);
  }
  for (TetId t : removed) {
    tet_edges_[t] = {kInvalidId, kInvalidId, kInvalidId, kInvalidId, kInvalidId, kInvalidId};
    tet_neighbors_[t] = {kBoundaryFace, kBoundaryFace, kBoundaryFace, kBoundaryFace};
  }
  std::vector<Tet> old_vertices;
  for (TetId t : reshaped) {
    old_vertices.push_back(tets_[t]);
    move_corner(t, local_index(t, vertex), target);
  }
  for (TetId t : reshaped) {
    const int at = local_index(t, target);
    for (int f = 0; f < 4; ++f) {
      if (f != at) {
        const auto& face = tet_local::kFaces[f];
        update_face(tets_[t][face[0]], tets_[t][face[1]], tets_[t][face[2]]);
      }
    }
  }
  for (std::size_t k = 0; k < reshaped.size(); ++k) {
    for (MeshObserver* observer : observers_) {
      observer->on_tet_reshaped(*this, reshaped[k], old_vertices[k]);
    }
  }
  std::vector<std::size_t> order(removed.size());
  for (std::size_t k = 0; k < order.size(); ++k) {
    order[k] = k;
  }
  std::sort(order.begin(), order.end(),
            [&](std::size_t a, std::size_t b) { return removed[a] > removed[b]; });
  for (std::size_t k : order) {
    const TetId t = removed[k];
    const Tet gone = tets_[t];
    const TetId last = erase_detached(t);
    for (MeshObserver* observer : observers_) {
      observer->on_tet_absorbed(*this, t, into[k], last, gone);
    }
    for (TetId& absorber : into) {
      absorber = absorber == last ? t : absorber;  // the last tetrahedron moved to t
    }
  }
  finish_edit();
}

void TetMesh::set_rest_position(VertexId vertex, const Vec3& rest_position) {
  INCISE_ASSERT(vertex >= 0 && static_cast<std::size_t>(vertex) < rest_positions_.size(),
                "vertex id out of range");
  rest_positions_[vertex] = rest_position;
  ++revision_;
}

// ---- self-check --------------------------------------------------------------------------

void TetMesh::set_material_fraction(TetId tet, double fraction) {
  if (tet < 0 || static_cast<std::size_t>(tet) >= tets_.size()) {
    throw InputError("set_material_fraction: tetrahedron " + std::to_string(tet) +
                     " does not exist");
  }
  if (!(fraction >= 0.0 && fraction <= 1.0)) {
    throw InputError("material fraction of tetrahedron " + std::to_string(tet) +
                     " must lie in [0, 1]");
  }
  tet_fractions_[tet] = fraction;  // the topology is the same: the revision stays
  for (MeshObserver* observer : observers_) {
    observer->on_material_fraction_changed(*this, tet);
  }
}

void TetMesh::save_state(StateWriter& out) const {
  out.tag("mesh");
  out.values(rest_positions_);
  out.values(vertex_origins_);
  out.values(tets_);
  out.values(tet_labels_);
  out.values(tet_fractions_);
  out.values(tet_neighbors_);
  out.values(tet_edges_);
  out.nested(vertex_tets_);
  out.values(edges_);
  out.nested(edge_tets_);
  out.value(revision_);
  out.value<std::uint64_t>(observers_.size());
  for (const MeshObserver* observer : observers_) {
    observer->save_state(out);
  }
}

void TetMesh::load_state(StateReader& in) {
  in.tag("mesh");
  rest_positions_ = in.values<Vec3>("rest positions");
  vertex_origins_ = in.values<VertexOrigin>("vertex origins");
  tets_ = in.values<Tet>("tetrahedra");
  tet_labels_ = in.values<int>("region labels");
  tet_fractions_ = in.values<double>("material fractions");
  tet_neighbors_ = in.values<std::array<TetId, 4>>("tetrahedron neighbours");
  tet_edges_ = in.values<std::array<EdgeId, 6>>("tetrahedron edges");
  vertex_tets_ = in.nested<TetId>("vertex tetrahedra");
  edges_ = in.values<std::array<VertexId, 2>>("edges");
  edge_tets_ = in.nested<TetId>("edge tetrahedra");
  revision_ = in.value<std::uint64_t>("revision");
  const std::size_t n = rest_positions_.size();
  const std::size_t m = tets_.size();
  if (vertex_origins_.size() != n || vertex_tets_.size() != n || tet_labels_.size() != m ||
      tet_fractions_.size() != m || tet_neighbors_.size() != m || tet_edges_.size() != m ||
      edge_tets_.size() != edges_.size()) {
    in.fail("the mesh", "its arrays disagree in size");
  }
  for (const Tet& tet : tets_) {
    for (VertexId v : tet) {
      if (v < 0 || static_cast<std::size_t>(v) >= n) {
        in.fail("the mesh", "a tetrahedron names vertex " + std::to_string(v));
      }
    }
  }
  for (const auto& edge : edges_) {
    for (VertexId v : edge) {
      if (v < 0 || static_cast<std::size_t>(v) >= n) {
        in.fail("the mesh", "an edge names vertex " + std::to_string(v));
      }
    }
  }
  edge_index_.clear();
  for (std::size_t e = 0; e < edges_.size(); ++e) {
    edge_index_.assign(edge_key(edges_[e][0], edges_[e][1]), static_cast<EdgeId>(e));
  }
  edit_created_edges_.clear();
  edit_unused_edges_.clear();
  reserve_all_for_edits();
  const auto observers = in.value<std::uint64_t>("observer count");
  if (observers != observers_.size()) {
    in.fail("observer count", "the checkpoint has " + std::to_string(observers) +
                                  " parts following the mesh, this scene " +
                                  std::to_string(observers_.size()));
  }
  for (MeshObserver* observer : observers_) {
    observer->load_state(in);
  }
}

std::string TetMesh::compare_with_rebuilt_adjacency() const {
  TetMesh fresh(rest_positions_, tets_);
  std::ostringstream diff;
  for (std::size_t v = 0; v < vertex_tets_.size(); ++v) {
    std::vector<TetId> mine(vertex_tets_[v].begin(), vertex_tets_[v].end());
    std::vector<TetId> theirs(fresh.vertex_tets_[v].begin(), fresh.vertex_tets_[v].end());
    std::sort(mine.begin(), mine.end());
    std::sort(theirs.begin(), theirs.end());
    if (mine != theirs) {
      diff << "vertex " << v << ": vertex->tets differ";
      return diff.str();
    }
  }
  if (tet_neighbors_ != fresh.tet_neighbors_) {
    for (std::size_t t = 0; t < tets_.size(); ++t) {
      if (tet_neighbors_[t] != fresh.tet_neighbors_[t]) {
        diff << "tet " << t << ": neighbours differ";
        return diff.str();
      }
    }
  }
  if (edges_.size() != fresh.edges_.size() || edge_index_.size() != edges_.size()) {
    diff << "edge count " << edges_.size() << " (index " << edge_index_.size() << ") vs rebuilt "
         << fresh.edges_.size();
    return diff.str();
  }
  for (std::size_t e = 0; e < edges_.size(); ++e) {
    const EdgeId other = fresh.find_edge(edges_[e][0], edges_[e][1]);
    if (other == kInvalidId || find_edge(edges_[e][0], edges_[e][1]) != static_cast<EdgeId>(e)) {
      diff << "edge " << e << " (" << edges_[e][0] << "," << edges_[e][1] << ") is not indexed";
      return diff.str();
    }
    std::vector<TetId> mine(edge_tets_[e].begin(), edge_tets_[e].end());
    std::vector<TetId> theirs(fresh.edge_tets_[other].begin(), fresh.edge_tets_[other].end());
    std::sort(mine.begin(), mine.end());
    std::sort(theirs.begin(), theirs.end());
    if (mine != theirs) {
      diff << "edge " << e << ": edge->tets differ";
      return diff.str();
    }
  }
  for (std::size_t t = 0; t < tets_.size(); ++t) {
    for (int k = 0; k < 6; ++k) {
      const auto& local = tet_local::kEdges[k];
      const EdgeId e = tet_edges_[t][k];
      if (e < 0 || static_cast<std::size_t>(e) >= edges_.size() ||
          edges_[e] != std::array<VertexId, 2>{std::min(tets_[t][local[0]], tets_[t][local[1]]),
                                               std::max(tets_[t][local[0]], tets_[t][local[1]])}) {
        diff << "tet " << t << ": edge " << k << " id is stale";
        return diff.str();
      }
    }
  }
  return {};
}

// ---- volumes -----------------------------------------------------------------------------

double signed_volume(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d) {
  return (b - a).dot((c - a).cross(d - a)) / 6.0;
}

std::array<double, 4> barycentric_coordinates(const Vec3& p, const Vec3& a, const Vec3& b,
                                              const Vec3& c, const Vec3& d) {
  Mat3 frame;
  frame << b - a, c - a, d - a;
  const Vec3 local = frame.inverse() * (p - a);
  return {1.0 - local.sum(), local[0], local[1], local[2]};
}

double signed_volume(const TetMesh& mesh, TetId tet) {
  const Tet& v = mesh.tet(tet);
  return signed_volume(mesh.rest_position(v[0]), mesh.rest_position(v[1]), mesh.rest_position(v[2]),
                       mesh.rest_position(v[3]));
}

double total_volume(const TetMesh& mesh) {
  // Pairwise-free Kahan-style summation keeps 1e-12 relative accuracy on large meshes.
  double sum = 0.0;
  double compensation = 0.0;
  for (std::size_t t = 0; t < mesh.tet_count(); ++t) {
    const double y = signed_volume(mesh, static_cast<TetId>(t)) - compensation;
    const double s = sum + y;
    compensation = (s - sum) - y;
    sum = s;
  }
  return sum;
}

}  // namespace incise

namespace incise {

std::pair<Vec3, Vec3> bounding_box(const TetMesh& mesh) {
  if (mesh.vertex_count() == 0) {
    return {Vec3::Zero(), Vec3::Zero()};
  }
  Vec3 low = mesh.rest_position(0);
  Vec3 high = low;
  for (const Vec3& p : mesh.rest_positions()) {
    low = low.cwiseMin(p);
    high = high.cwiseMax(p);
  }
  return {low, high};
}

}  // namespace incise
