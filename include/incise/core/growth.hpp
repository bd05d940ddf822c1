#pragma once
// Capacity for the edits to come. A body's per-element arrays are built at exactly their size,
// so the first cut would reallocate every one of them at once, copying the whole body into
// fresh pages: 180 ms in the first cutting frame of the 384k-tet box (BENCHMARKS.md). Twice
// the size puts that off until the cuts have doubled the body, and a cut then costs what it
// cuts. A quarter more was not enough: a long session that cut the 50k body through twice
// copied the per-vertex arrays at every quarter it added, four times (BENCHMARKS.md).
// Capacity never touched costs address space only.

#include <cstddef>
#include <vector>

namespace incise {

/// The capacity kept for `size` elements: twice as many.
[[nodiscard]] constexpr std::size_t capacity_for_edits(std::size_t size) {
  return 2 * size + 16;
}

/// Room for as many elements again as `values` holds.
template <typename T>
void reserve_for_edits(std::vector<T>& values) {
  values.reserve(capacity_for_edits(values.size()));
}

/// The capacity kept for `size` elements of storage that edited rows move through (a block
/// matrix's values, packed rows): three times as many. Each row an edit moves leaves its old
/// place behind until the rows are packed, at a quarter of the storage, so the storage holds
/// up to 4/3 of the live values: three times the first storage holds twice the values, and
/// the storage is copied no sooner than the per-element arrays. A quarter more capacity was
/// always reached before the rows were ever packed, and every block was copied into fresh
/// pages within a cutting frame (a frame of 20-60x the usual update on the 50k body).
[[nodiscard]] constexpr std::size_t capacity_for_moved_rows(std::size_t size) {
  return 3 * size + 16;
}

/// The room kept for `size` keys of a hash table (the mesh's edge index): a quarter more. Its
/// slots are all touched when it is built, so room there is memory, not address space only:
/// doubling it as the arrays are cost the 403k-tet box 16 MB more at build.
[[nodiscard]] constexpr std::size_t capacity_for_hashed_keys(std::size_t size) {
  return size + size / 4 + 16;
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

/// values.resize(size, fill...), keeping capacity_for_edits(size) when it must grow past its
/// capacity.
template <typename T, typename... Fill>
void resize_for_edits(std::vector<T>& values, std::size_t size, const Fill&... fill) {
  resize_keeping(values, size, capacity_for_edits, fill...);
}

}  // namespace incise
