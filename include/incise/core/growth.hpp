#pragma once
// Capacity for the edits to come. A body's per-element arrays are built at exactly their size,
// so the first cut would reallocate every one of them at once, copying the whole body into
// fresh pages: 180 ms in the first cutting frame of the 384k-tet box (BENCHMARKS.md). An eighth
// more capacity puts that off past what cuts usually add (3 % of the tetrahedra there), and a
// cut then costs what it cuts.

#include <cstddef>
#include <vector>

namespace incise {

/// Room for an eighth more elements than `values` holds.
template <typename T>
void reserve_for_edits(std::vector<T>& values) {
  values.reserve(values.size() + values.size() / 8 + 16);
}

/// values.resize(size), reserving an eighth more when it must grow past its capacity.
template <typename T>
void resize_for_edits(std::vector<T>& values, std::size_t size) {
  if (size > values.capacity()) {
    values.reserve(size + size / 8 + 16);
  }
  values.resize(size);
}

/// values.resize(size, fill), the same way.
template <typename T>
void resize_for_edits(std::vector<T>& values, std::size_t size, const T& fill) {
  if (size > values.capacity()) {
    values.reserve(size + size / 8 + 16);
  }
  values.resize(size, fill);
}

}  // namespace incise
