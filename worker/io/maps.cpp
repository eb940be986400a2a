// SPDX-License-Identifier: Apache-2.0
// Input maps (initial bedrock, sand, vegetation; masks) from HDF5 datasets or
// greyscale PNGs, and the 16-bit PNG writer used for exports and tests.
//
// Orientation: maps are [ny][nx] with row 0 = y = 0 = south. An HDF5 dataset
// is taken as stored (row 0 first); an image shows north at the top, so its
// first image row is y = ny - 1.
#include <png.h>

#include <algorithm>
#include <cerrno>
#include <climits>
#include <cmath>
#include <csetjmp>
#include <cstdint>
#include <cstdio>
#include <string>
#include <vector>

#include "io/atomic_file.h"
#include "io/hdf5_util.h"
#include "io/io.h"
#include "io/png_util.h"

namespace erg::io {
namespace {

using detail::fail;
using detail::Hid;

// Everything a PNG decode needs, owned outside the setjmp functions below so
// that a longjmp out of libpng skips no destructor.
struct PngReader {
  FILE* fp = nullptr;
  png_structp png = nullptr;
  png_infop info = nullptr;
  detail::PngError err;
  png_uint_32 width = 0, height = 0;
  int bit_depth = 0;  // 8 or 16 after the transforms
  int channels = 0;   // 1 (grey) or 3 (RGB) after the transforms
  std::size_t rowbytes = 0;

  PngReader() = default;
  PngReader(const PngReader&) = delete;
  PngReader& operator=(const PngReader&) = delete;
  ~PngReader() {
    if (png) png_destroy_read_struct(&png, info ? &info : nullptr, nullptr);
    if (fp) std::fclose(fp);
  }
};

// Reads the header and sets the transforms that reduce every PNG to 8- or
// 16-bit grey or RGB: palettes expand to RGB, 1/2/4-bit grey widens to 8 bits
// (scaled to 0..255), alpha is dropped. No gamma correction is applied: a
// heightmap's samples are data, not light.
bool png_read_header(PngReader* r) {
  r->png = png_create_read_struct(PNG_LIBPNG_VER_STRING, &r->err, detail::png_error_to_buffer,
                                  detail::png_ignore_warning);
  if (!r->png) return false;
  r->info = png_create_info_struct(r->png);
  if (!r->info) return false;
  if (setjmp(png_jmpbuf(r->png))) return false;
  png_init_io(r->png, r->fp);
  png_set_sig_bytes(r->png, 8);
  png_read_info(r->png, r->info);
  const int color_type = png_get_color_type(r->png, r->info);
  const int depth = png_get_bit_depth(r->png, r->info);
  if (color_type == PNG_COLOR_TYPE_PALETTE) png_set_palette_to_rgb(r->png);
  if (color_type == PNG_COLOR_TYPE_GRAY && depth < 8) png_set_expand_gray_1_2_4_to_8(r->png);
  if (color_type & PNG_COLOR_MASK_ALPHA) png_set_strip_alpha(r->png);
  png_set_interlace_handling(r->png);
  png_read_update_info(r->png, r->info);
  r->width = png_get_image_width(r->png, r->info);
  r->height = png_get_image_height(r->png, r->info);
  r->bit_depth = png_get_bit_depth(r->png, r->info);
  r->channels = png_get_channels(r->png, r->info);
  r->rowbytes = png_get_rowbytes(r->png, r->info);
  return true;
}

bool png_read_pixels(PngReader* r, png_bytepp rows) {
  if (setjmp(png_jmpbuf(r->png))) return false;
  png_read_image(r->png, rows);
  png_read_end(r->png, nullptr);
  return true;
}

}  // namespace

Map read_hdf5_map(const std::string& path, const std::string& dataset) {
  detail::Hdf5Guard guard;
  Hid file = detail::open_hdf5_readonly(path, "map file");
  std::vector<hsize_t> dims;
  Hid dset = detail::open_dataset(file.get(), dataset, dims, path);
  if (dims.size() != 2) {
    fail(path, "dataset '" + dataset + "' has rank " + std::to_string(dims.size()) + " (shape " +
                   detail::shape_text(dims) + "); a map must be 2-D [ny][nx]");
  }
  Hid type =
      detail::checked(H5Dget_type(dset.get()), H5Tclose, path, "type of dataset '" + dataset + "'");
  H5T_class_t cls = H5Tget_class(type.get());
  if (cls != H5T_INTEGER && cls != H5T_FLOAT) {
    fail(path, "dataset '" + dataset + "' is not numeric (integer or float)");
  }
  if (dims[0] == 0 || dims[1] == 0 || dims[0] > INT_MAX || dims[1] > INT_MAX) {
    fail(path, "dataset '" + dataset + "' has unusable shape " + detail::shape_text(dims));
  }
  Map m;
  m.ny = static_cast<int>(dims[0]);
  m.nx = static_cast<int>(dims[1]);
  m.values.resize(static_cast<std::size_t>(m.nx) * static_cast<std::size_t>(m.ny));
  // HDF5 converts any integer or float type to double on read.
  detail::check(
      H5Dread(dset.get(), H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, m.values.data()), path,
      "cannot read dataset '" + dataset + "'");
  return m;
}

Map read_png_map(const std::string& path) {
  PngReader r;
  r.fp = std::fopen(path.c_str(), "rb");
  if (!r.fp) detail::fail_errno(path, "cannot open PNG map", errno);
  unsigned char sig[8] = {};
  if (std::fread(sig, 1, sizeof sig, r.fp) != sizeof sig || png_sig_cmp(sig, 0, sizeof sig) != 0) {
    fail(path, "not a PNG file");
  }
  if (!png_read_header(&r)) fail(path, std::string("cannot read PNG header: ") + r.err.msg);
  if ((r.channels != 1 && r.channels != 3) || (r.bit_depth != 8 && r.bit_depth != 16)) {
    fail(path, "unsupported PNG layout (" + std::to_string(r.channels) + " channels of " +
                   std::to_string(r.bit_depth) + " bits)");
  }
  if (r.width == 0 || r.height == 0 || r.width > INT_MAX || r.height > INT_MAX) {
    fail(path, "unusable PNG size");
  }

  const std::size_t w = r.width, h = r.height;
  std::vector<unsigned char> pixels(r.rowbytes * h);
  std::vector<png_bytep> rows(h);
  for (std::size_t y = 0; y < h; ++y) rows[y] = pixels.data() + y * r.rowbytes;
  if (!png_read_pixels(&r, rows.data())) fail(path, std::string("cannot decode PNG: ") + r.err.msg);

  // Normalise samples to [0, 1]. RGB is reduced to its Rec. 709 luminance
  // (weights on the stored values, no gamma), so a grey image saved as RGB
  // reads exactly like the greyscale one.
  const bool wide = r.bit_depth == 16;
  const double scale = 1.0 / (wide ? 65535.0 : 255.0);
  auto sample = [&](const unsigned char* row, std::size_t i) -> double {
    return wide ? static_cast<double>((row[2 * i] << 8) | row[2 * i + 1]) : row[i];
  };
  Map m;
  m.nx = static_cast<int>(w);
  m.ny = static_cast<int>(h);
  m.values.resize(w * h);
  for (std::size_t iy = 0; iy < h; ++iy) {
    const unsigned char* row = rows[iy];
    double* dst = m.values.data() + (h - 1 - iy) * w;  // image top = north = y = ny - 1
    for (std::size_t x = 0; x < w; ++x) {
      if (r.channels == 1) {
        dst[x] = sample(row, x) * scale;
      } else {
        double lum = 0.2126 * sample(row, 3 * x) + 0.7152 * sample(row, 3 * x + 1) +
                     0.0722 * sample(row, 3 * x + 2);
        dst[x] = std::min(1.0, lum * scale);  // the weights sum to 1 only up to rounding
      }
    }
  }
  return m;
}

void write_png16(const std::string& path, int nx, int ny, const std::vector<double>& values01) {
  if (nx <= 0 || ny <= 0) {
    fail(path, "invalid image size " + std::to_string(nx) + " x " + std::to_string(ny));
  }
  const std::size_t w = static_cast<std::size_t>(nx), h = static_cast<std::size_t>(ny);
  if (values01.size() != w * h) {
    fail(path, "PNG data has " + std::to_string(values01.size()) +
                   " values, expected nx * ny = " + std::to_string(w * h));
  }
  for (std::size_t i = 0; i < values01.size(); ++i) {
    if (!std::isfinite(values01[i])) {
      fail(path, "value at x = " + std::to_string(i % w) + ", y = " + std::to_string(i / w) +
                     " is not finite");
    }
  }
  // Clamp to [0, 1], round to the nearest of 65536 levels, big-endian as PNG
  // stores 16-bit samples. Image row 0 is the north edge (y = ny - 1).
  detail::write_png_atomically(
      path, nx, ny, 16, PNG_COLOR_TYPE_GRAY, 1, [&](int row, unsigned char* out) {
        const double* src = values01.data() + (h - 1 - static_cast<std::size_t>(row)) * w;
        for (std::size_t x = 0; x < w; ++x) {
          double v = std::min(1.0, std::max(0.0, src[x]));
          auto q = static_cast<std::uint16_t>(std::lround(v * 65535.0));
          out[2 * x] = static_cast<unsigned char>(q >> 8);
          out[2 * x + 1] = static_cast<unsigned char>(q & 0xff);
        }
      });
}

}  // namespace erg::io
