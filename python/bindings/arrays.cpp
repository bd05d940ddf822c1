#include "arrays.hpp"

#include <pybind11/stl/filesystem.h>

#include <cmath>
#include <limits>

#include "incise/core/error.hpp"

namespace incise::python {
namespace {

/// The array as numpy sees it, or an InputError saying what it is instead.
py::array as_array(const py::handle& value, const std::string& what) {
  try {
    return py::array::ensure(value);
  } catch (const py::error_already_set&) {
  }
  throw InputError(what + ": not an array (" + std::string(py::str(value.get_type())) + ")");
}

std::string shape_of(const py::array& array) {
  std::string text = "(";
  for (py::ssize_t axis = 0; axis < array.ndim(); ++axis) {
    text += (axis > 0 ? ", " : "") + std::to_string(array.shape(axis));
  }
  return text + (array.ndim() == 1 ? ",)" : ")");
}

void require_shape(const py::array& array, py::ssize_t columns, const std::string& what) {
  if (array.ndim() != 2 || array.shape(1) != columns) {
    throw InputError(what + ": an (n, " + std::to_string(columns) + ") array is needed, not " +
                     shape_of(array));
  }
}

/// Whole numbers as int64: integer arrays as they are; floats only when whole.
py::array_t<std::int64_t> whole_numbers(const py::array& array, const std::string& what) {
  const char kind = array.dtype().kind();
  if (kind == 'i' || kind == 'u' || kind == 'b') {
    return py::array_t<std::int64_t, py::array::c_style | py::array::forcecast>::ensure(array);
  }
  if (kind == 'f') {
    const auto floats =
        py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(array);
    const double* data = floats.data();
    for (py::ssize_t i = 0; i < floats.size(); ++i) {
      if (!std::isfinite(data[i]) || data[i] != std::floor(data[i]) || std::abs(data[i]) > 2e9) {
        throw InputError(what + ": entry " + std::to_string(i) + " (" + std::to_string(data[i]) +
                         ") is not a whole number");
      }
    }
    return py::array_t<std::int64_t, py::array::c_style | py::array::forcecast>::ensure(array);
  }
  throw InputError(what + ": integers are needed, not dtype " +
                   std::string(py::str(array.dtype())));
}

}  // namespace

py::array points_view(std::span<const Vec3> points, py::handle owner) {
  static_assert(sizeof(Vec3) == 3 * sizeof(double));
  py::array array(
      py::dtype::of<double>(), {static_cast<py::ssize_t>(points.size()), py::ssize_t{3}},
      {static_cast<py::ssize_t>(sizeof(Vec3)), static_cast<py::ssize_t>(sizeof(double))},
      points.empty() ? nullptr : points.front().data(), owner);
  array.attr("flags").attr("writeable") = false;
  return array;
}

std::vector<Vec3> points_from(const py::handle& value, const std::string& what) {
  const py::array array = as_array(value, what);
  require_shape(array, 3, what);
  const char kind = array.dtype().kind();
  if (kind != 'f' && kind != 'i' && kind != 'u') {
    throw InputError(what + ": numbers are needed, not dtype " +
                     std::string(py::str(array.dtype())));
  }
  const auto doubles =
      py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(array);
  std::vector<Vec3> points(static_cast<std::size_t>(doubles.shape(0)));
  const double* data = doubles.data();
  for (std::size_t i = 0; i < points.size(); ++i) {
    points[i] = Vec3(data[3 * i], data[3 * i + 1], data[3 * i + 2]);
    if (!points[i].allFinite()) {
      throw InputError(what + ": row " + std::to_string(i) + " is not finite (NaN or infinite)");
    }
  }
  return points;
}

Vec3 point_from(const py::handle& value, const std::string& what) {
  const py::array array = as_array(value, what);
  if (array.size() != 3 || (array.ndim() != 1 && array.ndim() != 2)) {
    throw InputError(what + ": 3 coordinates are needed, not shape " + shape_of(array));
  }
  const auto doubles =
      py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(array);
  const Vec3 point(doubles.data()[0], doubles.data()[1], doubles.data()[2]);
  if (!point.allFinite()) {
    throw InputError(what + ": a coordinate is not finite (NaN or infinite)");
  }
  return point;
}

template <std::size_t k>
std::vector<std::array<std::int32_t, k>> ids_from(const py::handle& value, std::size_t id_count,
                                                  const std::string& what) {
  const py::array array = as_array(value, what);
  require_shape(array, static_cast<py::ssize_t>(k), what);
  const auto ids = whole_numbers(array, what);
  std::vector<std::array<std::int32_t, k>> rows(static_cast<std::size_t>(ids.shape(0)));
  const std::int64_t* data = ids.data();
  for (std::size_t row = 0; row < rows.size(); ++row) {
    for (std::size_t corner = 0; corner < k; ++corner) {
      const std::int64_t id = data[row * k + corner];
      if (id < 0 || static_cast<std::uint64_t>(id) >= id_count) {
        throw InputError(what + ": row " + std::to_string(row) + " refers to vertex " +
                         std::to_string(id) + ", outside 0.." +
                         std::to_string(static_cast<std::int64_t>(id_count) - 1));
      }
      rows[row][corner] = static_cast<std::int32_t>(id);
    }
  }
  return rows;
}

template std::vector<std::array<std::int32_t, 4>> ids_from<4>(const py::handle&, std::size_t,
                                                              const std::string&);
template std::vector<std::array<std::int32_t, 3>> ids_from<3>(const py::handle&, std::size_t,
                                                              const std::string&);

std::vector<int> labels_from(const py::handle& value, std::size_t count, const std::string& what) {
  const py::array array = as_array(value, what);
  if (array.ndim() != 1 || static_cast<std::size_t>(array.shape(0)) != count) {
    throw InputError(what + ": one label per tetrahedron is needed (" + std::to_string(count) +
                     "), not shape " + shape_of(array));
  }
  const auto labels = whole_numbers(array, what);
  std::vector<int> out(count);
  for (std::size_t i = 0; i < count; ++i) {
    const std::int64_t label = labels.data()[i];
    if (label < std::numeric_limits<int>::min() || label > std::numeric_limits<int>::max()) {
      throw InputError(what + ": entry " + std::to_string(i) + " is out of range");
    }
    out[i] = static_cast<int>(label);
  }
  return out;
}

SurfaceMesh surface_from(const py::object& surface, const std::string& what) {
  if (py::isinstance<py::str>(surface) || py::hasattr(surface, "__fspath__")) {
    const auto path = surface.cast<std::filesystem::path>();
    py::gil_scoped_release release;
    return read_surface(path);
  }
  if (!py::isinstance<py::tuple>(surface) || py::len(surface) != 2) {
    throw InputError(what + ": a file's path or (points, triangles) arrays are needed");
  }
  const auto pair = surface.cast<py::tuple>();
  SurfaceMesh mesh;
  mesh.points = points_from(pair[0], what + " points");
  mesh.triangles = ids_from<3>(pair[1], mesh.points.size(), what + " triangles");
  if (mesh.triangles.empty()) {
    throw InputError(what + " triangles: a surface needs at least one triangle");
  }
  return mesh;
}

}  // namespace incise::python
