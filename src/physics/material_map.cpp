#include "incise/physics/material_map.hpp"

#include <string>

#include "incise/core/error.hpp"

namespace incise {

MaterialMap::MaterialMap(TetMesh& mesh, const MaterialAssignment& assignment)
    : table_(assignment.table), ids_(mesh, 0, TetRule::kCopy) {
  if (table_.empty()) {
    throw InputError("a body needs at least one material");
  }
  for (std::size_t m = 0; m < table_.size(); ++m) {
    try {
      table_[m].check();
    } catch (const InputError& error) {
      throw InputError("material " + std::to_string(m) + ": " + error.what());
    }
  }
  if (assignment.ids.empty()) {
    return;
  }
  if (assignment.ids.size() != mesh.tet_count()) {
    throw InputError(std::to_string(assignment.ids.size()) + " material ids for " +
                     std::to_string(mesh.tet_count()) + " tetrahedra");
  }
  for (std::size_t t = 0; t < assignment.ids.size(); ++t) {
    const int id = assignment.ids[t];
    if (id < 0 || static_cast<std::size_t>(id) >= table_.size()) {
      throw InputError("tetrahedron " + std::to_string(t) + " names material " +
                       std::to_string(id) + ", but the table holds " +
                       std::to_string(table_.size()));
    }
    ids_[static_cast<TetId>(t)] = id;
  }
}

}  // namespace incise
