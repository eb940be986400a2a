// SPDX-License-Identifier: Apache-2.0
// Host storage of one padded per-cell field (see grid.h).
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdlib>
#include <cstring>
#include <new>
#include <utility>
#include <vector>

#include "core/grid.h"

namespace erg {

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
      if (n_) std::memcpy(data_, o.data_, n_ * sizeof(T));
    }
    return *this;
  }
  Field(Field&& o) noexcept { swap(o); }
  Field& operator=(Field&& o) noexcept {
    swap(o);
    return *this;
  }
  ~Field() {
    if (owned_) std::free(data_);
  }

  void reset(const TileGeom& g, T fill = T{}) {
    geom_ = g;
    allocate(g.size());
    std::fill(data_, data_ + n_, fill);
  }
  // Storage shared with other fields (a backend's work buffers, whose
  // lifetimes do not overlap): g.size() values at `p`, which the caller
  // keeps alive and which this field does not free. Nothing is filled.
  void view(T* p, const TileGeom& g) {
    if (owned_) std::free(data_);
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
  void allocate(std::size_t n) {
    if (n == n_ && data_ && owned_) return;
    if (owned_) std::free(data_);
    data_ = nullptr;
    owned_ = true;
    n_ = n;
    if (n == 0) return;
    std::size_t bytes = (n * sizeof(T) + 63) / 64 * 64;
    data_ = static_cast<T*>(std::aligned_alloc(64, bytes));
    if (!data_) throw std::bad_alloc();
  }
  T* data_ = nullptr;
  std::size_t n_ = 0;
  TileGeom geom_{};
  bool owned_ = true;  // false: a view (see view())
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
