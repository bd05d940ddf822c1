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

/// The capacity kept for `size` elements of storage that edited rows move through (a block
/// matrix's values): twice as many. Each row an edit moves leaves its old place behind until
/// the rows are packed, at a quarter of the storage, so a quarter more capacity was always
/// reached first, and every block was copied into fresh pages within a cutting frame (a hitch
/// of 20-60x the frame's usual update on the 50k body, BENCHMARKS.md). Twice the storage holds
/// half again as many blocks, packed, before a copy.
[[nodiscard]] constexpr std::size_t capacity_for_moved_rows(std::size_t size) {
  return 2 * size + 16;
}

/// values.resize(size, fill...), keeping capacity(size) when it must grow past its capacity.
template <typename T, typename... Fill>
void resize_keeping(std::vector<T>& values, std::size_t size, std::size_t (*capacity)(std::size_t),
                    const Fill&... fill) {
  if (size > values.capacity()) {
    values.reserve(capacity(size));
  }
  values.resize(size, fill...);
}

/// values.resize(size, fill...), keeping a quarter more capacity when it must grow past it.
template <typename T, typename... Fill>
void resize_for_edits(std::vector<T>& values, std::size_t size, const Fill&... fill) {
  resize_keeping(values, size, capacity_for_edits, fill...);
}

}  // namespace incise
