// SPDX-License-Identifier: Apache-2.0
// Input maps from OpenEXR images: one float channel, first row = north edge.
#include <ImathBox.h>
#include <ImfChannelList.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfInputFile.h>

#include <cmath>
#include <exception>
#include <string>
#include <vector>

#include "io/atomic_file.h"
#include "io/io.h"

namespace erg::io {

Map read_exr_map(const std::string& path) {
  using detail::fail;
  try {
    Imf::InputFile file(path.c_str());
    const Imath::Box2i dw = file.header().dataWindow();
    const long long w = static_cast<long long>(dw.max.x) - dw.min.x + 1;
    const long long h = static_cast<long long>(dw.max.y) - dw.min.y + 1;
    if (w <= 0 || h <= 0 || w > (1 << 20) || h > (1 << 20)) fail(path, "unusable EXR size");
    const Imf::ChannelList& channels = file.header().channels();
    // A const char* rather than a std::string: GCC 12 warns (-Wrestrict, a
    // false positive) on assigning short literals to a string here.
    const char* name = nullptr;
    if (channels.findChannel("Y"))
      name = "Y";
    else if (channels.findChannel("R"))
      name = "R";
    else {
      int n = 0;
      for (auto it = channels.begin(); it != channels.end(); ++it, ++n) name = it.name();
      if (n != 1) fail(path, "EXR has no channel Y or R and not exactly one channel");
    }
    std::vector<float> pixels(static_cast<std::size_t>(w * h));
    Imf::FrameBuffer fb;
    // The slice base is offset so that pixel (dw.min.x, dw.min.y) lands at index 0.
    char* base = reinterpret_cast<char*>(pixels.data()) -
                 (static_cast<std::ptrdiff_t>(dw.min.x) +
                  static_cast<std::ptrdiff_t>(dw.min.y) * static_cast<std::ptrdiff_t>(w)) *
                     static_cast<std::ptrdiff_t>(sizeof(float));
    fb.insert(name, Imf::Slice(Imf::FLOAT, base, sizeof(float),
                               sizeof(float) * static_cast<std::size_t>(w)));
    file.setFrameBuffer(fb);
    file.readPixels(dw.min.y, dw.max.y);
    Map m;
    m.nx = static_cast<int>(w);
    m.ny = static_cast<int>(h);
    m.values.resize(pixels.size());
    for (long long r = 0; r < h; ++r)
      for (long long x = 0; x < w; ++x) {
        const float v = pixels[static_cast<std::size_t>(r * w + x)];
        if (!std::isfinite(v))
          fail(path, "pixel (" + std::to_string(x) + ", " + std::to_string(h - 1 - r) +
                         ") of channel " + std::string(name) + " is not finite");
        m.values[static_cast<std::size_t>((h - 1 - r) * w + x)] = v;
      }
    return m;
  } catch (const IoError&) {
    throw;
  } catch (const std::exception& e) {
    fail(path, std::string("cannot read EXR: ") + e.what());
  }
}

}  // namespace erg::io
