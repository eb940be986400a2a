// SPDX-License-Identifier: Apache-2.0
// XDMF descriptions of snapshots for ParaView and VisIt: one sidecar per
// snapshot and DIR/run.xdmf, the temporal collection of a whole run.
//
// Layout, as ParaView 5.11's XDMF reader builds it: a 3DCoRectMesh of
// 1 x ny x nx nodes (XDMF lists dimensions, origin and spacing slowest first:
// z, y, x) becomes vtkImageData with dimensions (nx, ny, 1) in the X-Y plane,
// z = 0. The nodes are the cell centres ((i + 1/2) dx, (j + 1/2) dy), the x and
// y coordinates of the CF snapshot (cf.h), and the layers are node data, so
// "Warp By Scalar" on `height` lifts the terrain along +Z with no resampling.
// The wind is a 3-component vector (x, y, 0) for glyphs. tests/paraview
// checks bounds, arrays, ranges and times with pvbatch.
#include <algorithm>
#include <cctype>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <locale>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "core/fields.h"
#include "io/atomic_file.h"
#include "io/cf.h"
#include "io/formats.h"
#include "io/hdf5_util.h"
#include "io/io.h"

namespace erg::io {

namespace {

namespace fs = std::filesystem;
using detail::fail;

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

// What marks a grid of the current layout (a sidecar written by an older
// erg, in the Y-Z plane, is left out of run.xdmf).
constexpr const char* kTopology = "TopologyType=\"3DCoRectMesh\"";
constexpr const char* kHdfItem = "Format=\"HDF\">";

// The shape of a grid: nx x ny nodes `spacing_m` apart, the first at
// spacing_m / 2, with its datasets under `group` ("" or "overview/level_K/").
struct GridShape {
  long long nx = 0, ny = 0;
  double spacing_m = 1;
  std::string group;
};

// One <Grid>, its HDF5 paths relative to the XDMF file that holds it: the
// height, then `layers` (registry fields, in file order; wind_x and wind_y as
// one vector).
std::string grid_text(const std::string& name, const std::string& h5_ref, const SnapshotMeta& meta,
                      const GridShape& g, const std::vector<fields::Id>& layers) {
  std::ostringstream os = xml_stream();
  const std::string dims = "1 " + std::to_string(g.ny) + " " + std::to_string(g.nx);
  const std::string h5 = xml_escape(h5_ref);
  const double d = g.spacing_m;
  auto data_item = [&](const std::string& dataset, const char* indent) {
    os << indent << "<DataItem Dimensions=\"" << dims << "\" NumberType=\"Float\" Precision=\"4\" "
       << kHdfItem << h5 << ":/" << g.group << dataset << "</DataItem>\n";
  };
  auto scalar = [&](const std::string& dataset) {
    os << "      <Attribute Name=\"" << dataset << "\" AttributeType=\"Scalar\" Center=\"Node\">\n";
    data_item(dataset, "        ");
    os << "      </Attribute>\n";
  };
  os << "    <Grid Name=\"" << xml_escape(name) << "\" GridType=\"Uniform\">\n"
     << "      <Time Value=\"" << detail::snapshot_time_days(meta) << "\"/>\n"
     << "      <Topology " << kTopology << " Dimensions=\"" << dims << "\"/>\n"
     << "      <Geometry GeometryType=\"ORIGIN_DXDYDZ\">\n"
     << "        <DataItem Name=\"Origin\" Dimensions=\"3\" NumberType=\"Float\" Precision=\"8\" "
        "Format=\"XML\">0 "
     << d / 2 << " " << d / 2 << "</DataItem>\n"
     << "        <DataItem Name=\"Spacing\" Dimensions=\"3\" NumberType=\"Float\" Precision=\"8\" "
        "Format=\"XML\">"
     << d << " " << d << " " << d << "</DataItem>\n"
     << "      </Geometry>\n";
  // Surface height = bedrock + sand, computed by the reader (an XDMF
  // Function item) rather than stored twice; first, so that ParaView colours
  // and warps by it unless told otherwise.
  os << "      <Attribute Name=\"height\" AttributeType=\"Scalar\" Center=\"Node\">\n"
     << "        <DataItem ItemType=\"Function\" Function=\"$0 + $1\" Dimensions=\"" << dims
     << "\">\n";
  data_item("bedrock", "          ");
  data_item("sand", "          ");
  os << "        </DataItem>\n"
     << "      </Attribute>\n";
  for (const fields::Id id : layers) {
    if (id == fields::kWindY) continue;
    if (id != fields::kWindX) {
      scalar(fields::info(id).name);
      continue;
    }
    os << "      <Attribute Name=\"wind\" AttributeType=\"Vector\" Center=\"Node\">\n"
       << "        <DataItem ItemType=\"Function\" Function=\"JOIN($0, $1, 0 * $0)\" "
          "Dimensions=\""
       << dims << " 3\">\n";
    data_item(fields::info(fields::kWindX).name, "          ");
    data_item(fields::info(fields::kWindY).name, "          ");
    os << "        </DataItem>\n"
       << "      </Attribute>\n";
  }
  os << "    </Grid>\n";
  return os.str();
}

// One overview level's <Grid> (io.h OverviewPyramid): a node per block, on
// the level's regular spacing (2^level cells), with its three layers and the
// height. Where the domain is not a multiple of 2^level cells the last block
// of a row or column is partial: its mean is drawn at the regular spacing,
// not at the centre of its cells (the level's /x and /y have that).
std::string overview_grid_text(const std::string& name, const std::string& h5_ref,
                               const SnapshotMeta& meta, int level) {
  const long long s = 1LL << level;
  const GridShape g{(meta.nx + s - 1) / s, (meta.ny + s - 1) / s,
                    meta.cell_size_m * static_cast<double>(s),
                    "overview/level_" + std::to_string(level) + "/"};
  return grid_text(name, h5_ref, meta, g, {fields::kBedrock, fields::kSand, fields::kVegetation});
}

std::string document(const std::string& body) {
  return "<?xml version=\"1.0\" ?>\n"
         "<!DOCTYPE Xdmf SYSTEM \"Xdmf.dtd\" []>\n"
         "<Xdmf Version=\"3.0\" xmlns:xi=\"http://www.w3.org/2001/XInclude\">\n"
         "  <Domain>\n" +
         body +
         "  </Domain>\n"
         "</Xdmf>\n";
}

void write_text(const std::string& path, const std::string& text) {
  detail::AtomicFile out(path);
  out.write_whole(text.data(), text.size());
  out.commit();
}

// The step of "step_N" + suffix (".xdmf", ".overview.xdmf"), or -1.
long long step_of(const std::string& file, const std::string& suffix) {
  if (file.rfind("step_", 0) != 0 || file.size() <= 5 + suffix.size()) return -1;
  if (file.substr(file.size() - suffix.size()) != suffix) return -1;
  const std::string digits = file.substr(5, file.size() - 5 - suffix.size());
  if (digits.empty() || digits.size() > 18 ||
      !std::all_of(digits.begin(), digits.end(), [](unsigned char c) { return std::isdigit(c); }))
    return -1;
  return std::stoll(digits);
}

}  // namespace

void write_xdmf(const std::string& xdmf_path, const std::string& h5_name, const SnapshotMeta& meta,
                const std::vector<fields::Id>& layers) {
  detail::check_grid(xdmf_path, meta.nx, meta.ny);
  if (h5_name.empty()) fail(xdmf_path, "XDMF needs the name of its HDF5 file");
  std::string name = fs::path(h5_name).stem().string();
  write_text(xdmf_path, document(grid_text(name, h5_name, meta,
                                           {meta.nx, meta.ny, meta.cell_size_m, ""}, layers)));
}

void write_xdmf_for(const std::string& h5_path) {
  SnapshotMeta meta;
  std::vector<fields::Id> layers;
  bool has_overview = false;
  {
    detail::Hdf5Guard guard;
    detail::Hid file = detail::open_hdf5_readonly(h5_path, "snapshot");
    const hid_t fid = file.get();
    meta.nx = static_cast<int>(detail::read_attr_i64(fid, "nx", h5_path));
    meta.ny = static_cast<int>(detail::read_attr_i64(fid, "ny", h5_path));
    meta.step = detail::read_attr_i64(fid, "step", h5_path);
    meta.time_days = detail::read_attr_f64(fid, "time_days", h5_path);
    meta.cell_size_m = detail::read_attr_f64(fid, "cell_size_m", h5_path);
    if (!detail::link_exists(fid, "wind_x")) {
      fail(h5_path, "snapshot has no /wind_x: written by an erg older than the CF layout");
    }
    for (const fields::Id id : fields::snapshot_order())
      if (detail::link_exists(fid, fields::info(id).name)) layers.push_back(id);
    has_overview = detail::link_exists(fid, "overview");
  }
  const fs::path p(h5_path);
  write_xdmf(fs::path(p).replace_extension(".xdmf").string(), p.filename().string(), meta, layers);
  if (const int level = overview_xdmf_level(meta.nx, meta.ny); has_overview && level > 0)
    write_overview_xdmf(fs::path(p).replace_extension(".overview.xdmf").string(),
                        p.filename().string(), meta, level);
}

void write_overview_xdmf(const std::string& xdmf_path, const std::string& h5_name,
                         const SnapshotMeta& meta, int level) {
  detail::check_grid(xdmf_path, meta.nx, meta.ny);
  if (h5_name.empty()) fail(xdmf_path, "XDMF needs the name of its HDF5 file");
  if (level < 1 || level > overview_levels(meta.nx, meta.ny))
    fail(xdmf_path, "no overview level " + std::to_string(level) + " in a grid of " +
                        std::to_string(meta.nx) + " x " + std::to_string(meta.ny) + " cells");
  const std::string name = fs::path(h5_name).stem().string() + "_level_" + std::to_string(level);
  write_text(xdmf_path, document(overview_grid_text(name, h5_name, meta, level)));
}

int overview_xdmf_level(int nx, int ny) {
  return overview_levels(nx, ny) == 0 ? 0 : std::max(1, overview_level_for(nx, ny, kPreviewMaxPx));
}

namespace {
// DIR/`out`: the temporal collection of every DIR/snapshots/step_N`suffix`.
void write_collection(const std::string& dir, const std::string& suffix, const std::string& out) {
  const fs::path snapshots = fs::path(dir) / "snapshots";
  std::vector<std::pair<long long, fs::path>> sidecars;
  std::error_code ec;
  for (fs::directory_iterator it(snapshots, ec), end; !ec && it != end; it.increment(ec)) {
    const long long step = step_of(it->path().filename().string(), suffix);
    if (step >= 0) sidecars.emplace_back(step, it->path());
  }
  if (ec) detail::fail_errno(snapshots.string(), "cannot list snapshots", ec.value());
  std::sort(sidecars.begin(), sidecars.end());

  std::string grids;
  for (const auto& [step, path] : sidecars) {
    std::ifstream in(path, std::ios::binary);
    const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    const std::size_t begin = text.find("    <Grid ");
    const std::size_t end = text.rfind("</Grid>");
    // A sidecar being replaced right now is read whole or not at all (it is
    // renamed into place); one of another layout is skipped.
    if (begin == std::string::npos || end == std::string::npos || end < begin ||
        text.find(kTopology) == std::string::npos)
      continue;
    std::string grid = text.substr(begin, end + 7 - begin) + "\n";
    // The sidecar's HDF5 paths are relative to snapshots/; run.xdmf is one
    // level up.
    const std::string marker = kHdfItem, prefix = "snapshots/";
    for (std::size_t k = grid.find(marker); k != std::string::npos;
         k = grid.find(marker, k + marker.size() + prefix.size()))
      grid.insert(k + marker.size(), prefix);
    // Indented one level more, inside the collection.
    std::istringstream lines(grid);
    for (std::string line; std::getline(lines, line);) grids += "  " + line + "\n";
  }
  const std::string body =
      "    <Grid Name=\"run\" GridType=\"Collection\" CollectionType=\"Temporal\">\n" + grids +
      "    </Grid>\n";
  write_text((fs::path(dir) / out).string(), document(body));
}
}  // namespace

void write_run_xdmf(const std::string& dir) {
  write_collection(dir, ".xdmf", "run.xdmf");
  write_collection(dir, ".overview.xdmf", "overview.xdmf");
}

}  // namespace erg::io
