#pragma once
// numpy arrays in and out. Out: read-only arrays that view memory kept alive by their base
// object (never copied, never dangling). In: arrays checked for shape, type, finiteness and
// id range before anything is built from them; a bad one is an InputError naming it and the
// first bad row.

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <memory>
#include <span>
#include <string>
#include <vector>

#include "incise/core/types.hpp"
#include "incise/io/mesh_io.hpp"

namespace incise::python {

namespace py = pybind11;

/// A read-only (n, 3) float64 view of `points`, whose memory `owner` keeps alive.
[[nodiscard]] py::array points_view(std::span<const Vec3> points, py::handle owner);
/// A read-only (m, k) int32 view of `rows` (tetrahedra, triangles), kept alive by `owner`.
template <std::size_t k>
[[nodiscard]] py::array ids_view(std::span<const std::array<std::int32_t, k>> rows,
                                 py::handle owner) {
  py::array array(py::dtype::of<std::int32_t>(),
                  {static_cast<py::ssize_t>(rows.size()), static_cast<py::ssize_t>(k)},
                  {static_cast<py::ssize_t>(k * sizeof(std::int32_t)),
                   static_cast<py::ssize_t>(sizeof(std::int32_t))},
                  rows.empty() ? nullptr : rows.front().data(), owner);
  array.attr("flags").attr("writeable") = false;
  return array;
}
/// A read-only 1-D view of `values`, kept alive by `owner`.
template <typename T>
[[nodiscard]] py::array values_view(std::span<const T> values, py::handle owner) {
  py::array array(py::dtype::of<T>(), {static_cast<py::ssize_t>(values.size())},
                  {static_cast<py::ssize_t>(sizeof(T))}, values.data(), owner);
  array.attr("flags").attr("writeable") = false;
  return array;
}
/// A Python object owning `data`: the base of arrays that view it.
template <typename T>
[[nodiscard]] py::object keeper(std::shared_ptr<T> data) {
  auto* held = new std::shared_ptr<T>(std::move(data));
  return py::capsule(held, [](void* pointer) { delete static_cast<std::shared_ptr<T>*>(pointer); });
}

/// (n, 3) finite floats -> points (m). `what` names the array in errors ("vertices").
[[nodiscard]] std::vector<Vec3> points_from(const py::handle& array, const std::string& what);
/// One point: a sequence or array of 3 finite floats.
[[nodiscard]] Vec3 point_from(const py::handle& value, const std::string& what);
/// (m, k) integers, each in [0, id_count) -> rows of ids.
template <std::size_t k>
[[nodiscard]] std::vector<std::array<std::int32_t, k>> ids_from(const py::handle& array,
                                                                std::size_t id_count,
                                                                const std::string& what);
/// A triangle surface: a file's path (read as incise mesh reads it) or (points, triangles)
/// arrays, checked; `what` names it in errors ("surface", "visual").
[[nodiscard]] SurfaceMesh surface_from(const py::object& surface, const std::string& what);
/// m integers -> labels.
[[nodiscard]] std::vector<int> labels_from(const py::handle& array, std::size_t count,
                                           const std::string& what);

}  // namespace incise::python
