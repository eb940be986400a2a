// SPDX-License-Identifier: Apache-2.0
// GeoTIFF export through GDAL: float32, DEFLATE with the floating-point
// predictor (PREDICTOR=3), 256 x 256 tiles, the pixel size as geotransform and
// a local engineering CRS in metres (the domain is a torus, not a place on
// Earth), the job spec and the step in GDAL metadata.
// Built with ERG_WITH_GDAL=OFF (ERG_NO_GDAL), write_geotiff refuses, naming
// the missing feature; the other formats need no GDAL.
#include <string>

#include "export/export.h"

#if defined(ERG_NO_GDAL)

namespace erg::exporting {
void write_geotiff(const std::string& path, const Field&, const Provenance&) {
  throw ExportError(path +
                    ": GeoTIFF export is not available: this erg was built without GDAL "
                    "(ERG_WITH_GDAL=OFF); use --format png16, exr or obj, or a build with GDAL");
}
}  // namespace erg::exporting

#else

#include <cpl_conv.h>
#include <cpl_string.h>
#include <gdal.h>

#include <mutex>

#include "io/atomic_file.h"

namespace erg::exporting {

namespace {

// The spec as one line of JSON: the snapshot holds it indented (job::to_json),
// and a GeoTIFF tag of hundreds of lines drowns gdalinfo's output. Whitespace
// outside strings is dropped; the spec is valid JSON (the worker wrote it),
// and strings are copied as they are.
std::string one_line_json(const std::string& json) {
  std::string out;
  out.reserve(json.size());
  bool in_string = false, escaped = false;
  for (const char c : json) {
    if (in_string) {
      out += c;
      if (escaped)
        escaped = false;
      else if (c == '\\')
        escaped = true;
      else if (c == '"')
        in_string = false;
    } else if (c == '"') {
      in_string = true;
      out += c;
    } else if (c != ' ' && c != '\n' && c != '\r' && c != '\t') {
      out += c;
    }
  }
  return out;
}
// LOCAL_CS: GDAL and QGIS show metres, and nothing pretends the terrain lies
// at a geographic position.
constexpr const char* kLocalCs =
    "LOCAL_CS[\"erg local engineering (periodic domain)\",LOCAL_DATUM[\"erg torus\",0],"
    "UNIT[\"metre\",1,AUTHORITY[\"EPSG\",\"9001\"]],AXIS[\"Easting\",EAST],"
    "AXIS[\"Northing\",NORTH]]";
}  // namespace

void write_geotiff(const std::string& path, const Field& f, const Provenance& p) {
  static std::once_flag once;
  std::call_once(once, [] {
    GDALAllRegister();
    // No .aux.xml side files: everything lives in the TIFF.
    CPLSetConfigOption("GDAL_PAM_ENABLED", "NO");
  });
  // Errors go into the exception, not to stderr.
  CPLPushErrorHandler(CPLQuietErrorHandler);
  struct Pop {
    ~Pop() { CPLPopErrorHandler(); }
  } pop;
  GDALDriverH drv = GDALGetDriverByName("GTiff");
  if (!drv) throw ExportError(path + ": GDAL has no GTiff driver");
  io::detail::AtomicFile out(path);
  char** opts = nullptr;
  opts = CSLSetNameValue(opts, "COMPRESS", "DEFLATE");
  opts = CSLSetNameValue(opts, "PREDICTOR", "3");
  opts = CSLSetNameValue(opts, "TILED", "YES");
  opts = CSLSetNameValue(opts, "BLOCKXSIZE", "256");
  opts = CSLSetNameValue(opts, "BLOCKYSIZE", "256");
  opts = CSLSetNameValue(opts, "BIGTIFF", "IF_SAFER");
  CPLErrorReset();
  GDALDatasetH ds = GDALCreate(drv, out.tmp().c_str(), f.nx, f.ny, 1, GDT_Float32, opts);
  CSLDestroy(opts);
  if (!ds)
    throw ExportError(path + ": GDAL cannot create '" + out.tmp() + "': " + CPLGetLastErrorMsg());
  // North-up: the first image row is the north edge.
  double gt[6] = {f.x0_m, f.pixel_m, 0, f.y0_m + f.ny * f.pixel_m, 0, -f.pixel_m};
  bool ok = GDALSetGeoTransform(ds, gt) == CE_None && GDALSetProjection(ds, kLocalCs) == CE_None;
  ok = ok && GDALSetMetadataItem(ds, "ERG_JOB_SPEC", one_line_json(p.job_spec_json).c_str(),
                                 nullptr) == CE_None;
  ok =
      ok && GDALSetMetadataItem(ds, "ERG_STEP", std::to_string(p.step).c_str(), nullptr) == CE_None;
  ok = ok && GDALSetMetadataItem(ds, "ERG_TIME_DAYS", std::to_string(p.time_days).c_str(),
                                 nullptr) == CE_None;
  ok = ok && GDALSetMetadataItem(ds, "ERG_LAYER", p.layer.c_str(), nullptr) == CE_None;
  ok = ok && GDALSetMetadataItem(ds, "ERG_VERSION", p.erg_version.c_str(), nullptr) == CE_None;
  GDALRasterBandH band = GDALGetRasterBand(ds, 1);
  ok = ok && GDALSetRasterUnitType(band, p.layer == "vegetation" ? "" : "m") == CE_None;
  std::vector<float> row(static_cast<std::size_t>(f.nx));
  for (int r = 0; ok && r < f.ny; ++r) {
    const float* src = f.v.data() + static_cast<std::size_t>(f.ny - 1 - r) * f.nx;
    row.assign(src, src + f.nx);
    ok = GDALRasterIO(band, GF_Write, 0, r, f.nx, 1, row.data(), f.nx, 1, GDT_Float32, 0, 0) ==
         CE_None;
  }
  const std::string err = ok ? "" : CPLGetLastErrorMsg();
  // GDALClose flushes; from GDAL 3.7 it returns an error code, here we check
  // the last error after it.
  CPLErrorReset();
  GDALClose(ds);
  if (!ok) throw ExportError(path + ": writing GeoTIFF failed: " + err);
  if (CPLGetLastErrorType() >= CE_Failure)
    throw ExportError(path + ": closing GeoTIFF failed: " + CPLGetLastErrorMsg());
  out.commit();
}

}  // namespace erg::exporting

#endif  // ERG_NO_GDAL
