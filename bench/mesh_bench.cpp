// Mesh core throughput: bulk adjacency build, local edits, validation and reading.
// Run: build/release/bench/mesh_bench   (results in BENCHMARKS.md)

#include <benchmark/benchmark.h>

#include <algorithm>
#include <filesystem>
#include <random>

#include "incise/io/mesh_io.hpp"
#include "incise/mesh/attributes.hpp"
#include "incise/mesh/boundary.hpp"
#include "incise/mesh/generators.hpp"
#include "incise/mesh/operations.hpp"
#include "incise/mesh/validate.hpp"

namespace {

using namespace incise;

TetMesh cube(int n) {
  BoxGridOptions options;
  options.cells = {n, n, n};
  options.size = Vec3(0.1, 0.1, 0.1);
  return make_box_grid(options);
}

/// n = 10, 20, 46: 6,000, 48,000 and 584,016 tetrahedra.
void BM_BuildAdjacency(benchmark::State& state) {
  const TetMesh source = cube(static_cast<int>(state.range(0)));
  const std::vector<Vec3> positions(source.rest_positions().begin(), source.rest_positions().end());
  const std::vector<Tet> tets(source.tets().begin(), source.tets().end());
  for (auto _ : state) {
    TetMesh mesh(positions, tets);
    benchmark::DoNotOptimize(mesh.edge_count());
  }
  state.counters["tets"] = static_cast<double>(tets.size());
  state.counters["tets/s"] = benchmark::Counter(static_cast<double>(tets.size()),
                                                benchmark::Counter::kIsIterationInvariantRate);
}
BENCHMARK(BM_BuildAdjacency)->Arg(10)->Arg(20)->Arg(46)->Unit(benchmark::kMillisecond);

/// Splitting one edge (all tetrahedra around it) with three attribute containers attached:
/// the local edit a cutter performs. Its cost must not grow with the mesh.
void BM_SplitEdge(benchmark::State& state) {
  TetMesh mesh = cube(static_cast<int>(state.range(0)));
  VertexData<Vec3> velocity(mesh, Vec3::Zero());
  TetData<double> rest_volume(mesh, 0.0);
  EdgeData<double> rest_length(mesh, 0.0, EdgeRule::kScale);
  std::mt19937 rng(7);
  std::size_t splits = 0;
  for (auto _ : state) {
    benchmark::DoNotOptimize(split_edge(mesh, static_cast<EdgeId>(rng() % mesh.edge_count()), 0.5));
    ++splits;
  }
  state.counters["tets_at_end"] = static_cast<double>(mesh.tet_count());
  state.SetItemsProcessed(static_cast<std::int64_t>(splits));
}
BENCHMARK(BM_SplitEdge)->Arg(10)->Arg(20)->Arg(46)->Unit(benchmark::kMicrosecond);

void BM_Validate(benchmark::State& state) {
  const TetMesh mesh = cube(static_cast<int>(state.range(0)));
  for (auto _ : state) {
    benchmark::DoNotOptimize(validate(mesh).ok());
  }
  state.counters["tets"] = static_cast<double>(mesh.tet_count());
}
BENCHMARK(BM_Validate)->Arg(10)->Arg(20)->Arg(46)->Unit(benchmark::kMillisecond);

void BM_BoundaryAndComponents(benchmark::State& state) {
  const TetMesh mesh = cube(static_cast<int>(state.range(0)));
  for (auto _ : state) {
    int count = 0;
    benchmark::DoNotOptimize(tet_components(mesh, &count));
    benchmark::DoNotOptimize(check_boundary(mesh).watertight());
  }
}
BENCHMARK(BM_BoundaryAndComponents)->Arg(20)->Arg(46)->Unit(benchmark::kMillisecond);

/// Writing and reading the 584k-tet cube as .vtu (binary appended) and .msh (ASCII).
void BM_WriteRead(benchmark::State& state, const std::string& extension) {
  const TetMesh mesh = cube(46);
  const auto path = std::filesystem::temp_directory_path() / ("incise-bench" + extension);
  for (auto _ : state) {
    write_tet_mesh(path, mesh);
    benchmark::DoNotOptimize(read_tet_mesh(path).mesh.tet_count());
  }
  std::filesystem::remove(path);
}
BENCHMARK_CAPTURE(BM_WriteRead, vtu, std::string(".vtu"))->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_WriteRead, msh, std::string(".msh"))->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
