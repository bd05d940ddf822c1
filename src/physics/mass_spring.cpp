#include "incise/physics/mass_spring.hpp"

#include <algorithm>
#include <cmath>

#include "incise/core/error.hpp"
#include "incise/physics/lumped_mass.hpp"

namespace incise {

std::array<Vec3, 4> volume_gradient(const std::array<Vec3, 4>& x) {
  const Vec3 e1 = x[1] - x[0];
  const Vec3 e2 = x[2] - x[0];
  const Vec3 e3 = x[3] - x[0];
  std::array<Vec3, 4> g{Vec3::Zero(), e2.cross(e3) / 6.0, e3.cross(e1) / 6.0, e1.cross(e2) / 6.0};
  g[0] = -(g[1] + g[2] + g[3]);
  return g;
}

MassSpringModel::MassSpringModel(TetMesh& mesh, const Material& material,
                                 const MassSpringParameters& parameters)
    : MassSpringModel(mesh, MaterialAssignment::uniform(material), parameters) {}

MassSpringModel::MassSpringModel(TetMesh& mesh, const MaterialAssignment& materials,
                                 const MassSpringParameters& parameters)
    : mesh_(&mesh),
      materials_(mesh, materials),
      parameters_(parameters),
      tet_mass_(mesh, 0.0, TetRule::kDefault),
      masses_(mesh, 0.0, VertexRule::kDefault),
      springs_(mesh, Spring{}, EdgeRule::kDefault),
      volume_terms_(mesh, {0.0, 0.0}, TetRule::kDefault),
      marks_(mesh) {
  if (!(parameters_.prestrain >= 0.0 && parameters_.prestrain < 1.0)) {
    throw InputError("prestrain must lie in [0, 1)");
  }
  if (!(parameters_.volume_stiffness >= 0.0) || !std::isfinite(parameters_.volume_stiffness)) {
    throw InputError("volume stiffness must be non-negative");
  }
  if (!(parameters_.spring_damping_ratio >= 0.0) ||
      !std::isfinite(parameters_.spring_damping_ratio)) {
    throw InputError("spring damping ratio must be non-negative");
  }
  for (std::size_t t = 0; t < mesh.tet_count(); ++t) {
    const auto tet = static_cast<TetId>(t);
    tet_mass_[tet] = materials_.of(tet).density * std::abs(signed_volume(mesh, tet));
  }
  conserve_mass(tet_mass_, mesh_);
  mesh.add_observer(this);
  marks_.mark_all();
  refresh();
}

MassSpringModel::~MassSpringModel() {
  if (mesh_ != nullptr) {
    mesh_->remove_observer(this);
  }
}

// ---- following edits ------------------------------------------------------------------------

void MassSpringModel::on_tet_added(const TetMesh& mesh, TetId tet) {
  tet_mass_[tet] = materials_.of(tet).density * std::abs(signed_volume(mesh, tet));
  volume_terms_[tet] = volume_term(tet);
}

void MassSpringModel::load_state(StateReader& /*in*/) {
  marks_.mark_all();
  rebuild_adjacency_ = true;
}

void MassSpringModel::rebuild_adjacency() {
  const VertexGraph graph = vertex_graph(*mesh_);
  const std::size_t n = mesh_->vertex_count();
  neighbours_.assign(n, [&](std::size_t v) { return graph.neighbors(static_cast<VertexId>(v)); });
  edges_at_.assign(n, [&](std::size_t v) {
    return std::span<const EdgeId>(graph.edge)
        .subspan(graph.row_start[v], graph.row_start[v + 1] - graph.row_start[v]);
  });
  if (parameters_.volume_stiffness > 0.0) {
    tet_corners_.assign(n, [](std::size_t) { return std::span<const TetCorners>(); });
    for (std::size_t v = 0; v < n; ++v) {
      set_tet_corners(static_cast<VertexId>(v));
    }
  }
}

void MassSpringModel::set_tet_corners(VertexId v) {
  const auto neighbours = neighbours_.row(static_cast<std::size_t>(v));
  std::vector<TetCorners> row;
  for (TetId t : mesh_->vertex_tets(v)) {
    const Tet& tet = mesh_->tet(t);
    TetCorners corners;
    corners.tet = t;
    for (std::size_t k = 0; k < 4; ++k) {
      if (tet[k] == v) {
        corners.own = static_cast<std::uint8_t>(k);
        continue;
      }
      const auto at = std::find(neighbours.begin(), neighbours.end(), tet[k]);
      INCISE_ASSERT(at != neighbours.end(), "a tetrahedron's corner is an edge neighbour");
      corners.slot[k] = static_cast<std::uint32_t>(at - neighbours.begin());
    }
    row.push_back(corners);
  }
  tet_corners_.set_row(static_cast<std::size_t>(v), row);
}

void MassSpringModel::update_adjacency() {
  const TetMesh& mesh = *mesh_;
  neighbours_.add_rows(mesh.vertex_count());
  edges_at_.add_rows(mesh.vertex_count());
  std::vector<EdgeId> edges;
  std::vector<VertexId> neighbours;
  for (VertexId v : marks_.marked()) {
    // The edges at v, in edge order as vertex_graph lists them (so the sums in vertex_force
    // run in the same order as after a rebuild).
    edges.clear();
    for (TetId t : mesh.vertex_tets(v)) {
      for (EdgeId e : mesh.tet_edges(t)) {
        if (mesh.edge(e)[0] == v || mesh.edge(e)[1] == v) {
          edges.push_back(e);
        }
      }
    }
    std::sort(edges.begin(), edges.end());
    edges.erase(std::unique(edges.begin(), edges.end()), edges.end());
    neighbours.clear();
    for (EdgeId e : edges) {
      neighbours.push_back(mesh.edge(e)[0] == v ? mesh.edge(e)[1] : mesh.edge(e)[0]);
    }
    edges_at_.set_row(static_cast<std::size_t>(v), edges);
    neighbours_.set_row(static_cast<std::size_t>(v), neighbours);
  }
  if (parameters_.volume_stiffness > 0.0) {
    tet_corners_.add_rows(mesh.vertex_count());
    for (VertexId v : marks_.marked()) {
      set_tet_corners(v);
    }
    (void)tet_corners_.compact_if_fragmented();
  }
  (void)edges_at_.compact_if_fragmented();
  (void)neighbours_.compact_if_fragmented();
}

void MassSpringModel::refresh() {
  if (marks_.empty() && !rebuild_adjacency_ && adjacency_revision_ == mesh_->revision()) {
    return;
  }
  const TetMesh& mesh = *mesh_;
  if (rebuild_adjacency_ || marks_.empty()) {
    // At construction, after a restore, or after a change no event told of.
    rebuild_adjacency();
    rebuild_adjacency_ = false;
  } else {
    update_adjacency();
  }
  adjacency_revision_ = mesh.revision();
  // Masses of touched vertices, summed afresh so no error accumulates.
  for (VertexId v : marks_.marked()) {
    masses_[v] = vertex_lumped_mass(mesh, tet_mass_, v);
  }
  // Springs at touched vertices (van Gelder's rule, extended to tetrahedra: the stiffness of
  // an edge is the sum of E times rest volume over the tetrahedra around it, over its squared
  // rest length; A. van Gelder, J. Graphics Tools 3(2), 1998). Each tetrahedron brings its
  // own material's E.
  for (VertexId v : marks_.marked()) {
    for (EdgeId e : edges_at_.row(static_cast<std::size_t>(v))) {
      const auto& ends = mesh.edge(e);
      const double length = (mesh.rest_position(ends[0]) - mesh.rest_position(ends[1])).norm();
      double modulus_volume = 0.0;  // Pa m^3
      for (TetId t : mesh.edge_tets(e)) {
        modulus_volume += materials_.of(t).young_modulus * mesh.material_fraction(t) *
                          std::abs(signed_volume(mesh, t));
      }
      Spring& spring = springs_[e];
      spring.rest_length = (1.0 - parameters_.prestrain) * length;
      spring.stiffness = length > 0.0 ? modulus_volume / (length * length) : 0.0;
      const double ma = masses_[ends[0]];
      const double mb = masses_[ends[1]];
      const double reduced = ma + mb > 0.0 ? ma * mb / (ma + mb) : 0.0;
      spring.damping =
          parameters_.spring_damping_ratio * 2.0 * std::sqrt(spring.stiffness * reduced);
    }
  }
  // Volume terms of the tetrahedra at touched vertices (new ones, changed fractions).
  if (marks_.size() == mesh.vertex_count()) {
    for (std::size_t t = 0; t < mesh.tet_count(); ++t) {
      volume_terms_[static_cast<TetId>(t)] = volume_term(static_cast<TetId>(t));
    }
  } else {
    for (VertexId v : marks_.marked()) {
      for (TetId t : mesh.vertex_tets(v)) {
        volume_terms_[t] = volume_term(t);
      }
    }
  }
  update_frequency_rows();
  marks_.clear();
}

double MassSpringModel::frequency_row(VertexId vertex) const {
  // Row `vertex` of the Gershgorin bound on M^-1/2 K M^-1/2 at rest: sum_j k_ij / m_i on the
  // diagonal and k_ij / sqrt(m_i m_j) off it (1/s^2).
  const double mv = masses_[vertex];
  if (mv <= 0.0) {
    return 0.0;
  }
  double row = 0.0;
  const auto edges = edges_at_.row(static_cast<std::size_t>(vertex));
  const auto neighbours = neighbours_.row(static_cast<std::size_t>(vertex));
  for (std::size_t k = 0; k < edges.size(); ++k) {
    const double stiffness = springs_[edges[k]].stiffness;
    const double mw = masses_[neighbours[k]];
    row += stiffness / mv + (mw > 0.0 ? stiffness / std::sqrt(mv * mw) : 0.0);
  }
  // The volume terms' blocks at rest, kappa / V0 g_v g_w^T, bounded by their norms.
  if (parameters_.volume_stiffness > 0.0) {
    for (TetId t : mesh_->vertex_tets(vertex)) {
      const auto [kappa, rest_volume] = volume_terms_[t];
      if (rest_volume <= 0.0) {
        continue;
      }
      const Tet& tet = mesh_->tet(t);
      const auto g = volume_gradient(rest_corners(*mesh_, t));
      std::size_t own = 0;
      while (tet[own] != vertex) {
        ++own;
      }
      for (std::size_t k = 0; k < 4; ++k) {
        const double mw = masses_[tet[k]];
        if (mw > 0.0) {
          row += kappa / rest_volume * g[own].norm() * g[k].norm() / std::sqrt(mv * mw);
        }
      }
    }
  }
  return row;
}

void MassSpringModel::update_frequency_rows() {
  // A vertex's row reads its springs and its neighbours' masses: the marked vertices' rows
  // and their neighbours' change.
  const std::size_t n = mesh_->vertex_count();
  if (frequency_.empty() || marks_.size() == n) {
    frequency_.fill(n, [this](VertexId v) { return frequency_row(v); });
    return;
  }
  frequency_.grow(n);
  for (VertexId v : marks_.marked()) {
    frequency_.set(v, frequency_row(v));
    for (VertexId w : neighbours_.row(static_cast<std::size_t>(v))) {
      if (!marks_.is_marked(w)) {
        frequency_.set(w, frequency_row(w));
      }
    }
  }
  frequency_.settle();
}

// ---- forces --------------------------------------------------------------------------------

Vec3 MassSpringModel::spring_force(const Spring& spring, const Vec3& xa, const Vec3& va,
                                   const Vec3& xb, const Vec3& vb) const {
  const Vec3 d = xb - xa;
  const double length = d.norm();
  if (length == 0.0) {
    return Vec3::Zero();  // no direction: coincident ends exert nothing
  }
  const Vec3 u = d / length;
  return (spring.stiffness * (length - spring.rest_length) + spring.damping * (vb - va).dot(u)) * u;
}

std::pair<double, double> MassSpringModel::volume_term(TetId tet) const {
  const double shrink = 1.0 - parameters_.prestrain;
  const double rest_volume = shrink * shrink * shrink * std::abs(signed_volume(*mesh_, tet));
  double kappa = parameters_.volume_stiffness * materials_.of(tet).young_modulus *
                 mesh_->material_fraction(tet);
  // The term's stiffness, kappa |g|^2 / V0, grows as 1 / height for a sliver (a mesher's, or
  // a cut's child) while its mass shrinks with its volume: an explicit step would have to
  // shrink without bound. It is held to 10 times that of the regular tetrahedron of the same
  // root-mean-square edge length L (kappa sqrt(2) L / 8), which leaves well-shaped elements
  // as they are and lets a sliver give way.
  const auto x = rest_corners(*mesh_, tet);
  const auto g = volume_gradient(x);
  double largest = 0.0;
  for (const Vec3& gk : g) {
    largest = std::max(largest, gk.squaredNorm());
  }
  double squared_edges = 0.0;
  for (const auto& edge : tet_local::kEdges) {
    squared_edges +=
        (x[static_cast<std::size_t>(edge[1])] - x[static_cast<std::size_t>(edge[0])]).squaredNorm();
  }
  const double rms_edge = std::sqrt(squared_edges / 6.0);  // m
  constexpr double kHeadroom = 10.0;
  const double bound = kHeadroom * std::sqrt(2.0) / 8.0 * rms_edge * rest_volume;  // m^4
  if (largest > bound && largest > 0.0) {
    kappa *= bound / largest;
  }
  return {kappa, rest_volume};
}

std::array<Vec3, 4> MassSpringModel::volume_forces(TetId tet, const std::array<Vec3, 4>& x) const {
  const auto [kappa, rest_volume] = volume_terms_[tet];
  if (rest_volume <= 0.0) {
    return {Vec3::Zero(), Vec3::Zero(), Vec3::Zero(), Vec3::Zero()};
  }
  std::array<Vec3, 4> g = volume_gradient(x);
  const double volume = signed_volume(x[0], x[1], x[2], x[3]);
  const double pressure = -kappa * (volume - rest_volume) / rest_volume;  // Pa
  for (Vec3& gk : g) {
    gk *= pressure;
  }
  return g;
}

void MassSpringModel::add_forces(std::span<const Vec3> x, std::span<const Vec3> v,
                                 std::span<Vec3> f) const {
  const TetMesh& mesh = *mesh_;
  for (std::size_t e = 0; e < mesh.edge_count(); ++e) {
    const auto& [a, b] = mesh.edge(static_cast<EdgeId>(e));
    const Vec3 force = spring_force(springs_[static_cast<EdgeId>(e)], x[a], v[a], x[b], v[b]);
    f[a] += force;
    f[b] -= force;
  }
  if (parameters_.volume_stiffness > 0.0) {
    for (std::size_t t = 0; t < mesh.tet_count(); ++t) {
      const Tet& tet = mesh.tet(static_cast<TetId>(t));
      const auto forces =
          volume_forces(static_cast<TetId>(t), {x[tet[0]], x[tet[1]], x[tet[2]], x[tet[3]]});
      for (std::size_t k = 0; k < 4; ++k) {
        f[tet[k]] += forces[k];
      }
    }
  }
}

Vec3 MassSpringModel::vertex_force(VertexId vertex, const Vec3& x, const Vec3& v,
                                   const NeighborState& neighbor) const {
  Vec3 force = Vec3::Zero();
  const auto edges = edges_at_.row(static_cast<std::size_t>(vertex));
  const auto neighbours = neighbours_.row(static_cast<std::size_t>(vertex));
  // Each neighbour's state is asked for once (the volume terms read them again).
  constexpr std::size_t kKept = 64;
  std::array<Vec3, kKept> kept;
  for (std::size_t k = 0; k < edges.size(); ++k) {
    Vec3 xb;
    Vec3 vb;
    neighbor(neighbours[k], xb, vb);
    force += spring_force(springs_[edges[k]], x, v, xb, vb);
    if (k < kKept) {
      kept[k] = xb;
    }
  }
  if (parameters_.volume_stiffness > 0.0) {
    // Each tetrahedron's other corners are edge neighbours, whose states were read above. Only
    // this corner's share: d V / d x_own is a third of the opposite face's area along its
    // inward normal.
    for (const TetCorners& at : tet_corners_.row(static_cast<std::size_t>(vertex))) {
      const auto [kappa, rest_volume] = volume_terms_[at.tet];
      if (rest_volume <= 0.0) {
        continue;
      }
      const Tet& tet = mesh_->tet(at.tet);
      std::array<Vec3, 4> corners;
      for (std::size_t k = 0; k < 4; ++k) {
        if (k == at.own) {
          corners[k] = x;
        } else if (at.slot[k] < kKept) {
          corners[k] = kept[at.slot[k]];
        } else {
          Vec3 vw;
          neighbor(tet[k], corners[k], vw);
        }
      }
      const auto& face = tet_local::kFaces[at.own];
      const Vec3& f0 = corners[static_cast<std::size_t>(face[0])];
      const Vec3 outward = (corners[static_cast<std::size_t>(face[1])] - f0)
                               .cross(corners[static_cast<std::size_t>(face[2])] - f0);
      // The opposite face (tet_local::kFaces) faces away from this corner in a tetrahedron
      // the right way out: the volume is a sixth of the corner's height times twice its area.
      const double volume = -(x - f0).dot(outward) / 6.0;
      force += kappa * (volume - rest_volume) / rest_volume / 6.0 * outward;
    }
  }
  return force;
}

std::span<const VertexId> MassSpringModel::neighbors(VertexId vertex) const {
  return neighbours_.row(static_cast<std::size_t>(vertex));
}

void MassSpringModel::prepare_linearization(std::span<const Vec3> x, std::span<const Vec3>) {
  const TetMesh& mesh = *mesh_;
  stiffness_blocks_.resize(mesh.edge_count());
  damping_blocks_.resize(mesh.edge_count());
  for (std::size_t e = 0; e < mesh.edge_count(); ++e) {
    const auto& [a, b] = mesh.edge(static_cast<EdgeId>(e));
    const Spring& spring = springs_[static_cast<EdgeId>(e)];
    const Vec3 d = x[b] - x[a];
    const double length = d.norm();
    if (length == 0.0) {
      stiffness_blocks_[e].setZero();
      damping_blocks_[e].setZero();
      continue;
    }
    const Vec3 u = d / length;
    const Mat3 axial = u * u.transpose();
    // The transverse term (1 - L/l) is clamped at zero for compressed springs, which keeps
    // the matrix positive semi-definite (Choi and Ko, SIGGRAPH 2002).
    const double transverse = std::max(0.0, 1.0 - spring.rest_length / length);
    stiffness_blocks_[e] = spring.stiffness * (axial + transverse * (Mat3::Identity() - axial));
    damping_blocks_[e] = spring.damping * axial;
  }
  volume_coefficients_.assign(parameters_.volume_stiffness > 0.0 ? mesh.tet_count() : 0, 0.0);
  volume_gradients_.resize(volume_coefficients_.size());
  for (std::size_t t = 0; t < volume_coefficients_.size(); ++t) {
    const Tet& tet = mesh.tet(static_cast<TetId>(t));
    const auto [kappa, rest_volume] = volume_terms_[static_cast<TetId>(t)];
    volume_coefficients_[t] = rest_volume > 0.0 ? kappa / rest_volume : 0.0;
    volume_gradients_[t] = volume_gradient({x[tet[0]], x[tet[1]], x[tet[2]], x[tet[3]]});
  }
}

void MassSpringModel::add_linearized_product(double a, double b, std::span<const Vec3> p,
                                             std::span<Vec3> y) const {
  const TetMesh& mesh = *mesh_;
  for (std::size_t e = 0; e < mesh.edge_count(); ++e) {
    const auto& [i, j] = mesh.edge(static_cast<EdgeId>(e));
    const Vec3 difference = p[i] - p[j];
    const Vec3 product =
        a * (stiffness_blocks_[e] * difference) + b * (damping_blocks_[e] * difference);
    y[i] += product;
    y[j] -= product;
  }
  for (std::size_t t = 0; t < volume_coefficients_.size(); ++t) {
    const Tet& tet = mesh.tet(static_cast<TetId>(t));
    const auto& g = volume_gradients_[t];
    double along = 0.0;
    for (std::size_t k = 0; k < 4; ++k) {
      along += g[k].dot(p[tet[k]]);
    }
    const double scale = a * volume_coefficients_[t] * along;
    for (std::size_t k = 0; k < 4; ++k) {
      y[tet[k]] += scale * g[k];
    }
  }
}

void MassSpringModel::add_linearized_diagonal(double a, double b, std::span<Mat3> diagonal) const {
  const TetMesh& mesh = *mesh_;
  for (std::size_t e = 0; e < mesh.edge_count(); ++e) {
    const auto& [i, j] = mesh.edge(static_cast<EdgeId>(e));
    const Mat3 block = a * stiffness_blocks_[e] + b * damping_blocks_[e];
    diagonal[i] += block;
    diagonal[j] += block;
  }
  for (std::size_t t = 0; t < volume_coefficients_.size(); ++t) {
    const Tet& tet = mesh.tet(static_cast<TetId>(t));
    for (std::size_t k = 0; k < 4; ++k) {
      const Vec3& g = volume_gradients_[t][k];
      diagonal[tet[k]] += a * volume_coefficients_[t] * (g * g.transpose());
    }
  }
}

double MassSpringModel::elastic_energy(std::span<const Vec3> x) const {
  const TetMesh& mesh = *mesh_;
  double energy = 0.0;
  for (std::size_t e = 0; e < mesh.edge_count(); ++e) {
    const auto& [a, b] = mesh.edge(static_cast<EdgeId>(e));
    const Spring& spring = springs_[static_cast<EdgeId>(e)];
    const double stretch = (x[b] - x[a]).norm() - spring.rest_length;
    energy += 0.5 * spring.stiffness * stretch * stretch;
  }
  if (parameters_.volume_stiffness > 0.0) {
    for (std::size_t t = 0; t < mesh.tet_count(); ++t) {
      const Tet& tet = mesh.tet(static_cast<TetId>(t));
      const auto [kappa, rest_volume] = volume_terms_[static_cast<TetId>(t)];
      if (rest_volume > 0.0) {
        const double strain =
            (signed_volume(x[tet[0]], x[tet[1]], x[tet[2]], x[tet[3]]) - rest_volume) / rest_volume;
        energy += 0.5 * kappa * rest_volume * strain * strain;
      }
    }
  }
  return energy;
}

double MassSpringModel::max_vertex_frequency() const {
  return std::sqrt(frequency_.largest());  // kept up to date by refresh(), row by row
}

double MassSpringModel::total_mass() const {
  double total = 0.0;
  for (std::size_t t = 0; t < tet_mass_.size(); ++t) {
    total += tet_mass_[static_cast<TetId>(t)] * mesh_->material_fraction(static_cast<TetId>(t));
  }
  return total;
}

}  // namespace incise
