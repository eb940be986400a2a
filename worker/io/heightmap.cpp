// SPDX-License-Identifier: Apache-2.0
// Heightmaps of amplified regions (erg amplify).
#include <hdf5.h>

#include <string>
#include <vector>

#include "io/hdf5_util.h"
#include "io/io.h"

namespace erg::io {

void write_heightmap(const std::string& path, const HeightmapMeta& meta, const float* height) {
  if (meta.nx <= 0 || meta.ny <= 0 || !height) {
    detail::fail(path, "heightmap needs nx, ny > 0 and data (got " + std::to_string(meta.nx) +
                           " x " + std::to_string(meta.ny) + ")");
  }
  detail::AtomicFile out(path);
  std::vector<char> image;
  {
    detail::Hdf5Guard guard;
    detail::Hid file = detail::create_hdf5_in_memory(out);
    const hid_t fid = file.get();
    const std::vector<hsize_t> dims = {static_cast<hsize_t>(meta.ny),
                                       static_cast<hsize_t>(meta.nx)};
    detail::write_dataset(fid, "height", H5T_IEEE_F32LE, H5T_NATIVE_FLOAT, dims, height, 4, path);
    detail::write_attr_f64(fid, "cell_size_m", meta.cell_size_m, path);
    detail::write_attr_i64(fid, "nx", meta.nx, path);
    detail::write_attr_i64(fid, "ny", meta.ny, path);
    for (const auto& [name, value] : meta.attrs) detail::write_attr_f64(fid, name, value, path);
    detail::write_attr_str(fid, "source", meta.source, path);
    image = detail::take_hdf5_image(file, path);
  }
  out.write_whole(image.data(), image.size());
  out.commit();
}

}  // namespace erg::io
