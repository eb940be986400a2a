// SPDX-License-Identifier: Apache-2.0
// The rectangles a halo exchange moves and the packer that moves them
// (HaloExchanger, dist/halo.h). No MPI here: a device backend implements a
// packer in its own compiler (the CUDA backend, for a CUDA-aware MPI).
#pragma once

#include <cstddef>
#include <span>
#include <vector>

#include "dist/ghosts.h"

namespace erg::dist {

// Local cells [x0, x1) x [y0, y1).
struct Rect {
  int x0, x1, y0, y1;
};

// The edge and ghost rectangles of width w on a tile of nx x ny (local
// cells): the x phase runs on owned rows, the y phase on the full padded
// width (carrying the corners).
struct HaloRects {
  int nx, ny;
  Rect left_edge(int w) const { return {0, w, 0, ny}; }
  Rect right_edge(int w) const { return {nx - w, nx, 0, ny}; }
  Rect left_ghost(int w) const { return {-w, 0, 0, ny}; }
  Rect right_ghost(int w) const { return {nx, nx + w, 0, ny}; }
  Rect down_edge(int w) const { return {-w, nx + w, 0, w}; }
  Rect up_edge(int w) const { return {-w, nx + w, ny - w, ny}; }
  Rect down_ghost(int w) const { return {-w, nx + w, -w, 0}; }
  Rect up_ghost(int w) const { return {-w, nx + w, ny, ny + w}; }
};
// One of them, for every field at its own width.
struct RectOf {
  HaloRects rects;
  Rect (HaloRects::*of)(int) const;
  Rect operator()(int w) const { return (rects.*of)(w); }
};

// Where the messages of an exchange are packed from and unpacked into. A
// message carries, for every field of the list with a width > 0 in list
// order, its rectangle rect(width) row by row. The default packer works on
// the host fields in host memory; a device backend whose MPI reads device
// memory (CUDA-aware, dist/halo_path.h) supplies one that packs the fields'
// device copies (Ghosts::device) into device buffers, which MPI then reads
// and writes directly.
class HaloPacker {
 public:
  virtual ~HaloPacker() = default;
  // Storage of at least `bytes` for message slot s (0-3: sent towards
  // left, right, down, up; 4-7: received from them), valid until the next
  // call for that slot.
  virtual char* buffer(int slot, std::size_t bytes) = 0;
  virtual void pack(std::span<const Ghosts> fields, const RectOf& rect, char* dst) = 0;
  // Copies (add = false) or adds what src holds into the rectangles.
  virtual void unpack(std::span<const Ghosts> fields, const RectOf& rect, const char* src,
                      bool add) = 0;
  virtual void zero(std::span<const Ghosts> fields, const RectOf& rect) = 0;
  // Every pack is complete: MPI may read the buffers (a device waits for
  // its kernels here).
  virtual void ready() {}
};

// A packer whose messages live in host memory (buffers that grow).
class HostBufferPacker : public HaloPacker {
 public:
  char* buffer(int slot, std::size_t bytes) override {
    std::vector<char>& b = buf_[slot];
    if (b.size() < bytes) b.resize(bytes);
    return b.data();
  }

 private:
  std::vector<char> buf_[8];
};

}  // namespace erg::dist
