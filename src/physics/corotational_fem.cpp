#include "incise/physics/corotational_fem.hpp"

#include <algorithm>
#include <bit>
#include <chrono>
#include <cmath>

#include "incise/core/error.hpp"
#include "incise/core/growth.hpp"
#include "incise/core/parallel_for.hpp"
#include "incise/core/timing.hpp"
#include "incise/physics/corotational_batch.hpp"
#include "incise/physics/lumped_mass.hpp"

namespace incise {

CorotationalFemModel::CorotationalFemModel(TetMesh& mesh, const Material& material,
                                           const CorotationalFemParameters& parameters)
    : CorotationalFemModel(mesh, MaterialAssignment::uniform(material), parameters) {}

CorotationalFemModel::CorotationalFemModel(TetMesh& mesh, const MaterialAssignment& materials,
                                           const CorotationalFemParameters& parameters)
    : mesh_(&mesh),
      materials_(mesh, materials),
      parameters_(parameters),
      elements_(mesh, FemElement{}, TetRule::kDefault),
      tet_mass_(mesh, 0.0, TetRule::kDefault),
      rotations_(mesh, Eigen::Quaterniond::Identity(), TetRule::kCopy),
      masses_(mesh, 0.0, VertexRule::kDefault),
      slots_(mesh, {}, TetRule::kDefault),
      marks_(mesh) {
  for (const Material& material : materials_.table()) {
    lames_.push_back(lame_parameters(material.young_modulus, material.poisson_ratio));
  }
  if (!(parameters_.rayleigh_mass >= 0.0) || !(parameters_.rayleigh_stiffness >= 0.0) ||
      !std::isfinite(parameters_.rayleigh_mass) || !std::isfinite(parameters_.rayleigh_stiffness)) {
    throw InputError("Rayleigh damping coefficients must be non-negative (alpha 1/s, beta s)");
  }
  for (std::size_t t = 0; t < mesh.tet_count(); ++t) {
    const auto tet = static_cast<TetId>(t);
    Corners rest;
    for (int a = 0; a < 4; ++a) {
      rest[a] = mesh.rest_position(mesh.tet(tet)[a]);
    }
    elements_[tet].shape = tet_rest_shape(rest, static_cast<std::int64_t>(t));
    elements_[tet].valid = true;
    tet_mass_[tet] = materials_.of(tet).density * elements_[tet].shape.volume;
  }
  conserve_mass(tet_mass_, mesh_);
  mesh.add_observer(this);
  refresh();
}

CorotationalFemModel::~CorotationalFemModel() {
  if (mesh_ != nullptr) {
    mesh_->remove_observer(this);
  }
}

void CorotationalFemModel::set_material_fraction(TetId tet, double fraction) {
  mesh_->set_material_fraction(tet, fraction);  // on_material_fraction_changed follows
}

double CorotationalFemModel::total_mass() const {
  double total = 0.0;
  for (std::size_t t = 0; t < tet_mass_.size(); ++t) {
    total += tet_mass_[static_cast<TetId>(t)] * mesh_->material_fraction(static_cast<TetId>(t));
  }
  return total;
}

// ---- following edits ------------------------------------------------------------------------

void CorotationalFemModel::on_tet_reshaped(const TetMesh&, TetId tet, const Tet&) {
  elements_[tet].valid = false;
}

void CorotationalFemModel::on_vertex_relocated(const TetMesh& mesh, VertexId vertex,
                                               const VertexOrigin&) {
  for (TetId t : mesh.vertex_tets(vertex)) {
    elements_[t].valid = false;
  }
}

void CorotationalFemModel::update_element(TetId tet) {
  FemElement& element = elements_[tet];
  if (element.valid) {
    return;
  }
  const TetMesh& mesh = *mesh_;
  Corners rest;
  for (int a = 0; a < 4; ++a) {
    rest[a] = mesh.rest_position(mesh.tet(tet)[a]);
  }
  try {
    element.shape = tet_rest_shape(rest, static_cast<std::int64_t>(tet));
    element.valid = true;
  } catch (const InputError&) {
    // A sliver a cutter left behind: it carries mass but no stiffness, and validate()
    // reports it.
    element.shape = TetRestShape{};
  }
  if (tet_mass_[tet] == 0.0) {
    tet_mass_[tet] = materials_.of(tet).density * element.shape.volume;  // a tet added afresh
  }
}

void CorotationalFemModel::update_slots(TetId tet) {
  const Tet& vertices = mesh_->tet(tet);
  auto& slot = slots_[tet];
  for (int a = 0; a < 4; ++a) {
    for (int b = 0; b < 4; ++b) {
      slot[4 * a + b] = static_cast<std::uint32_t>(stiffness_.find(vertices[a], vertices[b]));
    }
  }
}

template <typename Body>
void CorotationalFemModel::for_each_incidence(VertexId vertex, const Body& body) const {
  for (const Incidence& incidence : incidences_.row(static_cast<std::size_t>(vertex))) {
    body(incidence.tet, incidence.corner);
  }
}

template <typename Prefetch, typename Body>
void CorotationalFemModel::for_each_incidence_ahead(std::size_t row, std::size_t last,
                                                    const Prefetch& prefetch,
                                                    const Body& body) const {
  // A row's elements lie scattered through the element arrays, so their loads can miss the
  // nearest caches: their data is asked for kIncidencesAhead incidences before its turn, from
  // the next row (up to `last`) once this one runs out (BENCHMARKS.md, session 58: on the
  // 384k-tet box the assembly about 6 % shorter, the forces with this gather about 9 %).
  const auto incidences = incidences_.row(row);
  const auto next = row + 1 < last ? incidences_.row(row + 1) : std::span<const Incidence>{};
  for (std::size_t k = 0; k < incidences.size(); ++k) {
    const std::size_t ahead = k + kIncidencesAhead;
    if (ahead < incidences.size()) {
      prefetch(incidences[ahead].tet);
    } else if (ahead - incidences.size() < next.size()) {
      prefetch(next[ahead - incidences.size()].tet);
    }
    body(incidences[k].tet, incidences[k].corner);
  }
}

template <typename T>
void CorotationalFemModel::prefetch_lines(const T& value) {
  const auto* bytes = reinterpret_cast<const char*>(&value);
  for (std::size_t offset = 0; offset < sizeof(T); offset += 64) {
    __builtin_prefetch(bytes + offset);
  }
  __builtin_prefetch(bytes + sizeof(T) - 1);  // the last line, where T straddles one more
}

void CorotationalFemModel::take_incidences(VertexId vertex, std::vector<Incidence>& row) const {
  row.clear();
  for (TetId tet : mesh_->vertex_tets(vertex)) {
    row.push_back({tet, mesh_->local_index(tet, vertex)});
  }
}

void CorotationalFemModel::rebuild_all() {
  const TetMesh& mesh = *mesh_;
  for (std::size_t t = 0; t < mesh.tet_count(); ++t) {
    update_element(static_cast<TetId>(t));
  }
  stiffness_.build_pattern(vertex_graph(mesh));
  std::vector<Incidence> row;
  incidences_.assign(mesh.vertex_count(), [&](std::size_t v) -> std::span<const Incidence> {
    take_incidences(static_cast<VertexId>(v), row);
    return row;
  });
  parallel_for(0, mesh.tet_count(), 1024, [&](std::size_t first, std::size_t last) {
    for (std::size_t t = first; t != last; ++t) {
      update_slots(static_cast<TetId>(t));
    }
  });
  parallel_for(0, mesh.vertex_count(), 1024, [&](std::size_t first, std::size_t last) {
    for (std::size_t v = first; v != last; ++v) {
      masses_[static_cast<VertexId>(v)] =
          vertex_lumped_mass(mesh, tet_mass_, static_cast<VertexId>(v));
    }
  });
}

void CorotationalFemModel::update_marked() {
  const TetMesh& mesh = *mesh_;
  // The tetrahedra at the marked vertices, each once: every element whose rest shape, vertices
  // or mass changed is among them (each such edit marked its vertices).
  touched_tets_.clear();
  for (VertexId v : marks_.marked()) {
    const auto tets = mesh.vertex_tets(v);
    touched_tets_.insert(touched_tets_.end(), tets.begin(), tets.end());
  }
  std::sort(touched_tets_.begin(), touched_tets_.end());
  touched_tets_.erase(std::unique(touched_tets_.begin(), touched_tets_.end()), touched_tets_.end());
  // Each element's rest shape and mass are its own: worked out on worker threads.
  parallel_for(0, touched_tets_.size(), 64, [&](std::size_t first, std::size_t last) {
    for (std::size_t i = first; i != last; ++i) {
      update_element(touched_tets_[i]);
    }
  });
  // Their rows: the vertex and every vertex of its tetrahedra (a vertex left without any
  // keeps only its diagonal), worked out on worker threads (they read the mesh only); the
  // matrix takes them one row after another.
  stiffness_.add_rows(mesh.vertex_count());
  const std::span<const VertexId> marked = marks_.marked();
  marked_columns_.resize(std::max(marked_columns_.size(), marked.size()));
  parallel_for(0, marked.size(), 32, [&](std::size_t first, std::size_t last) {
    for (std::size_t i = first; i != last; ++i) {
      std::vector<VertexId>& columns = marked_columns_[i];
      columns.assign(1, marked[i]);
      for (TetId t : mesh.vertex_tets(marked[i])) {
        const Tet& corners = mesh.tet(t);
        columns.insert(columns.end(), corners.begin(), corners.end());
      }
      std::sort(columns.begin(), columns.end());
      columns.erase(std::unique(columns.begin(), columns.end()), columns.end());
    }
  });
  for (std::size_t i = 0; i < marked.size(); ++i) {
    stiffness_.edit_row(marked[i], marked_columns_[i]);
  }
  if (stiffness_.compact_if_fragmented()) {
    parallel_for(0, mesh.tet_count(), 1024, [&](std::size_t first, std::size_t last) {
      for (std::size_t t = first; t != last; ++t) {
        update_slots(static_cast<TetId>(t));
      }
    });
  } else {
    // A row that changed holds blocks of its tetrahedra only, all touched. Each tetrahedron's
    // slots are its own.
    parallel_for(0, touched_tets_.size(), 64, [&](std::size_t first, std::size_t last) {
      for (std::size_t i = first; i != last; ++i) {
        update_slots(touched_tets_[i]);
      }
    });
  }
  incidences_.add_rows(mesh.vertex_count());
  std::vector<Incidence> row;
  for (VertexId v : marks_.marked()) {
    take_incidences(v, row);
    incidences_.set_row(static_cast<std::size_t>(v), row);
  }
  (void)incidences_.compact_if_fragmented();
  for (VertexId v : marks_.marked()) {
    masses_[v] = vertex_lumped_mass(mesh, tet_mass_, v);
  }
  if (frequency_kept_) {
    update_frequency_rows();
  }
}

void CorotationalFemModel::refresh() {
  const TetMesh& mesh = *mesh_;
  if (!rebuild_all_ && marks_.empty() && topology_revision_ == mesh.revision()) {
    return;
  }
  if (rebuild_all_ || marks_.empty()) {
    // A change no event told of (the mesh moved on without marking anything): built again.
    rebuild_all();
    frequency_kept_ = false;
  } else {
    update_marked();
  }
  marks_.clear();
  rebuild_all_ = false;
  topology_revision_ = mesh.revision();
  assembled_ = false;
}

// ---- element loops --------------------------------------------------------------------------

template <typename Body>
void CorotationalFemModel::for_each_valid_element_in_order(const Body& body) const {
  parallel_for(0, mesh_->tet_count(), 256, [&](std::size_t first, std::size_t last) {
    for (std::size_t t = first; t != last; ++t) {
      const auto tet = static_cast<TetId>(t);
      const FemElement& element = elements_[tet];
      if (element.valid) {
        body(tet, element);
      }
    }
  });
}

Corners CorotationalFemModel::corners(TetId tet, std::span<const Vec3> x) const {
  const Tet& vertices = mesh_->tet(tet);
  return {x[vertices[0]], x[vertices[1]], x[vertices[2]], x[vertices[3]]};
}

void CorotationalFemModel::add_forces(std::span<const Vec3> x, std::span<const Vec3> v,
                                      std::span<Vec3> f) const {
  element_forces(x, v, f, false);
}

void CorotationalFemModel::add_forces_and_linearize(std::span<const Vec3> x,
                                                    std::span<const Vec3> v, std::span<Vec3> f) {
  refresh();
  resize_linearization();
  element_forces(x, v, f, true);
  assemble_linearization_matrix();
}

void CorotationalFemModel::element_forces(std::span<const Vec3> x, std::span<const Vec3> v,
                                          std::span<Vec3> f, bool linearize) const {
  INCISE_ASSERT(topology_revision_ == mesh_->revision(), "FEM model used before refresh()");
  const TetMesh& mesh = *mesh_;
  // Pass 1, elements in memory order: -w V P per element (and the tangent data).
  resize_for_edits(scaled_stress_, mesh.tet_count());
  for_each_element_batch(
      x, [&](std::size_t t) { scaled_stress_[t].setZero(); },
      [&](const CorotatedBatch& batch, int lane, TetId tet) {
        take_batch_result(batch, lane, tet, v, true, linearize);
      });
  // Pass 2, vertices: gather f_i = sum over incident elements of (-w V P) grad N_corner, in
  // a fixed order per vertex, so the sum does not depend on the thread count.
  parallel_for(0, mesh.vertex_count(), 256, [&](std::size_t first, std::size_t last) {
    for (std::size_t i = first; i != last; ++i) {
      Vec3 sum = Vec3::Zero();
      const auto ask = [&](TetId tet) {
        prefetch_lines(elements_[tet]);
        prefetch_lines(scaled_stress_[static_cast<std::size_t>(tet)]);
      };
      for_each_incidence_ahead(i, last, ask, [&](TetId tet, int corner) {
        sum.noalias() +=
            scaled_stress_[static_cast<std::size_t>(tet)] * elements_[tet].shape.gradients[corner];
      });
      f[i] += sum;
      if (parameters_.rayleigh_mass > 0.0) {
        f[i] -= parameters_.rayleigh_mass * masses_[static_cast<VertexId>(i)] * v[i];
      }
    }
  });
}

template <typename Skip, typename Take>
void CorotationalFemModel::for_each_element_batch(std::span<const Vec3> x, const Skip& skip,
                                                  const Take& take) const {
  // Four elements at a time (corotational_batch.hpp), the valid ones with material, in memory
  // order; an element's result does not depend on its lane. Every pass that moves the
  // rotations' warm starts goes through here: one implementation, so a rotation that has
  // settled stays settled bit for bit (a model rebuilt after a cut then equals the one that
  // followed it).
  parallel_for(0, mesh_->tet_count(), 256, [&](std::size_t first, std::size_t last) {
    CorotatedBatch batch;
    std::array<TetId, kElementLanes> lane_tets{};
    int count = 0;
    const auto finish = [&] {
      corotated_batch(batch, count);
      for (int lane = 0; lane < count; ++lane) {
        take(batch, lane, lane_tets[static_cast<std::size_t>(lane)]);
      }
      count = 0;
    };
    for (std::size_t t = first; t != last; ++t) {
      const auto tet = static_cast<TetId>(t);
      const FemElement& element = elements_[tet];
      const double weight = mesh_->material_fraction(tet);
      if (!element.valid || weight == 0.0) {
        skip(t);
        continue;
      }
      const Tet& vertices = mesh_->tet(tet);
      for (int a = 0; a < 4; ++a) {
        set_lane_vector(batch.corners[a], count, x[static_cast<std::size_t>(vertices[a])]);
        set_lane_vector(batch.gradients[a], count, element.shape.gradients[a]);
      }
      const LameParameters& material = lame(tet);
      batch.mu[count] = material.mu;
      batch.lambda[count] = material.lambda;
      batch.stress_scale[count] = -weight * element.shape.volume;
      set_lane_quaternion(batch, count, rotations_[tet]);
      lane_tets[static_cast<std::size_t>(count)] = tet;
      if (++count == kElementLanes) {
        finish();
      }
    }
    if (count > 0) {
      finish();
    }
  });
}

void CorotationalFemModel::take_batch_result(const CorotatedBatch& batch, int lane, TetId tet,
                                             std::span<const Vec3> v, bool stress,
                                             bool linearize) const {
  const auto t = static_cast<std::size_t>(tet);
  const Mat3 R = lane_matrix(batch.rotation, lane);
  rotations_[tet] = lane_quaternion(batch, lane);
  const double beta = parameters_.rayleigh_stiffness;
  if (stress) {
    Mat3& scaled_stress = scaled_stress_[t];
    scaled_stress = lane_matrix(batch.scaled_stress, lane);
    if (beta > 0.0) {
      // Stiffness-proportional damping with the element's current rotation.
      const TetRestShape& shape = elements_[tet].shape;
      scaled_stress +=
          (beta * batch.stress_scale[lane]) *
          warped_stress_differential(R, lame(tet), deformation_gradient(corners(tet, v), shape));
    }
  }
  if (!linearize) {
    return;
  }
  if (parameters_.tangent != TangentKind::kWarped) {
    linearization_[t] = corotated_linearization(lane_matrix(batch.deformation, lane), R, lame(tet),
                                                parameters_.tangent);
    return;
  }
  if (warped_rotations_kept_) {
    warped_rotations_[t] = R;
  }
  auto& rotated = rotated_gradients_[t];
  for (int a = 0; a < 4; ++a) {
    rotated[a] = lane_vector(batch.rotated_gradients[a], lane);
  }
}

void CorotationalFemModel::resize_linearization() {
  const std::size_t count = mesh_->tet_count();
  if (parameters_.tangent == TangentKind::kWarped) {
    // The warped tangent is the rotation alone: 72 bytes per element where a full
    // linearisation takes 320 (the force pass writes one per element each step); its assembly
    // reads the rotated shape gradients only, so the rotations are kept only where products
    // go without a matrix (27 MB written a step at 384k tets that nothing read).
    warped_rotations_kept_ = !parameters_.assemble;
    if (warped_rotations_kept_) {
      resize_for_edits(warped_rotations_, count);
    }
    resize_for_edits(rotated_gradients_, count);
  } else {
    resize_for_edits(linearization_, count);
  }
}

void CorotationalFemModel::expect_warped_rotations_kept() const {
  INCISE_ASSERT(warped_rotations_kept_,
                "the warped tangent's rotations are kept only by a linearisation without assembly");
}

CorotatedLinearization CorotationalFemModel::linearization_of(TetId tet) const {
  const auto t = static_cast<std::size_t>(tet);
  if (parameters_.tangent != TangentKind::kWarped) {
    return linearization_[t];
  }
  expect_warped_rotations_kept();
  CorotatedLinearization linearization;
  linearization.warped = true;
  linearization.rotation = warped_rotations_[t];
  linearization.twist_weights.fill(-2.0 * lame(tet).mu);
  return linearization;
}

Vec3 CorotationalFemModel::vertex_force(VertexId vertex, const Vec3& x, const Vec3& v,
                                        const NeighborState& neighbor) const {
  const TetMesh& mesh = *mesh_;
  Vec3 force = -parameters_.rayleigh_mass * masses_[vertex] * v;
  for (TetId tet : mesh.vertex_tets(vertex)) {
    const FemElement& element = elements_[tet];
    const double weight = mesh_->material_fraction(tet);
    if (!element.valid || weight == 0.0) {
      continue;
    }
    Corners positions;
    Corners velocities;
    int local = 0;
    for (int a = 0; a < 4; ++a) {
      const VertexId corner = mesh.tet(tet)[a];
      if (corner == vertex) {
        positions[a] = x;
        velocities[a] = v;
        local = a;
      } else {
        neighbor(corner, positions[a], velocities[a]);
      }
    }
    const Mat3 F = deformation_gradient(positions, element.shape);
    Eigen::Quaterniond start = rotations_[tet];
    const Mat3 R = polar_rotation(F, start);
    Mat3 P = corotated_stress(F, R, lame(tet));
    if (parameters_.rayleigh_stiffness > 0.0) {
      P +=
          parameters_.rayleigh_stiffness *
          warped_stress_differential(R, lame(tet), deformation_gradient(velocities, element.shape));
    }
    force -= weight * element.shape.volume * P * element.shape.gradients[local];
  }
  return force;
}

std::span<const VertexId> CorotationalFemModel::neighbors(VertexId vertex) const {
  if (graph_revision_ != mesh_->revision()) {
    vertex_graph(*mesh_, graph_);
    graph_revision_ = mesh_->revision();
  }
  return graph_.neighbors(vertex);
}

// ---- linearisation --------------------------------------------------------------------------

void CorotationalFemModel::prepare_linearization(std::span<const Vec3> x, std::span<const Vec3>) {
  refresh();
  resize_linearization();
  for_each_element_batch(
      x, [](std::size_t) {},
      [&](const CorotatedBatch& batch, int lane, TetId tet) {
        take_batch_result(batch, lane, tet, {}, false, true);
      });
  assemble_linearization_matrix();
}

void CorotationalFemModel::assemble_linearization_matrix() {
  // Lazily: a solver that assembles its own system matrix (assemble_linearization) never needs
  // K on its own, and then nothing is assembled twice.
  assembled_ = false;
  assembly_pending_ = parameters_.assemble;
  assembly_seconds_ = 0.0;
}

void CorotationalFemModel::ensure_assembled() const {
  if (!assembly_pending_) {
    return;
  }
  const auto start = Clock::now();
  assemble_rows(stiffness_.values(), 1.0);
  assembled_ = true;
  assembly_pending_ = false;
  assembly_seconds_ += seconds_since(start);
}

void CorotationalFemModel::add_linearized_product(double a, double b, std::span<const Vec3> p,
                                                  std::span<Vec3> y) const {
  const double stiffness_scale = a + b * parameters_.rayleigh_stiffness;
  ensure_assembled();
  if (assembled_) {
    stiffness_.multiply_add(stiffness_scale, p, y);
  } else {
    // Per element dP (into scaled_stress_, free between force evaluations), then per vertex.
    const TetMesh& mesh = *mesh_;
    const bool warped = parameters_.tangent == TangentKind::kWarped;
    if (warped) {
      expect_warped_rotations_kept();
    }
    resize_for_edits(scaled_stress_, mesh.tet_count());
    parallel_for(0, mesh.tet_count(), 256, [&](std::size_t first, std::size_t last) {
      for (std::size_t t = first; t != last; ++t) {
        const auto tet = static_cast<TetId>(t);
        const FemElement& element = elements_[tet];
        const double weight = mesh.material_fraction(tet);
        if (!element.valid || weight == 0.0) {
          scaled_stress_[t].setZero();
          continue;
        }
        const Mat3 dF = deformation_gradient(corners(tet, p), element.shape);
        scaled_stress_[t] =
            (stiffness_scale * weight * element.shape.volume) *
            (warped ? warped_stress_differential(warped_rotations_[t], lame(tet), dF)
                    : stress_differential(linearization_[t], lame(tet), dF));
      }
    });
    parallel_for(0, mesh.vertex_count(), 256, [&](std::size_t first, std::size_t last) {
      for (std::size_t i = first; i != last; ++i) {
        Vec3 sum = Vec3::Zero();
        for_each_incidence(static_cast<VertexId>(i), [&](TetId tet, int corner) {
          sum.noalias() += scaled_stress_[static_cast<std::size_t>(tet)] *
                           elements_[tet].shape.gradients[corner];
        });
        y[i] += sum;
      }
    });
  }
  const double mass_scale = b * parameters_.rayleigh_mass;
  if (mass_scale != 0.0) {
    for (std::size_t i = 0; i < p.size(); ++i) {
      y[i] += mass_scale * masses_[static_cast<VertexId>(i)] * p[i];
    }
  }
}

void CorotationalFemModel::add_linearized_diagonal(double a, double b,
                                                   std::span<Mat3> diagonal) const {
  const double stiffness_scale = a + b * parameters_.rayleigh_stiffness;
  ensure_assembled();
  if (assembled_) {
    const auto values = stiffness_.values();
    for (std::size_t i = 0; i < diagonal.size(); ++i) {
      diagonal[i] += stiffness_scale * values[stiffness_.diagonal(static_cast<VertexId>(i))];
    }
  } else {
    parallel_for(0, mesh_->vertex_count(), 256, [&](std::size_t first, std::size_t last) {
      for (std::size_t i = first; i != last; ++i) {
        for_each_incidence(static_cast<VertexId>(i), [&](TetId tet, int corner) {
          const FemElement& element = elements_[tet];
          const double weight = mesh_->material_fraction(tet);
          if (element.valid && weight != 0.0) {
            diagonal[i] += stiffness_scale * stiffness_block(linearization_of(tet), lame(tet),
                                                             element.shape, weight, corner, corner);
          }
        });
      }
    });
  }
  const double mass_scale = b * parameters_.rayleigh_mass;
  if (mass_scale != 0.0) {
    for (std::size_t i = 0; i < diagonal.size(); ++i) {
      diagonal[i] += mass_scale * masses_[static_cast<VertexId>(i)] * Mat3::Identity();
    }
  }
}

bool CorotationalFemModel::assemble_linearization(double a, double b,
                                                  BlockSparseMatrix& matrix) const {
  const double stiffness_scale = a + b * parameters_.rayleigh_stiffness;
  matrix.match_pattern(stiffness_);
  auto out = matrix.values();
  if (assembled_) {
    const auto values = stiffness_.values();
    parallel_for(0, values.size(), 4096, [&](std::size_t first, std::size_t last) {
      for (std::size_t k = first; k != last; ++k) {
        out[k] = stiffness_scale * values[k];
      }
    });
  } else {
    const auto start = Clock::now();
    assemble_rows(out, stiffness_scale);
    assembly_seconds_ += seconds_since(start);
  }
  const double mass_scale = b * parameters_.rayleigh_mass;
  if (mass_scale != 0.0) {
    for (std::size_t i = 0; i < matrix.rows(); ++i) {
      out[matrix.diagonal(static_cast<VertexId>(i))] +=
          mass_scale * masses_[static_cast<VertexId>(i)] * Mat3::Identity();
    }
  }
  return true;
}

void CorotationalFemModel::assemble_rows(std::span<Mat3> out, double scale) const {
  // Row by row: each thread owns whole block rows, so nothing is shared and the sum order per
  // block is fixed (deterministic); every element's blocks are computed once in all.
  const auto row_begin = stiffness_.row_begin();
  const auto row_end = stiffness_.row_end();
  const bool warped = parameters_.tangent == TangentKind::kWarped;
  parallel_for(0, mesh_->vertex_count(), 128, [&](std::size_t first, std::size_t last) {
    for (std::size_t row = first; row != last; ++row) {
      for (std::size_t k = row_begin[row]; k < row_end[row]; ++k) {
        out[k].setZero();
      }
      const auto ask = [&](TetId tet) {
        prefetch_lines(elements_[tet]);
        prefetch_lines(slots_[tet]);
        if (warped) {
          prefetch_lines(rotated_gradients_[static_cast<std::size_t>(tet)]);
        }
      };
      for_each_incidence_ahead(row, last, ask, [&](TetId tet, int a) {
        const FemElement& element = elements_[tet];
        const double weight = mesh_->material_fraction(tet);
        if (!element.valid || weight == 0.0) {
          return;
        }
        const auto& slot = slots_[tet];
        if (warped) {
          const auto& rotated = rotated_gradients_[static_cast<std::size_t>(tet)];
          const double factor = scale * weight * element.shape.volume;
          const Vec3 lambda_a = (factor * lame(tet).lambda) * rotated[a];
          const Vec3 mu_a = (factor * lame(tet).mu) * rotated[a];
          const Vec3& gradient_a = element.shape.gradients[a];
          std::array<Mat3*, 4> blocks;
          std::array<double, 4> diagonal;
          for (int b = 0; b < 4; ++b) {
            blocks[static_cast<std::size_t>(b)] = &out[slot[4 * a + b]];
            diagonal[static_cast<std::size_t>(b)] =
                factor * lame(tet).mu * gradient_a.dot(element.shape.gradients[b]);
          }
          add_warped_stiffness_row(blocks, lambda_a, mu_a, rotated, diagonal);
          return;
        }
        const CorotatedLinearization& linearization = linearization_[tet];
        for (int b = 0; b < 4; ++b) {
          out[slot[4 * a + b]] +=
              stiffness_block(linearization, lame(tet), element.shape, scale * weight, a, b);
        }
      });
    }
  });
}

double CorotationalFemModel::elastic_energy(std::span<const Vec3> x) const {
  const TetMesh& mesh = *mesh_;
  std::vector<double> energy(mesh.tet_count(), 0.0);
  for_each_valid_element_in_order([&](TetId tet, const FemElement& element) {
    const Mat3 F = deformation_gradient(corners(tet, x), element.shape);
    Eigen::Quaterniond start = rotations_[tet];
    energy[static_cast<std::size_t>(tet)] =
        mesh_->material_fraction(tet) * element.shape.volume *
        corotated_energy_density(F, polar_rotation(F, start), lame(tet));
  });
  double total = 0.0;
  for (double e : energy) {
    total += e;  // serial: the same sum whatever the thread count
  }
  return total;
}

double CorotationalFemModel::frequency_row(VertexId vertex) const {
  // Row `vertex` of the Gershgorin bound on M^-1/2 K M^-1/2 with the rest stiffness (1/s^2).
  const double ma = masses_[vertex];
  if (ma <= 0.0) {
    return 0.0;
  }
  double row = 0.0;
  for_each_incidence(vertex, [&](TetId tet, int a) {
    const FemElement& element = elements_[tet];
    if (!element.valid) {
      return;
    }
    const Tet& corners = mesh_->tet(tet);
    const CorotatedLinearization& rest =
        rest_linearizations_[static_cast<std::size_t>(materials_.id(tet))];
    for (int b = 0; b < 4; ++b) {
      const double mb = masses_[corners[b]];
      if (mb <= 0.0) {
        continue;
      }
      const Mat3 block =
          stiffness_block(rest, lame(tet), element.shape, mesh_->material_fraction(tet), a, b);
      row += block.cwiseAbs().rowwise().sum().maxCoeff() / std::sqrt(ma * mb);
    }
  });
  return row;
}

void CorotationalFemModel::update_frequency_rows() {
  // Rows read the vertex's elements and its neighbours' masses: the marked vertices and the
  // vertices of the touched elements hold every row an edit changed (a marked vertex left
  // without elements has a zero row now).
  frequency_.grow(mesh_->vertex_count());
  for (VertexId v : marks_.marked()) {
    frequency_.set(v, frequency_row(v));
  }
  for (TetId t : touched_tets_) {
    for (VertexId v : mesh_->tet(t)) {
      frequency_.set(v, frequency_row(v));
    }
  }
  frequency_.settle();
}

double CorotationalFemModel::max_vertex_frequency() const {
  // A whole-body pass the first time an explicit scheme asks (implicit ones never do); from
  // then on refresh() updates the rows an edit changed.
  if (!frequency_kept_) {
    rest_linearizations_.clear();
    for (const LameParameters& lame : lames_) {
      rest_linearizations_.push_back(
          corotated_linearization(Mat3::Identity(), Mat3::Identity(), lame, TangentKind::kWarped));
    }
    frequency_.fill(mesh_->vertex_count(), [this](VertexId v) { return frequency_row(v); });
    frequency_kept_ = true;
  }
  return std::sqrt(frequency_.largest());
}

}  // namespace incise
