// SPDX-License-Identifier: Apache-2.0
// Internal to erg_io: libpng error plumbing and the atomic PNG writer shared
// by previews (8-bit RGB) and heightmap exports (16-bit grey).
//
// libpng reports a fatal error by calling an error function that must not
// return. Ours records the message and longjmps back to the setjmp in the
// function that called into libpng. Such functions hold only trivially
// destructible locals (raw pointers and ints, any buffers live in the caller),
// so the jump skips no C++ destructor, which would be undefined behaviour.
#pragma once

#include <png.h>

#include <cerrno>
#include <csetjmp>
#include <cstddef>
#include <cstdio>
#include <string>
#include <vector>

#include "io/atomic_file.h"

namespace erg::io::detail {

struct PngError {
  char msg[256] = "unknown libpng error";
};

inline void png_error_to_buffer(png_structp png, png_const_charp msg) {
  auto* err = static_cast<PngError*>(png_get_error_ptr(png));
  std::snprintf(err->msg, sizeof err->msg, "%s", msg ? msg : "libpng error");
  png_longjmp(png, 1);
}

// Warnings (e.g. about ancillary chunks of an input file) are not failures.
inline void png_ignore_warning(png_structp, png_const_charp) {}

// Produces PNG row `row` (0 = top of the image) into `out`. Must not throw:
// it runs between setjmp and libpng.
using PngRowFiller = void (*)(void* ctx, int row, unsigned char* out);

// Encodes a whole image to `fp`; false with err->msg set on failure. `row` is
// a caller-owned buffer of one row.
inline bool png_encode(FILE* fp, int width, int height, int bit_depth, int color_type,
                       PngRowFiller fill, void* ctx, unsigned char* row, PngError* err) {
  png_structp png =
      png_create_write_struct(PNG_LIBPNG_VER_STRING, err, png_error_to_buffer, png_ignore_warning);
  if (!png) {
    std::snprintf(err->msg, sizeof err->msg, "png_create_write_struct failed");
    return false;
  }
  png_infop info = png_create_info_struct(png);
  if (!info) {
    png_destroy_write_struct(&png, nullptr);
    std::snprintf(err->msg, sizeof err->msg, "png_create_info_struct failed");
    return false;
  }
  if (setjmp(png_jmpbuf(png))) {
    png_destroy_write_struct(&png, &info);
    return false;
  }
  png_init_io(png, fp);
  // Level 6 is zlib's default trade-off; previews and maps are written rarely.
  png_set_compression_level(png, 6);
  png_set_IHDR(png, info, static_cast<png_uint_32>(width), static_cast<png_uint_32>(height),
               bit_depth, color_type, PNG_INTERLACE_NONE, PNG_COMPRESSION_TYPE_DEFAULT,
               PNG_FILTER_TYPE_DEFAULT);
  png_write_info(png, info);
  for (int y = 0; y < height; ++y) {
    fill(ctx, y, row);
    png_write_row(png, row);
  }
  png_write_end(png, nullptr);
  png_destroy_write_struct(&png, &info);
  return true;
}

// Writes a PNG atomically. `fill(row, out)` produces image row `row` (top
// first) of `width * channels * bit_depth / 8` bytes, big-endian samples for
// 16-bit images as PNG stores them; it must not throw.
template <class Fill>
void write_png_atomically(const std::string& path, int width, int height, int bit_depth,
                          int color_type, int channels, const Fill& fill) {
  std::vector<unsigned char> row(static_cast<std::size_t>(width) *
                                 static_cast<std::size_t>(channels) *
                                 static_cast<std::size_t>(bit_depth / 8));
  auto trampoline = [](void* ctx, int r, unsigned char* out) {
    (*static_cast<const Fill*>(ctx))(r, out);
  };

  AtomicFile out(path);
  FILE* fp = out.open_stdio();
  PngError err;
  errno = 0;
  if (!png_encode(fp, width, height, bit_depth, color_type, trampoline, const_cast<Fill*>(&fill),
                  row.data(), &err)) {
    // libpng's own message for I/O trouble is only "Write Error": add errno.
    int e = errno;
    std::fclose(fp);
    std::string what =
        std::string("writing PNG to temporary file '") + out.tmp() + "' failed: " + err.msg;
    if (e != 0) what += " (" + errno_text(e) + ")";
    fail(path, what);
  }
  out.close_stdio(fp);
  out.commit();
}

}  // namespace erg::io::detail
