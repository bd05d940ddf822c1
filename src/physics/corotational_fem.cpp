#include "incise/physics/corotational_fem.hpp"

#include <algorithm>
#include <bit>
#include <chrono>
#include <cmath>

#include "incise/core/error.hpp"
#include "incise/core/parallel_for.hpp"
#include "incise/core/timing.hpp"
#include "incise/physics/lumped_mass.hpp"

namespace incise {

namespace {

/// Colours 0..63 come from a 64-bit mask per vertex; the rare element that finds all of them
/// taken around its corners goes to colour 64, which is processed serially.
constexpr std::size_t kParallelColours = 64;

}  // namespace

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
      masses_(mesh, 0.0, VertexRule::kDefault) {
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

void CorotationalFemModel::on_vertex_relocated(const TetMesh& mesh, VertexId vertex,
                                               const VertexOrigin&) {
  for (TetId t : mesh.vertex_tets(vertex)) {
    elements_[t].valid = false;
  }
}

void CorotationalFemModel::update_rest_data() {
  const TetMesh& mesh = *mesh_;
  for (std::size_t t = 0; t < mesh.tet_count(); ++t) {
    const auto tet = static_cast<TetId>(t);
    FemElement& element = elements_[tet];
    if (element.valid) {
      continue;
    }
    Corners rest;
    for (int a = 0; a < 4; ++a) {
      rest[a] = mesh.rest_position(mesh.tet(tet)[a]);
    }
    try {
      element.shape = tet_rest_shape(rest, static_cast<std::int64_t>(t));
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
}

void CorotationalFemModel::rebuild_topology() {
  const TetMesh& mesh = *mesh_;
  const std::size_t n = mesh.vertex_count();
  const std::size_t tets = mesh.tet_count();
  vertex_graph(mesh, graph_);
  // Greedy colouring in tet order: deterministic.
  std::vector<std::uint64_t> used(n, 0);
  std::vector<std::uint8_t> colour(tets);
  std::vector<std::size_t> count(kParallelColours + 1, 0);
  for (std::size_t t = 0; t < tets; ++t) {
    const Tet& tet = mesh.tet(static_cast<TetId>(t));
    const std::uint64_t taken = used[tet[0]] | used[tet[1]] | used[tet[2]] | used[tet[3]];
    std::size_t c = kParallelColours;
    if (taken != ~std::uint64_t{0}) {
      c = static_cast<std::size_t>(std::countr_one(taken));
      for (VertexId v : tet) {
        used[v] |= std::uint64_t{1} << c;
      }
    }
    colour[t] = static_cast<std::uint8_t>(c);
    ++count[c];
  }
  std::size_t last = 0;
  for (std::size_t c = 0; c <= kParallelColours; ++c) {
    if (count[c] > 0) {
      last = c + 1;
    }
  }
  colour_start_.assign(last + 1, 0);
  for (std::size_t c = 0; c < last; ++c) {
    colour_start_[c + 1] = colour_start_[c] + count[c];
  }
  coloured_tets_.resize(tets);
  std::vector<std::size_t> cursor(colour_start_.begin(), colour_start_.end() - 1);
  for (std::size_t t = 0; t < tets; ++t) {
    coloured_tets_[cursor[colour[t]]++] = static_cast<TetId>(t);
  }
  // Vertex -> (element, corner) incidences, for assembly row by row.
  incidence_start_.assign(n + 1, 0);
  for (std::size_t t = 0; t < tets; ++t) {
    for (VertexId v : mesh.tet(static_cast<TetId>(t))) {
      ++incidence_start_[static_cast<std::size_t>(v) + 1];
    }
  }
  for (std::size_t v = 0; v < n; ++v) {
    incidence_start_[v + 1] += incidence_start_[v];
  }
  incidences_.resize(incidence_start_[n]);
  std::vector<std::size_t> next(incidence_start_.begin(), incidence_start_.end() - 1);
  for (std::size_t t = 0; t < tets; ++t) {
    const Tet& tet = mesh.tet(static_cast<TetId>(t));
    for (int a = 0; a < 4; ++a) {
      incidences_[next[tet[a]]++] = {static_cast<TetId>(t), a};
    }
  }
  // Matrix pattern and each element's slots in it.
  stiffness_.build_pattern(graph_, mesh.revision());
  slots_.resize(tets);
  for (std::size_t t = 0; t < tets; ++t) {
    const Tet& tet = mesh.tet(static_cast<TetId>(t));
    for (int a = 0; a < 4; ++a) {
      for (int b = 0; b < 4; ++b) {
        slots_[t][4 * a + b] = static_cast<std::uint32_t>(stiffness_.find(tet[a], tet[b]));
      }
    }
  }
  assembled_ = false;
}

void CorotationalFemModel::refresh() {
  const TetMesh& mesh = *mesh_;
  const bool topology_changed = topology_revision_ != mesh.revision();
  if (!topology_changed && !masses_stale_) {
    return;
  }
  if (topology_changed) {
    update_rest_data();
    rebuild_topology();
    topology_revision_ = mesh.revision();
  }
  // Lumped masses: a quarter of each adjacent element's mass, summed afresh.
  masses_.fill(0.0);
  for (std::size_t t = 0; t < mesh.tet_count(); ++t) {
    const auto tet = static_cast<TetId>(t);
    const double quarter = 0.25 * tet_mass_[tet] * mesh_->material_fraction(tet);
    for (VertexId v : mesh.tet(tet)) {
      masses_[v] += quarter;
    }
  }
  masses_stale_ = false;
  frequency_revision_ = kNoRevision;  // the bound is taken again when asked for
}

// ---- element loops --------------------------------------------------------------------------

template <typename Body>
void CorotationalFemModel::for_each_element(const Body& body) const {
  for (std::size_t c = 0; c + 1 < colour_start_.size(); ++c) {
    const std::size_t begin = colour_start_[c];
    const std::size_t end = colour_start_[c + 1];
    // Elements with a degenerate rest shape or no material contribute nothing.
    auto visit = [&](std::size_t k) {
      const TetId tet = coloured_tets_[k];
      const FemElement& element = elements_[tet];
      const double weight = mesh_->material_fraction(tet);
      if (element.valid && weight != 0.0) {
        body(tet, element, weight);
      }
    };
    if (c >= kParallelColours) {
      for (std::size_t k = begin; k < end; ++k) {
        visit(k);
      }
      continue;
    }
    parallel_for(begin, end, 64, [&](std::size_t first, std::size_t last) {
      for (std::size_t k = first; k != last; ++k) {
        visit(k);
      }
    });
  }
}

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
  linearization_.resize(mesh_->tet_count());
  rotated_gradients_.resize(mesh_->tet_count());
  element_forces(x, v, f, true);
  assemble_linearization_matrix();
}

void CorotationalFemModel::element_forces(std::span<const Vec3> x, std::span<const Vec3> v,
                                          std::span<Vec3> f, bool linearize) const {
  INCISE_ASSERT(topology_revision_ == mesh_->revision(), "FEM model used before refresh()");
  const TetMesh& mesh = *mesh_;
  const double beta = parameters_.rayleigh_stiffness;
  // Pass 1, elements in memory order: -w V P per element (and the tangent data).
  scaled_stress_.resize(mesh.tet_count());
  parallel_for(0, mesh.tet_count(), 256, [&](std::size_t first, std::size_t last) {
    for (std::size_t t = first; t != last; ++t) {
      const auto tet = static_cast<TetId>(t);
      const FemElement& element = elements_[tet];
      const double weight = mesh_->material_fraction(tet);
      if (!element.valid || weight == 0.0) {
        scaled_stress_[t].setZero();
        continue;
      }
      const Mat3 F = deformation_gradient(corners(tet, x), element.shape);
      const Mat3 R = polar_rotation(F, rotations_[tet]);
      Mat3 P = corotated_stress(F, R, lame(tet));
      if (beta > 0.0) {
        // Stiffness-proportional damping with the element's current rotation.
        P += beta * warped_stress_differential(
                        R, lame(tet), deformation_gradient(corners(tet, v), element.shape));
      }
      scaled_stress_[t] = (-weight * element.shape.volume) * P;
      if (linearize) {
        store_linearization(tet, F, R);
      }
    }
  });
  // Pass 2, vertices: gather f_i = sum over incident elements of (-w V P) grad N_corner, in
  // a fixed order per vertex, so the sum does not depend on the thread count.
  parallel_for(0, mesh.vertex_count(), 256, [&](std::size_t first, std::size_t last) {
    for (std::size_t i = first; i != last; ++i) {
      Vec3 sum = Vec3::Zero();
      for (std::size_t k = incidence_start_[i]; k < incidence_start_[i + 1]; ++k) {
        const auto [tet, corner] = incidences_[k];
        sum.noalias() +=
            scaled_stress_[static_cast<std::size_t>(tet)] * elements_[tet].shape.gradients[corner];
      }
      f[i] += sum;
      if (parameters_.rayleigh_mass > 0.0) {
        f[i] -= parameters_.rayleigh_mass * masses_[static_cast<VertexId>(i)] * v[i];
      }
    }
  });
}

void CorotationalFemModel::store_linearization(TetId tet, const Mat3& F, const Mat3& R) const {
  CorotatedLinearization& linearization = linearization_[static_cast<std::size_t>(tet)];
  if (parameters_.tangent == TangentKind::kWarped) {
    // Only what the warped tangent reads: a third of the bytes of a full linearisation.
    linearization.warped = true;
    linearization.rotation = R;
    linearization.twist_weights.fill(-2.0 * lame(tet).mu);
  } else {
    linearization = corotated_linearization(F, R, lame(tet), parameters_.tangent);
  }
  auto& rotated = rotated_gradients_[static_cast<std::size_t>(tet)];
  for (int a = 0; a < 4; ++a) {
    rotated[a] = R * elements_[tet].shape.gradients[a];
  }
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
  return graph_.neighbors(vertex);
}

// ---- linearisation --------------------------------------------------------------------------

void CorotationalFemModel::prepare_linearization(std::span<const Vec3> x, std::span<const Vec3>) {
  refresh();
  const TetMesh& mesh = *mesh_;
  linearization_.resize(mesh.tet_count());
  rotated_gradients_.resize(mesh.tet_count());
  for_each_valid_element_in_order([&](TetId tet, const FemElement& element) {
    const Mat3 F = deformation_gradient(corners(tet, x), element.shape);
    store_linearization(tet, F, polar_rotation(F, rotations_[tet]));
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
    for_each_element([&](TetId tet, const FemElement& element, double weight) {
      const Mat3 dF = deformation_gradient(corners(tet, p), element.shape);
      const Mat3 dP = (stiffness_scale * weight * element.shape.volume) *
                      stress_differential(linearization_[tet], lame(tet), dF);
      const Tet& vertices = mesh_->tet(tet);
      for (int c = 0; c < 4; ++c) {
        y[vertices[c]] += dP * element.shape.gradients[c];
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
    for_each_element([&](TetId tet, const FemElement& element, double weight) {
      const Tet& vertices = mesh_->tet(tet);
      for (int c = 0; c < 4; ++c) {
        diagonal[vertices[c]] += stiffness_scale * stiffness_block(linearization_[tet], lame(tet),
                                                                   element.shape, weight, c, c);
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
  const auto row_start = stiffness_.row_start();
  const bool warped = parameters_.tangent == TangentKind::kWarped;
  parallel_for(0, incidence_start_.size() - 1, 128, [&](std::size_t first, std::size_t last) {
    for (std::size_t row = first; row != last; ++row) {
      for (std::size_t k = row_start[row]; k < row_start[row + 1]; ++k) {
        out[k].setZero();
      }
      for (std::size_t k = incidence_start_[row]; k < incidence_start_[row + 1]; ++k) {
        const auto [tet, a] = incidences_[k];
        const FemElement& element = elements_[tet];
        const double weight = mesh_->material_fraction(tet);
        if (!element.valid || weight == 0.0) {
          continue;
        }
        const auto& slot = slots_[static_cast<std::size_t>(tet)];
        if (warped) {
          const auto& rotated = rotated_gradients_[static_cast<std::size_t>(tet)];
          const double factor = scale * weight * element.shape.volume;
          const Vec3 lambda_a = (factor * lame(tet).lambda) * rotated[a];
          const Vec3 mu_a = (factor * lame(tet).mu) * rotated[a];
          const Vec3& gradient_a = element.shape.gradients[a];
          for (int b = 0; b < 4; ++b) {
            add_warped_stiffness_block(
                out[slot[4 * a + b]], lambda_a, mu_a, rotated[b],
                factor * lame(tet).mu * gradient_a.dot(element.shape.gradients[b]));
          }
          continue;
        }
        const CorotatedLinearization& linearization = linearization_[tet];
        for (int b = 0; b < 4; ++b) {
          out[slot[4 * a + b]] +=
              stiffness_block(linearization, lame(tet), element.shape, scale * weight, a, b);
        }
      }
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

double CorotationalFemModel::max_vertex_frequency() const {
  // Gershgorin bound on M^-1/2 K M^-1/2 with the rest stiffness: a whole-body pass, so taken
  // only when an explicit scheme asks (implicit ones never do), once per mesh revision.
  if (frequency_revision_ == mesh_->revision()) {
    return max_frequency_;
  }
  const TetMesh& mesh = *mesh_;
  std::vector<double> row(mesh.vertex_count(), 0.0);
  std::vector<CorotatedLinearization> rest_linearizations;  // per material
  for (const LameParameters& lame : lames_) {
    rest_linearizations.push_back(
        corotated_linearization(Mat3::Identity(), Mat3::Identity(), lame, TangentKind::kWarped));
  }
  for (std::size_t t = 0; t < mesh.tet_count(); ++t) {
    const auto tet = static_cast<TetId>(t);
    const FemElement& element = elements_[tet];
    if (!element.valid) {
      continue;
    }
    const Tet& corners = mesh.tet(tet);
    for (int a = 0; a < 4; ++a) {
      const double ma = masses_[corners[a]];
      if (ma <= 0.0) {
        continue;
      }
      for (int b = 0; b < 4; ++b) {
        const double mb = masses_[corners[b]];
        if (mb <= 0.0) {
          continue;
        }
        const Mat3 block =
            stiffness_block(rest_linearizations[static_cast<std::size_t>(materials_.id(tet))],
                            lame(tet), element.shape, mesh_->material_fraction(tet), a, b);
        row[corners[a]] += block.cwiseAbs().rowwise().sum().maxCoeff() / std::sqrt(ma * mb);
      }
    }
  }
  max_frequency_ = row.empty() ? 0.0 : std::sqrt(*std::max_element(row.begin(), row.end()));
  frequency_revision_ = mesh.revision();
  return max_frequency_;
}

}  // namespace incise
