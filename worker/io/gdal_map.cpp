// SPDX-License-Identifier: Apache-2.0
// Input maps through GDAL (GeoTIFF, and any raster GDAL reads): band 1 as
// doubles, row 0 = south, with the pixel size and linear unit the file gives.
// Built with ERG_WITH_GDAL=OFF (ERG_NO_GDAL), read_gdal_map refuses, naming
// the missing feature.
#include <string>

#include "io/atomic_file.h"
#include "io/io.h"

#if defined(ERG_NO_GDAL)

namespace erg::io {
Map read_gdal_map(const std::string& path) {
  detail::fail(path,
               "GeoTIFF map imports are not available: this erg was built without GDAL "
               "(ERG_WITH_GDAL=OFF); convert the map to HDF5, PNG16 or EXR, or use a build with "
               "GDAL");
}
}  // namespace erg::io

#else

#include <cpl_conv.h>
#include <gdal.h>
#include <ogr_srs_api.h>

#include <climits>
#include <cmath>
#include <mutex>
#include <string>
#include <vector>

namespace erg::io {

namespace {
using detail::fail;

// GDAL prints its errors on stderr by default; ours carry them in the
// exception instead (CPLGetLastErrorMsg still records them).
struct QuietGdal {
  QuietGdal() { CPLPushErrorHandler(CPLQuietErrorHandler); }
  ~QuietGdal() { CPLPopErrorHandler(); }
  QuietGdal(const QuietGdal&) = delete;
  QuietGdal& operator=(const QuietGdal&) = delete;
};

struct Dataset {
  GDALDatasetH h = nullptr;
  ~Dataset() {
    if (h) GDALClose(h);
  }
};
}  // namespace

Map read_gdal_map(const std::string& path) {
  static std::once_flag once;
  std::call_once(once, [] { GDALAllRegister(); });
  QuietGdal quiet;
  CPLErrorReset();
  Dataset ds;
  ds.h = GDALOpenEx(path.c_str(), GDAL_OF_RASTER | GDAL_OF_READONLY, nullptr, nullptr, nullptr);
  if (!ds.h) {
    const char* msg = CPLGetLastErrorMsg();
    fail(path, std::string("GDAL cannot open it as a raster") +
                   (msg && *msg ? std::string(": ") + msg : std::string()));
  }
  if (GDALGetRasterCount(ds.h) < 1) fail(path, "the raster has no band");
  const int w = GDALGetRasterXSize(ds.h), h = GDALGetRasterYSize(ds.h);
  if (w <= 0 || h <= 0) fail(path, "unusable raster size");
  GDALRasterBandH band = GDALGetRasterBand(ds.h, 1);
  std::vector<double> rows(static_cast<std::size_t>(w) * static_cast<std::size_t>(h));
  if (GDALRasterIO(band, GF_Read, 0, 0, w, h, rows.data(), w, h, GDT_Float64, 0, 0) != CE_None)
    fail(path, std::string("cannot read band 1: ") + CPLGetLastErrorMsg());
  int has_nodata = 0;
  const double nodata = GDALGetRasterNoDataValue(band, &has_nodata);

  Map m;
  m.nx = w;
  m.ny = h;
  double gt[6] = {0, 1, 0, 0, 0, 1};
  const bool georeferenced = GDALGetGeoTransform(ds.h, gt) == CE_None;
  if (georeferenced && (gt[2] != 0 || gt[4] != 0))
    fail(path,
         "the raster is rotated or sheared (geotransform terms 2 and 4 are not 0); "
         "warp it north-up first (gdalwarp)");
  // Images are stored north up (gt[5] < 0): the first row is the north edge.
  const bool north_up = !georeferenced || gt[5] < 0;
  if (georeferenced) {
    m.pixel_w = std::fabs(gt[1]);
    m.pixel_h = std::fabs(gt[5]);
    m.units = "unknown";
    if (const char* wkt = GDALGetProjectionRef(ds.h); wkt && *wkt) {
      OGRSpatialReferenceH srs = OSRNewSpatialReference(wkt);
      if (srs) {
        if (OSRIsGeographic(srs)) {
          OSRDestroySpatialReference(srs);
          fail(path,
               "the raster is in geographic coordinates (degrees); reproject it to a "
               "projected CRS in metres first (gdalwarp -t_srs)");
        }
        char* name = nullptr;
        const double to_m = OSRGetLinearUnits(srs, &name);
        m.units = name ? name : "unknown";
        m.units_m = to_m;
        OSRDestroySpatialReference(srs);
      }
    }
  }
  m.values.resize(rows.size());
  for (int r = 0; r < h; ++r) {
    const int y = north_up ? h - 1 - r : r;
    for (int x = 0; x < w; ++x) {
      const double v = rows[static_cast<std::size_t>(r) * w + x];
      if ((has_nodata && v == nodata) || !std::isfinite(v))
        fail(path, "pixel (" + std::to_string(x) + ", " + std::to_string(y) +
                       ") has no data; fill the holes first (gdal_fillnodata.py)");
      m.values[static_cast<std::size_t>(y) * w + x] = v;
    }
  }
  return m;
}

}  // namespace erg::io

#endif  // ERG_NO_GDAL
