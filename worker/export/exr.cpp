// SPDX-License-Identifier: Apache-2.0
// OpenEXR export: one 32-bit float channel "Y" (luminance: DCC tools and
// Houdini read a one-channel height field from it), ZIP compression, the
// first row at the north edge, erg's provenance as string attributes.
#include <ImfChannelList.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfOutputFile.h>
#include <ImfStandardAttributes.h>
#include <ImfStringAttribute.h>

#include <exception>
#include <string>
#include <vector>

#include "export/export.h"
#include "io/atomic_file.h"

namespace erg::exporting {

void write_exr(const std::string& path, const Field& f, const Provenance& p) {
  io::detail::AtomicFile out(path);
  try {
    std::vector<float> rows(f.v.size());  // north first
    for (int r = 0; r < f.ny; ++r)
      for (int x = 0; x < f.nx; ++x)
        rows[static_cast<std::size_t>(r) * f.nx + x] =
            f.v[static_cast<std::size_t>(f.ny - 1 - r) * f.nx + x];
    Imf::Header header(f.nx, f.ny);
    header.compression() = Imf::ZIP_COMPRESSION;
    header.channels().insert("Y", Imf::Channel(Imf::FLOAT));
    header.insert("ergJobSpec", Imf::StringAttribute(p.job_spec_json));
    header.insert("ergStep", Imf::StringAttribute(std::to_string(p.step)));
    header.insert("ergTimeDays", Imf::StringAttribute(std::to_string(p.time_days)));
    header.insert("ergLayer", Imf::StringAttribute(p.layer));
    header.insert("ergPixelSizeM", Imf::StringAttribute(std::to_string(f.pixel_m)));
    Imf::FrameBuffer fb;
    fb.insert("Y", Imf::Slice(Imf::FLOAT, reinterpret_cast<char*>(rows.data()), sizeof(float),
                              sizeof(float) * static_cast<std::size_t>(f.nx)));
    {
      Imf::OutputFile file(out.tmp().c_str(), header);
      file.setFrameBuffer(fb);
      file.writePixels(f.ny);
    }  // closed here, before the rename
  } catch (const std::exception& e) {
    throw ExportError(path + ": writing EXR failed: " + e.what());
  }
  out.commit();
}

}  // namespace erg::exporting
