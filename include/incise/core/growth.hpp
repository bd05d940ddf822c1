#pragma once
// Capacity for the edits to come. A body's per-element arrays are built at exactly their size,
// so the first cut would reallocate every one of them at once, copying the whole body into
// fresh pages: 180 ms in the first cutting frame of the 384k-tet box (BENCHMARKS.md). A quarter
// more capacity puts that off past what cuts usually add (3 % of the tetrahedra there), and a
// cut then costs what it cuts. Capacity never touched costs address space only.

#include <cstddef>
#include <vector>

namespace incise {

/// The capacity kept for `size` elements: a quarter more.
[[nodiscard]] constexpr std::size_t capacity_for_edits(std::size_t size) {
  return size + size / 4 + 16;
}

/// Room for a quarter more elements than `values` holds.
template <typename T>
void reserve_for_edits(std::vector<T>& values) {
  values.reserve(capacity_for_edits(values.size()));
}

/// values.resize(size, fill...), keeping a quarter more capacity when it must grow past it.
template <typename T, typename... Fill>
void resize_for_edits(std::vector<T>& values, std::size_t size, const Fill&... fill) {
  if (size > values.capacity()) {
    values.reserve(capacity_for_edits(size));
  }
  values.resize(size, fill...);
}

}  // namespace incise
