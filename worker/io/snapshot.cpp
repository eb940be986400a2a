// Snapshots: one HDF5 file per output step (float32 layers in metres plus the
// run's metadata as root attributes) and an XDMF sidecar for ParaView. The
// file contract is documented in README.md; keep the two in step.
#include <climits>
#include <cstdint>
#include <locale>
#include <sstream>
#include <string>
#include <vector>

#include "io/atomic_file.h"
#include "io/formats.h"
#include "io/hdf5_util.h"
#include "io/io.h"

namespace erg::io {

// ---- shared with the parallel writer (formats.h) ------------------------------

void detail::check_grid(const std::string& path, int nx, int ny) {
  if (nx <= 0 || ny <= 0) {
    fail(path, "invalid grid " + std::to_string(nx) + " x " + std::to_string(ny) +
                   " (nx and ny must be positive)");
  }
}

std::vector<detail::SnapshotLayer> detail::snapshot_layers(const SnapshotFields& f,
                                                           bool with_airborne, bool with_shadow,
                                                           bool with_obstacles) {
  std::vector<SnapshotLayer> layers = {{"bedrock", f.bedrock, 1},
                                       {"sand", f.sand, 1},
                                       {"vegetation", f.vegetation, 1},
                                       {"wind", f.wind, 2}};
  if (with_airborne) layers.push_back({"airborne", f.airborne, 1});
  if (with_shadow) layers.push_back({"shadow", f.shadow, 1});
  if (with_obstacles) layers.push_back({"obstacles", f.obstacles, 1});
  return layers;
}

void detail::write_snapshot_attrs(hid_t fid, const SnapshotMeta& meta, const std::string& path) {
  write_attr_i64(fid, "step", meta.step, path);
  write_attr_f64(fid, "time_days", meta.time_days, path);
  write_attr_f64(fid, "cell_size_m", meta.cell_size_m, path);
  write_attr_i64(fid, "nx", meta.nx, path);
  write_attr_i64(fid, "ny", meta.ny, path);
  write_attr_str(fid, "job_spec", meta.job_spec_json, path);
  write_attr_str(fid, "erg_version", meta.erg_version, path);
  write_attr_f64(fid, "unit_m", meta.unit_m, path);
  write_attr_str(fid, "sand_units_total", meta.sand_units_total, path);
  write_attr_str(fid, "bedrock_units_total", meta.bedrock_units_total, path);
  write_attr_str(fid, "airborne_units_total", meta.airborne_units_total, path);
  write_attr_u64(fid, "seed", meta.seed, path);
  write_attr_str(fid, "backend", meta.backend, path);
  // Fixed by the model: the domain is a torus and all lengths are metres.
  write_attr_str(fid, "periodic", "xy", path);
  write_attr_str(fid, "units", "m", path);
}

namespace {

using detail::AtomicFile;
using detail::check_grid;
using detail::fail;
using detail::Hid;

// Reads nx or ny back, rejecting values that do not fit the int of the API.
int read_extent(hid_t file, const char* name, const std::string& path) {
  std::int64_t v = detail::read_attr_i64(file, name, path);
  if (v <= 0 || v > INT_MAX) {
    fail(path, std::string("attribute '") + name + "' = " + std::to_string(v) + " is out of range");
  }
  return static_cast<int>(v);
}

// Numbers in the XDMF text: locale-independent, and doubles with enough
// digits to round-trip exactly.
std::ostringstream xml_stream() {
  std::ostringstream os;
  os.imbue(std::locale::classic());
  os.precision(17);
  return os;
}

// The five XML special characters, for names and paths placed in attributes
// or text. File names with '&' or '<' are rare but legal.
std::string xml_escape(const std::string& s) {
  std::string out;
  out.reserve(s.size());
  for (char c : s) {
    switch (c) {
      case '&':
        out += "&amp;";
        break;
      case '<':
        out += "&lt;";
        break;
      case '>':
        out += "&gt;";
        break;
      case '"':
        out += "&quot;";
        break;
      case '\'':
        out += "&apos;";
        break;
      default:
        out += c;
    }
  }
  return out;
}

}  // namespace

void write_snapshot(const std::string& path, const SnapshotMeta& meta, const SnapshotFields& f) {
  // Argument errors first, before anything touches the disk.
  check_grid(path, meta.nx, meta.ny);
  if (!f.bedrock || !f.sand || !f.vegetation || !f.wind) {
    fail(path, "snapshot needs bedrock, sand, vegetation and wind fields (got a null pointer)");
  }

  AtomicFile out(path);
  std::vector<char> image;
  {
    detail::Hdf5Guard guard;
    Hid file = detail::create_hdf5_in_memory(out);
    const hid_t fid = file.get();
    const hsize_t ny = static_cast<hsize_t>(meta.ny), nx = static_cast<hsize_t>(meta.nx);
    for (const detail::SnapshotLayer& l :
         detail::snapshot_layers(f, f.airborne, f.shadow, f.obstacles)) {
      std::vector<hsize_t> dims = {ny, nx};
      if (l.components > 1) dims.push_back(static_cast<hsize_t>(l.components));
      detail::write_dataset(fid, l.name, H5T_IEEE_F32LE, H5T_NATIVE_FLOAT, dims, l.data,
                            detail::kSnapshotDeflate, path);
    }
    detail::write_snapshot_attrs(fid, meta, path);

    image = detail::take_hdf5_image(file, path);
  }
  out.write_whole(image.data(), image.size());
  out.commit();
}

void write_xdmf(const std::string& xdmf_path, const std::string& h5_name, const SnapshotMeta& meta,
                bool has_airborne, bool has_shadow, bool has_obstacles) {
  check_grid(xdmf_path, meta.nx, meta.ny);
  if (h5_name.empty()) fail(xdmf_path, "XDMF needs the name of its HDF5 file");

  // XDMF orders dimensions slowest first ("ny nx"), like the HDF5 datasets.
  // A CoRectMesh topology counts nodes, so cell-centred [ny][nx] data sits on
  // a mesh of (ny+1) x (nx+1) nodes; cells are square with side cell_size_m.
  std::ostringstream os = xml_stream();
  const std::string cells = std::to_string(meta.ny) + " " + std::to_string(meta.nx);
  const std::string nodes = std::to_string(meta.ny + 1) + " " + std::to_string(meta.nx + 1);
  const std::string h5 = xml_escape(h5_name);
  auto data_item = [&](const std::string& dataset, const std::string& dims, const char* indent) {
    os << indent << "<DataItem Dimensions=\"" << dims
       << "\" NumberType=\"Float\" Precision=\"4\" Format=\"HDF\">" << h5 << ":/" << dataset
       << "</DataItem>\n";
  };
  auto scalar = [&](const std::string& name) {
    os << "      <Attribute Name=\"" << name << "\" AttributeType=\"Scalar\" Center=\"Cell\">\n";
    data_item(name, cells, "        ");
    os << "      </Attribute>\n";
  };

  os << "<?xml version=\"1.0\" ?>\n"
     << "<!DOCTYPE Xdmf SYSTEM \"Xdmf.dtd\" []>\n"
     << "<Xdmf Version=\"3.0\" xmlns:xi=\"http://www.w3.org/2001/XInclude\">\n"
     << "  <Domain>\n"
     << "    <Grid Name=\"erg\" GridType=\"Uniform\">\n"
     << "      <Time Value=\"" << meta.time_days << "\"/>\n"
     << "      <Topology TopologyType=\"2DCoRectMesh\" Dimensions=\"" << nodes << "\"/>\n"
     << "      <Geometry GeometryType=\"ORIGIN_DXDY\">\n"
     << "        <DataItem Name=\"Origin\" Dimensions=\"2\" NumberType=\"Float\" Precision=\"8\" "
        "Format=\"XML\">0 0</DataItem>\n"
     << "        <DataItem Name=\"Spacing\" Dimensions=\"2\" NumberType=\"Float\" Precision=\"8\" "
        "Format=\"XML\">"
     << meta.cell_size_m << " " << meta.cell_size_m << "</DataItem>\n"
     << "      </Geometry>\n";
  scalar("bedrock");
  scalar("sand");
  scalar("vegetation");
  // Surface height = bedrock + sand, computed by the reader (an XDMF
  // Function item) rather than stored twice.
  os << "      <Attribute Name=\"height\" AttributeType=\"Scalar\" Center=\"Cell\">\n"
     << "        <DataItem ItemType=\"Function\" Function=\"$0 + $1\" Dimensions=\"" << cells
     << "\">\n";
  data_item("bedrock", cells, "          ");
  data_item("sand", cells, "          ");
  os << "        </DataItem>\n"
     << "      </Attribute>\n";
  // Two components (east, north): ParaView colours by it and computes with
  // it; for arrow glyphs extend it to 3-D with a Calculator.
  os << "      <Attribute Name=\"wind\" AttributeType=\"Vector\" Center=\"Cell\">\n";
  data_item("wind", cells + " 2", "        ");
  os << "      </Attribute>\n";
  if (has_airborne) scalar("airborne");
  if (has_shadow) scalar("shadow");
  if (has_obstacles) scalar("obstacles");
  os << "    </Grid>\n"
     << "  </Domain>\n"
     << "</Xdmf>\n";

  const std::string text = os.str();
  AtomicFile out(xdmf_path);
  out.write_whole(text.data(), text.size());
  out.commit();
}

Snapshot read_snapshot(const std::string& path, bool terrain_only) {
  detail::Hdf5Guard guard;
  Hid file = detail::open_hdf5_readonly(path, "snapshot");
  const hid_t fid = file.get();

  Snapshot s;
  SnapshotMeta& m = s.meta;
  m.nx = read_extent(fid, "nx", path);
  m.ny = read_extent(fid, "ny", path);
  m.step = detail::read_attr_i64(fid, "step", path);
  m.time_days = detail::read_attr_f64(fid, "time_days", path);
  m.cell_size_m = detail::read_attr_f64(fid, "cell_size_m", path);
  m.job_spec_json = detail::read_attr_str(fid, "job_spec", path);
  m.erg_version = detail::read_attr_str(fid, "erg_version", path);
  m.unit_m = detail::read_attr_f64(fid, "unit_m", path);
  m.sand_units_total = detail::read_attr_str(fid, "sand_units_total", path);
  m.bedrock_units_total = detail::read_attr_str(fid, "bedrock_units_total", path);
  m.airborne_units_total = detail::read_attr_str(fid, "airborne_units_total", path);
  m.seed = detail::read_attr_u64(fid, "seed", path);
  m.backend = detail::read_attr_str(fid, "backend", path);

  const hsize_t ny = static_cast<hsize_t>(m.ny), nx = static_cast<hsize_t>(m.nx);
  const std::vector<hsize_t> grid = {ny, nx};
  auto layer = [&](const char* name, const std::vector<hsize_t>& dims) {
    return detail::read_dataset<float>(fid, name, H5T_NATIVE_FLOAT, dims, path);
  };
  s.bedrock = layer("bedrock", grid);
  s.sand = layer("sand", grid);
  s.vegetation = layer("vegetation", grid);
  if (terrain_only) return s;
  s.wind = layer("wind", {ny, nx, 2});
  if (detail::link_exists(fid, "airborne")) s.airborne = layer("airborne", grid);
  if (detail::link_exists(fid, "shadow")) s.shadow = layer("shadow", grid);
  if (detail::link_exists(fid, "obstacles")) s.obstacles = layer("obstacles", grid);
  return s;
}

}  // namespace erg::io
