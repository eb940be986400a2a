// SPDX-License-Identifier: Apache-2.0
// Input maps as the job names them (erg.v1.MapFile): the format from the
// field or the extension, the reader, the tileability test, the border
// cross-fade and the resampling to the domain's grid. validate() and the
// layer generator both call load_map, so a map accepted by one is read the
// same way by the other.
#pragma once

#include <stdexcept>
#include <string>

#include "erg/v1/job.pb.h"
#include "io/io.h"

namespace erg::job {

// The format of a map: map.format, else guessed from the extension (.h5
// .hdf5 .he5: HDF5; .png: PNG16; .tif .tiff: GEOTIFF; .exr: EXR, any case).
// FORMAT_UNSPECIFIED when neither says.
erg::v1::MapFile::Format map_format(const erg::v1::MapFile& map, const std::string& file);

// A map that cannot be used; the message starts with the field it concerns
// relative to the map (".path", ".blend_border_m"), e.g.
// ".path = \"dem.tif\" is not tileable: ...".
struct MapError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

// Reads the map, checks it is tileable (unless blend_border_m > 0, which
// cross-fades the borders), and brings it to domain.nx x domain.ny cells:
// a georeferenced raster (GeoTIFF with a pixel size) must cover the domain's
// extent within one pixel and is resampled bilinearly on the torus when its
// pixel size differs from domain.cell_size_m; any other map must have the
// domain's size. Raw values: scale and offset are applied by the caller.
// `note`, when given, receives one line describing the file and what was
// done to it (pixel size, units, resampling, blending).
io::Map load_map(const erg::v1::MapFile& map, const erg::v1::JobSpec& spec,
                 const std::string& base_dir, std::string* note = nullptr);

// One note per map of the spec ("layers.bedrock.map: ..."), for `erg check`.
std::vector<std::string> describe_maps(const erg::v1::JobSpec& spec, const std::string& base_dir);

}  // namespace erg::job
