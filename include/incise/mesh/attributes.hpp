#pragma once
// Attribute containers: per-vertex, per-tetrahedron and per-edge data that follow every edit
// of a TetMesh. A model keeps its state here (positions, velocities, masses, rest shapes,
// springs) and never needs to know which cutter changed the mesh.
//
// Rules for new entries (the "specification" the tests check):
//   vertices  fresh: the default value. A relocated vertex is taken again like a new one.
//             combination of parents with weights w: kInterpolate gives sum w_i * value(p_i),
//             kCopy the value of the heaviest parent, kDefault the default.
//             duplicate of v: kInterpolate and kCopy give value(v), kDefault the default.
//   tets      fresh: the default. replaced by children: kCopy gives each child the parent's
//             value, kDefault the default.
//   edges     with a parent edge and fraction f = |new| / |parent|: kCopy gives the parent's
//             value, kScale f * value(parent), kDefault the default; without a parent: default.
// After the rule, an optional hook may adjust any entry (e.g. split a lumped mass so the total
// is conserved). Removed entries are dropped by swapping with the last, like the mesh does.

#include <concepts>
#include <functional>
#include <span>
#include <utility>
#include <vector>

#include "incise/core/error.hpp"
#include "incise/core/growth.hpp"
#include "incise/mesh/tet_mesh.hpp"

namespace incise {

/// Types that can be blended: scaled by a double and added.
template <typename T>
concept Blendable = requires(const T& a, double w) {
  {T(a * w)};
  {T(a + a)};
};

enum class VertexRule { kInterpolate, kCopy, kDefault };
enum class TetRule { kCopy, kDefault };
enum class EdgeRule { kCopy, kScale, kDefault };

namespace detail {

/// Shared plumbing: storage, observer registration, relocation.
template <typename T>
class AttributeBase : public MeshObserver {
 public:
  AttributeBase(const AttributeBase&) = delete;
  AttributeBase& operator=(const AttributeBase&) = delete;
  /// Takes the other's values and its place among the mesh's observers.
  AttributeBase(AttributeBase&& other) noexcept
      : MeshObserver(other),
        mesh_(std::exchange(other.mesh_, nullptr)),
        values_(std::move(other.values_)),
        default_value_(std::move(other.default_value_)) {
    if (mesh_ != nullptr) {
      mesh_->replace_observer(&other, this);
    }
  }
  AttributeBase& operator=(AttributeBase&&) = delete;
  ~AttributeBase() override {
    if (mesh_ != nullptr) {
      mesh_->remove_observer(this);
    }
  }

  [[nodiscard]] std::size_t size() const { return values_.size(); }     ///< one per entity
  [[nodiscard]] T& operator[](std::int32_t id) { return values_[id]; }  ///< by entity id
  /// By entity id.
  [[nodiscard]] const T& operator[](std::int32_t id) const { return values_[id]; }
  [[nodiscard]] std::span<T> values() { return values_; }  ///< every value, by entity id
  /// Every value, by entity id.
  [[nodiscard]] std::span<const T> values() const { return values_; }
  /// What new entities get when their rule gives nothing else.
  [[nodiscard]] const T& default_value() const { return default_value_; }
  /// The mesh followed, or nullptr once it is destroyed.
  [[nodiscard]] const TetMesh* mesh() const { return mesh_; }
  /// Sets every value.
  void fill(const T& value) { std::fill(values_.begin(), values_.end(), value); }

  void on_mesh_destroyed() override { mesh_ = nullptr; }

  void save_state(StateWriter& out) const override {
    static_assert(RawState<T>, "attributes saved in checkpoints hold plain values");
    out.tag("attribute");
    out.values(values_);
  }
  void load_state(StateReader& in) override {
    in.tag("attribute");
    std::vector<T> values = in.values<T>("attribute values");
    if (values.size() != count_in(*mesh_)) {
      in.fail("attribute values", std::to_string(values.size()) + " values for " +
                                      std::to_string(count_in(*mesh_)) + " mesh entities");
    }
    values_ = std::move(values);
    reserve_for_edits(values_);
  }

 protected:
  /// How many values the mesh needs (vertices, tetrahedra or edges).
  [[nodiscard]] virtual std::size_t count_in(const TetMesh& mesh) const = 0;

  /// `count` values of `default_value`, following `mesh` from now on.
  AttributeBase(TetMesh& mesh, std::size_t count, T default_value)
      : mesh_(&mesh), values_(count, default_value), default_value_(std::move(default_value)) {
    reserve_for_edits(values_);
    mesh.add_observer(this);
  }

  /// The mesh removed entity `removed` and moved its last one (`moved_from`) into its place.
  void swap_remove(std::int32_t removed, std::int32_t moved_from) {
    INCISE_ASSERT(static_cast<std::size_t>(moved_from) + 1 == values_.size(),
                  "attribute container out of step with its mesh");
    if (removed != moved_from) {
      values_[removed] = std::move(values_[moved_from]);
    }
    values_.pop_back();
  }

  TetMesh* mesh_;          ///< the mesh followed; null once it is destroyed
  std::vector<T> values_;  ///< one per entity
  T default_value_;        ///< for entities no rule fills
};

}  // namespace detail

/// One value per vertex.
template <typename T>
class VertexData final : public detail::AttributeBase<T> {
 public:
  /// Called after the rule fills a new or relocated vertex's value.
  using Hook = std::function<void(VertexData&, VertexId, const VertexOrigin&)>;
  /// Interpolate what can be blended (numbers, vectors), copy the rest.
  static constexpr VertexRule kDefaultRule =
      Blendable<T> ? VertexRule::kInterpolate : VertexRule::kCopy;

  /// One value per vertex of `mesh` (which must outlive it), following its edits by `rule`.
  explicit VertexData(TetMesh& mesh, T default_value = T{}, VertexRule rule = kDefaultRule)
      : detail::AttributeBase<T>(mesh, mesh.vertex_count(), std::move(default_value)),
        rule_(rule) {}

  void set_hook(Hook hook) { hook_ = std::move(hook); }  ///< see Hook
  [[nodiscard]] std::size_t count_in(const TetMesh& mesh) const override {
    return mesh.vertex_count();
  }

  void on_vertex_added(const TetMesh& /*mesh*/, VertexId vertex,
                       const VertexOrigin& origin) override {
    INCISE_ASSERT(static_cast<std::size_t>(vertex) == this->values_.size(),
                  "vertex attribute out of step with its mesh");
    this->values_.push_back(initial_value(origin));
    if (hook_) {
      hook_(*this, vertex, origin);
    }
  }

  void on_vertex_relocated(const TetMesh& /*mesh*/, VertexId vertex,
                           const VertexOrigin& origin) override {
    this->values_[vertex] = initial_value(origin);
    if (hook_) {
      hook_(*this, vertex, origin);
    }
  }

 private:
  T initial_value(const VertexOrigin& origin) const {
    if (origin.kind == VertexOrigin::Kind::kFresh || rule_ == VertexRule::kDefault) {
      return this->default_value_;
    }
    if (origin.kind == VertexOrigin::Kind::kDuplicate) {
      return this->values_[origin.parents[0]];
    }
    if constexpr (Blendable<T>) {
      if (rule_ == VertexRule::kInterpolate) {
        T blended = T(this->values_[origin.parents[0]] * origin.weights[0]);
        for (int i = 1; i < origin.parent_count; ++i) {
          blended = T(blended + T(this->values_[origin.parents[i]] * origin.weights[i]));
        }
        return blended;
      }
    }
    int heaviest = 0;
    for (int i = 1; i < origin.parent_count; ++i) {
      if (origin.weights[i] > origin.weights[heaviest]) {
        heaviest = i;
      }
    }
    return this->values_[origin.parents[heaviest]];
  }

  VertexRule rule_;
  Hook hook_;
};

/// One value per tetrahedron.
template <typename T>
class TetData final : public detail::AttributeBase<T> {
 public:
  /// Called after the rule with the replaced parent's old value.
  using Hook = std::function<void(TetData&, TetId parent, std::span<const TetId> children,
                                  const T& parent_value)>;

  /// One value per tetrahedron of `mesh` (which must outlive it), following its edits by `rule`.
  explicit TetData(TetMesh& mesh, T default_value = T{}, TetRule rule = TetRule::kCopy)
      : detail::AttributeBase<T>(mesh, mesh.tet_count(), std::move(default_value)), rule_(rule) {}

  /// Called when a tetrahedron is absorbed by another (collapse_vertex), before it is removed,
  /// with its value: e.g. adds its mass to `into`'s. Without one its value is dropped.
  using AbsorbHook = std::function<void(TetData&, TetId into, const T& removed_value)>;

  void set_hook(Hook hook) { hook_ = std::move(hook); }                      ///< see Hook
  void set_absorb_hook(AbsorbHook hook) { absorb_hook_ = std::move(hook); }  ///< see AbsorbHook
  [[nodiscard]] std::size_t count_in(const TetMesh& mesh) const override {
    return mesh.tet_count();
  }

  void on_tet_added(const TetMesh& /*mesh*/, TetId tet) override {
    INCISE_ASSERT(static_cast<std::size_t>(tet) == this->values_.size(),
                  "tet attribute out of step with its mesh");
    this->values_.push_back(this->default_value_);
  }

  void on_tet_replaced(const TetMesh& /*mesh*/, TetId parent, std::span<const TetId> children,
                       const Tet& /*parent_vertices*/) override {
    const T parent_value = this->values_[parent];
    const T& child_value = rule_ == TetRule::kCopy ? parent_value : this->default_value_;
    this->values_.resize(this->values_.size() + children.size() - 1, child_value);
    for (TetId child : children) {
      this->values_[child] = child_value;
    }
    if (hook_) {
      hook_(*this, parent, children, parent_value);
    }
  }

  void on_tet_removed(const TetMesh& /*mesh*/, TetId removed, TetId moved_from,
                      const Tet& /*removed_vertices*/) override {
    this->swap_remove(removed, moved_from);
  }

  void on_tet_absorbed(const TetMesh& /*mesh*/, TetId removed, TetId into, TetId moved_from,
                       const Tet& /*removed_vertices*/) override {
    if (absorb_hook_) {
      absorb_hook_(*this, into, this->values_[removed]);
    }
    this->swap_remove(removed, moved_from);
  }

 private:
  TetRule rule_;
  Hook hook_;
  AbsorbHook absorb_hook_;
};

/// One value per edge.
template <typename T>
class EdgeData final : public detail::AttributeBase<T> {
 public:
  /// Called after the rule fills a new edge's value.
  using Hook = std::function<void(EdgeData&, const EdgeOrigin&)>;

  /// One value per edge of `mesh` (which must outlive it), following its edits by `rule`.
  explicit EdgeData(TetMesh& mesh, T default_value = T{}, EdgeRule rule = EdgeRule::kCopy)
      : detail::AttributeBase<T>(mesh, mesh.edge_count(), std::move(default_value)), rule_(rule) {}

  void set_hook(Hook hook) { hook_ = std::move(hook); }  ///< see Hook
  [[nodiscard]] std::size_t count_in(const TetMesh& mesh) const override {
    return mesh.edge_count();
  }

  void on_edges_created(const TetMesh& /*mesh*/, std::span<const EdgeOrigin> edges) override {
    for (const EdgeOrigin& origin : edges) {
      INCISE_ASSERT(static_cast<std::size_t>(origin.edge) == this->values_.size(),
                    "edge attribute out of step with its mesh");
      this->values_.push_back(initial_value(origin));
      if (hook_) {
        hook_(*this, origin);
      }
    }
  }

  void on_edge_removed(const TetMesh& /*mesh*/, EdgeId removed, EdgeId moved_from) override {
    this->swap_remove(removed, moved_from);
  }

 private:
  T initial_value(const EdgeOrigin& origin) const {
    if (origin.parent == kInvalidId || rule_ == EdgeRule::kDefault) {
      return this->default_value_;
    }
    if constexpr (Blendable<T>) {
      if (rule_ == EdgeRule::kScale) {
        return T(this->values_[origin.parent] * origin.fraction);
      }
    }
    return this->values_[origin.parent];
  }

  EdgeRule rule_;
  Hook hook_;
};

}  // namespace incise
