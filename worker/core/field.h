// SPDX-License-Identifier: Apache-2.0
// Host storage of one padded per-cell field (see grid.h).
#pragma once

#include <sys/mman.h>

#include <algorithm>
#include <cstddef>
#include <cstdlib>
#include <cstring>
#include <new>
#include <utility>
#include <vector>

#include "core/grid.h"

namespace erg {

// Copies `bytes` from src to dst, writing only the pages whose contents
// differ. A field's storage comes from the operating system as zero pages
// that take no memory until written (Field::allocate); a layer that stays
// zero everywhere (no vegetation, no obstacles, no bedrock resistance: the
// defaults) is then never written, by uploads or by ghost exchanges, and
// costs nothing (docs/design.md, "Memory"). The values are those of a
// plain copy.
inline void copy_changed(void* dst, const void* src, std::size_t bytes) {
  constexpr std::size_t kChunk = 4096;
  auto* d = static_cast<char*>(dst);
  const auto* s = static_cast<const char*>(src);
  for (std::size_t i = 0; i < bytes; i += kChunk) {
    const std::size_t n = bytes - i < kChunk ? bytes - i : kChunk;
    if (std::memcmp(d + i, s + i, n) != 0) std::memcpy(d + i, s + i, n);
  }
}

template <class T>
class Field {
 public:
  using value_type = T;
  Field() = default;
  explicit Field(const TileGeom& g, T fill = T{}) { reset(g, fill); }
  Field(const Field& o) { *this = o; }
  Field& operator=(const Field& o) {
    if (this != &o) {
      allocate(o.n_);
      geom_ = o.geom_;
      if (n_) copy_changed(data_, o.data_, n_ * sizeof(T));
    }
    return *this;
  }
  Field(Field&& o) noexcept { swap(o); }
  Field& operator=(Field&& o) noexcept {
    swap(o);
    return *this;
  }
  ~Field() { release(); }

  void reset(const TileGeom& g, T fill = T{}) {
    geom_ = g;
    // Fresh pages from the system already hold zeros: filling them with
    // zeros would only make them resident.
    const T zero{};
    if (!allocate(g.size()) || std::memcmp(&fill, &zero, sizeof(T)) != 0)
      std::fill(data_, data_ + n_, fill);
  }
  // Storage shared with other fields (a backend's work buffers, whose
  // lifetimes do not overlap): g.size() values at `p`, which the caller
  // keeps alive and which this field does not free. Nothing is filled.
  void view(T* p, const TileGeom& g) {
    release();
    data_ = p;
    n_ = g.size();
    geom_ = g;
    owned_ = false;
  }
  void swap(Field& o) noexcept {
    std::swap(data_, o.data_);
    std::swap(n_, o.n_);
    std::swap(geom_, o.geom_);
    std::swap(owned_, o.owned_);
    std::swap(mapped_, o.mapped_);
  }

  T* data() { return data_; }
  const T* data() const { return data_; }
  std::size_t size() const { return n_; }
  const TileGeom& geom() const { return geom_; }
  T& operator()(int x, int y) { return data_[geom_.at(x, y)]; }
  const T& operator()(int x, int y) const { return data_[geom_.at(x, y)]; }
  T* row(int y) { return data_ + geom_.at(0, y); }
  const T* row(int y) const { return data_ + geom_.at(0, y); }

 private:
  // Storage of at least kMapBytes is mapped from the system directly: it is
  // page-aligned and zero, and a page takes memory only once written (see
  // copy_changed). Returns whether the storage is fresh (zero).
  static constexpr std::size_t kMapBytes = std::size_t{1} << 20;
  bool allocate(std::size_t n) {
    if (n == n_ && data_ && owned_) return false;
    release();
    owned_ = true;
    n_ = n;
    if (n == 0) return false;
    const std::size_t bytes = (n * sizeof(T) + 63) / 64 * 64;
    if (bytes >= kMapBytes) {
      void* p = mmap(nullptr, bytes, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
      if (p == MAP_FAILED) throw std::bad_alloc();
      data_ = static_cast<T*>(p);
      mapped_ = bytes;
      return true;
    }
    data_ = static_cast<T*>(std::aligned_alloc(64, bytes));
    if (!data_) throw std::bad_alloc();
    return false;
  }
  void release() {
    if (owned_ && data_) {
      if (mapped_)
        munmap(data_, mapped_);
      else
        std::free(data_);
    }
    data_ = nullptr;
    mapped_ = 0;
  }
  T* data_ = nullptr;
  std::size_t n_ = 0;
  TileGeom geom_{};
  bool owned_ = true;       // false: a view (see view())
  std::size_t mapped_ = 0;  // bytes mapped (allocate), 0: from the heap
};

// The owned cells of a field (no halo), row-major [ny][nx], each converted.
template <class U, class T, class Convert>
std::vector<U> owned_cells(const Field<T>& f, Convert convert) {
  const TileGeom& g = f.geom();
  std::vector<U> v;
  v.reserve(static_cast<std::size_t>(g.nx) * g.ny);
  for (int y = 0; y < g.ny; ++y)
    for (int x = 0; x < g.nx; ++x) v.push_back(convert(f(x, y)));
  return v;
}
template <class T>
std::vector<T> owned_cells(const Field<T>& f) {
  return owned_cells<T>(f, [](const T& t) { return t; });
}

// Sets the owned cells from row-major [ny][nx] values, each converted.
template <class T, class V, class Convert>
void set_owned_cells(Field<T>& f, const std::vector<V>& v, Convert convert) {
  const TileGeom& g = f.geom();
  for (int y = 0; y < g.ny; ++y)
    for (int x = 0; x < g.nx; ++x) f(x, y) = convert(v[static_cast<std::size_t>(y) * g.nx + x]);
}
template <class T>
void set_owned_cells(Field<T>& f, const std::vector<T>& v) {
  set_owned_cells(f, v, [](const T& t) { return t; });
}

}  // namespace erg
