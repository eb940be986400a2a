// SPDX-License-Identifier: Apache-2.0
// Snapshots and their XDMF sidecar: exact round trip of every dataset and
// attribute, the file contract as an independent reader (h5py) sees it, read
// errors, and a well-formed XDMF that points at the right datasets.
#include <gtest/gtest.h>
#include <hdf5.h>

#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <limits>
#include <sstream>
#include <string>
#include <vector>

#include "io/io.h"
#include "test_util.h"

namespace erg::io {
namespace {

using testing::read_bytes;
using testing::TempDir;

// A snapshot whose values are all exact in float32, so that any reader can
// compare them with ==. Non-square and not a multiple of the chunk size.
struct Sample {
  static constexpr int kNx = 37, kNy = 23;
  SnapshotMeta meta;
  std::vector<float> bedrock, sand, vegetation, wind, airborne, shadow;

  Sample() {
    meta.step = 1234567890123;
    meta.time_days = 12.75;
    meta.cell_size_m = 0.5;
    meta.nx = kNx;
    meta.ny = kNy;
    meta.job_spec_json =
        "{\"name\": \"test \xc3\xbc\", \"grid\": {\"nx\": 37},\n \"quote\": \"\\\"\"}";
    meta.erg_version = "0.1.0";
    meta.unit_m = 1.0 / 4294967296.0;
    meta.sand_units_total = "123456789012345678901234567890";
    meta.bedrock_units_total = "-42";
    meta.airborne_units_total = "0";
    meta.seed = std::numeric_limits<std::uint64_t>::max() - 58;  // above 2^63: must stay unsigned
    meta.backend = "cpu";
    for (int y = 0; y < kNy; ++y) {
      for (int x = 0; x < kNx; ++x) {
        bedrock.push_back(static_cast<float>(y * 100 + x) + 0.25f);
        sand.push_back(static_cast<float>((x * 7 + y * 3) % 11) * 0.5f);
        vegetation.push_back(static_cast<float>((x + y) % 5) / 4.0f);
        wind.push_back(static_cast<float>(x) - 18.5f);
        wind.push_back(static_cast<float>(y) * 0.125f - 1.0f);
        airborne.push_back(static_cast<float>(x) / 1024.0f);
        shadow.push_back(static_cast<float>(x % 2));
      }
    }
  }

  SnapshotFields fields(bool optional) const {
    SnapshotFields f;
    f[erg::fields::kBedrock].data = bedrock.data();
    f[erg::fields::kSand].data = sand.data();
    f[erg::fields::kVegetation].data = vegetation.data();
    f[erg::fields::kWindX] = {wind.data(), 2, 0};
    f[erg::fields::kWindY] = {wind.data(), 2, 1};
    if (optional) {
      f[erg::fields::kAirborne].data = airborne.data();
      f[erg::fields::kShadow].data = shadow.data();
    }
    return f;
  }
};

void expect_same_bits(const std::vector<float>& got, const std::vector<float>& want,
                      const char* name) {
  ASSERT_EQ(got.size(), want.size()) << name;
  EXPECT_EQ(0, std::memcmp(got.data(), want.data(), want.size() * sizeof(float))) << name;
}

TEST(Snapshot, RoundTripsEveryDatasetAndAttribute) {
  TempDir dir;
  Sample s;
  const std::string path = dir.file("snap.h5");
  write_snapshot(path, s.meta, s.fields(true));

  Snapshot r = read_snapshot(path);
  EXPECT_EQ(r.meta.step, s.meta.step);
  EXPECT_EQ(r.meta.time_days, s.meta.time_days);
  EXPECT_EQ(r.meta.cell_size_m, s.meta.cell_size_m);
  EXPECT_EQ(r.meta.nx, Sample::kNx);
  EXPECT_EQ(r.meta.ny, Sample::kNy);
  EXPECT_EQ(r.meta.job_spec_json, s.meta.job_spec_json);
  EXPECT_EQ(r.meta.erg_version, s.meta.erg_version);
  EXPECT_EQ(r.meta.unit_m, s.meta.unit_m);
  EXPECT_EQ(r.meta.sand_units_total, s.meta.sand_units_total);
  EXPECT_EQ(r.meta.bedrock_units_total, s.meta.bedrock_units_total);
  EXPECT_EQ(r.meta.airborne_units_total, s.meta.airborne_units_total);
  EXPECT_EQ(r.meta.seed, s.meta.seed);
  EXPECT_EQ(r.meta.backend, s.meta.backend);
  expect_same_bits(r[erg::fields::kBedrock], s.bedrock, "bedrock");
  expect_same_bits(r[erg::fields::kSand], s.sand, "sand");
  expect_same_bits(r[erg::fields::kVegetation], s.vegetation, "vegetation");
  expect_same_bits(r.wind, s.wind, "wind");
  expect_same_bits(r[erg::fields::kAirborne], s.airborne, "airborne");
  expect_same_bits(r[erg::fields::kShadow], s.shadow, "shadow");

  // Only the snapshot is left in the directory: no temporary survives.
  EXPECT_EQ(dir.entries(), std::set<std::string>{"snap.h5"});

  // The terrain alone (previews of tiled runs): the same three layers.
  const Snapshot t = read_snapshot(path, /*terrain_only=*/true);
  EXPECT_EQ(t.meta.step, s.meta.step);
  expect_same_bits(t[erg::fields::kBedrock], s.bedrock, "terrain bedrock");
  expect_same_bits(t[erg::fields::kSand], s.sand, "terrain sand");
  expect_same_bits(t[erg::fields::kVegetation], s.vegetation, "terrain vegetation");
  EXPECT_TRUE(t.wind.empty() && t[erg::fields::kAirborne].empty() &&
              t[erg::fields::kShadow].empty());
}

// A string attribute of an HDF5 object (variable or fixed length), or "".
std::string string_attr(hid_t obj, const char* name) {
  if (H5Aexists(obj, name) <= 0) return "";
  const hid_t a = H5Aopen(obj, name, H5P_DEFAULT);
  const hid_t type = H5Aget_type(a);
  std::string out;
  if (H5Tis_variable_str(type) > 0) {
    char* v = nullptr;
    const hid_t mem = H5Tget_native_type(type, H5T_DIR_DEFAULT);
    if (H5Aread(a, mem, &v) >= 0 && v) out = v;
    if (v) H5free_memory(v);
    H5Tclose(mem);
  } else {
    out.assign(H5Tget_size(type), '\0');
    H5Aread(a, type, out.data());
    out = out.c_str();
  }
  H5Tclose(type);
  H5Aclose(a);
  return out;
}

herr_t collect_name(hid_t, const char* name, const H5L_info_t*, void* names) {
  static_cast<std::vector<std::string>*>(names)->push_back(name);
  return 0;
}

// The registry (core/fields.h) drives the snapshot: given every snapshot
// layer of the registry, the file holds exactly those as [1][ny][nx] float32
// datasets, in the registry's order of positions, each with the registry's
// unit and long name, and the XDMF sidecar shows each of them (the wind's
// components as one vector).
TEST(Snapshot, TheFieldRegistryDrivesTheLayersAndTheirUnits) {
  TempDir dir;
  Sample s;
  const std::size_t n = static_cast<std::size_t>(Sample::kNx) * Sample::kNy;
  std::vector<std::vector<float>> values;
  SnapshotFields f;
  for (const fields::Id id : fields::snapshot_order()) {
    values.emplace_back(n, static_cast<float>(id) + 0.5f);
    f[id].data = values.back().data();
  }
  const std::string path = dir.file("all.h5");
  write_snapshot(path, s.meta, f);
  const std::vector<fields::Id> written = snapshot_layer_ids(f);
  ASSERT_EQ(written.size(), static_cast<std::size_t>(fields::kSnapshotLayers));
  write_xdmf(dir.file("all.xdmf"), "all.h5", s.meta, written);

  const hid_t file = H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  ASSERT_GE(file, 0);
  std::vector<std::string> names;
  hsize_t idx = 0;
  H5Literate(file, H5_INDEX_NAME, H5_ITER_INC, &idx, collect_name, &names);
  std::vector<std::string> layers;
  for (const std::string& name : names) {
    if (name == "time" || name == "x" || name == "y") continue;
    layers.push_back(name);
    const fields::Id id = fields::by_name(name);
    ASSERT_NE(id, fields::kCount) << name << " is in the file but not in the registry";
    EXPECT_TRUE(fields::in_snapshots(id)) << name;
  }
  EXPECT_EQ(layers.size(), static_cast<std::size_t>(fields::kSnapshotLayers));
  const std::string xml = read_bytes(dir.file("all.xdmf"));
  for (const fields::Id id : fields::snapshot_order()) {
    const fields::Info& info = fields::info(id);
    const hid_t d = H5Dopen2(file, info.name, H5P_DEFAULT);
    ASSERT_GE(d, 0) << info.name;
    const hid_t space = H5Dget_space(d);
    hsize_t dims[3] = {};
    EXPECT_EQ(H5Sget_simple_extent_ndims(space), 3) << info.name;
    H5Sget_simple_extent_dims(space, dims, nullptr);
    EXPECT_EQ(dims[1], static_cast<hsize_t>(Sample::kNy)) << info.name;
    EXPECT_EQ(dims[2], static_cast<hsize_t>(Sample::kNx)) << info.name;
    std::vector<float> got(n);
    H5Dread(d, H5T_NATIVE_FLOAT, H5S_ALL, H5S_ALL, H5P_DEFAULT, got.data());
    EXPECT_EQ(got[n / 2], static_cast<float>(id) + 0.5f) << info.name;
    EXPECT_EQ(string_attr(d, "units"), info.unit) << info.name;
    EXPECT_EQ(string_attr(d, "long_name"), info.snapshot.long_name) << info.name;
    EXPECT_EQ(string_attr(d, "standard_name"), info.snapshot.standard_name) << info.name;
    H5Sclose(space);
    H5Dclose(d);
    const std::string shown = id == fields::kWindX || id == fields::kWindY ? "wind" : info.name;
    EXPECT_NE(xml.find("Name=\"" + shown + "\""), std::string::npos) << info.name;
    EXPECT_NE(xml.find("all.h5:/" + std::string(info.name) + "<"), std::string::npos) << info.name;
  }
  H5Fclose(file);
  // The new diagnostic is one of them, in metres.
  EXPECT_TRUE(fields::in_snapshots(fields::kDeposited));
  EXPECT_STREQ(fields::info(fields::kDeposited).unit, "m");
}

TEST(Snapshot, OptionalLayersAbsentReadBackEmpty) {
  TempDir dir;
  Sample s;
  write_snapshot(dir.file("snap.h5"), s.meta, s.fields(false));
  Snapshot r = read_snapshot(dir.file("snap.h5"));
  EXPECT_TRUE(r[erg::fields::kAirborne].empty());
  EXPECT_TRUE(r[erg::fields::kShadow].empty());
  expect_same_bits(r[erg::fields::kBedrock], s.bedrock, "bedrock");
}

TEST(Snapshot, ManyChunksRoundTrip) {
  // 300 x 520 spans 2 x 3 chunks of 256 x 256, including partial ones.
  TempDir dir;
  SnapshotMeta meta;
  meta.nx = 520;
  meta.ny = 300;
  const std::size_t n = 520 * 300;
  std::vector<float> a(n), b(n), v(n, 0.5f), w(2 * n);
  for (std::size_t i = 0; i < n; ++i) {
    a[i] = static_cast<float>(i) * 0.001f;
    b[i] = static_cast<float>(i % 977) - 3.0f;
  }
  for (std::size_t i = 0; i < 2 * n; ++i) w[i] = static_cast<float>(i % 13);
  SnapshotFields f;
  f[erg::fields::kBedrock].data = a.data();
  f[erg::fields::kSand].data = b.data();
  f[erg::fields::kVegetation].data = v.data();
  f[erg::fields::kWindX] = {w.data(), 2, 0};
  f[erg::fields::kWindY] = {w.data(), 2, 1};
  write_snapshot(dir.file("big.h5"), meta, f);
  Snapshot r = read_snapshot(dir.file("big.h5"));
  expect_same_bits(r[erg::fields::kBedrock], a, "bedrock");
  expect_same_bits(r[erg::fields::kSand], b, "sand");
  expect_same_bits(r.wind, w, "wind");
}

// The file contract as an independent tool sees it: dtypes, shapes, chunks,
// filters, attribute types (str, not bytes; int64; uint64) and values.
TEST(Snapshot, ReadableByH5py) {
  if (std::system("/usr/bin/python3 -c 'import h5py' >/dev/null 2>&1") != 0) {
    GTEST_SKIP() << "/usr/bin/python3 with h5py is not available";
  }
  TempDir dir;
  Sample s;
  const std::string path = dir.file("snap.h5");
  write_snapshot(path, s.meta, s.fields(true));

  const std::string script = R"PY(
import json, sys
import h5py
import numpy as np

def check(cond, what):
    if not cond:
        print("FAIL:", what)
        sys.exit(1)

nx, ny = 37, 23
f = h5py.File(sys.argv[1], "r")
x = np.arange(nx)[None, :]
y = np.arange(ny)[:, None]
expected = {
    "bedrock": (y * 100 + x) + 0.25,
    "sand": ((x * 7 + y * 3) % 11) * 0.5,
    "vegetation": ((x + y) % 5) / 4.0,
    "airborne": np.broadcast_to(x / 1024.0, (ny, nx)),
    "shadow": np.broadcast_to(x % 2, (ny, nx)),
}
expected["wind_x"] = np.broadcast_to(x - 18.5, (ny, nx))
expected["wind_y"] = np.broadcast_to(y * 0.125 - 1.0, (ny, nx))
units = {"bedrock": "m", "sand": "m", "vegetation": "1", "airborne": "m", "shadow": "1",
         "wind_x": "m s-1", "wind_y": "m s-1"}
standard = {"vegetation": "vegetation_area_fraction", "wind_x": "eastward_wind",
            "wind_y": "northward_wind"}
for name, want in expected.items():
    d = f[name]
    check(d.dtype == np.float32, name + " dtype " + str(d.dtype))
    check(d.shape == (1, ny, nx), name + " shape " + str(d.shape))
    check(d.chunks == (1, ny, nx), name + " chunks " + str(d.chunks))
    check(d.compression == "gzip" and d.compression_opts == 4, name + " compression")
    check(d.shuffle, name + " shuffle")
    check(np.array_equal(d[0], want.astype(np.float32)), name + " values")
    # netCDF-4 dimensions: the coordinate datasets attached as dimension scales.
    check([d.dims[k][0].name for k in range(3)] == ["/time", "/y", "/x"], name + " dims")
    check(d.attrs["units"] == units[name], name + " units " + repr(d.attrs["units"]))
    check(isinstance(d.attrs["long_name"], str) and d.attrs["long_name"], name + " long_name")
    check(d.attrs.get("standard_name") == standard.get(name), name + " standard_name")
check("wind" not in f, "no interleaved /wind")
for name, n, values in (("x", nx, (np.arange(nx) + 0.5) * 0.5),
                        ("y", ny, (np.arange(ny) + 0.5) * 0.5), ("time", 1, [12.75])):
    c = f[name]
    check(c.dtype == np.float64 and c.shape == (n,), name + " shape")
    check(np.array_equal(c[...], values), name + " values " + repr(c[:4]))
    check(h5py.h5ds.is_scale(c.id), name + " is a dimension scale")
    check(c.attrs["axis"] == {"x": "X", "y": "Y", "time": "T"}[name], name + " axis")
check(f["x"].attrs["units"] == "m" and f["time"].attrs["units"] == "day", "coordinate units")
check(f.attrs["Conventions"] == "CF-1.10", "Conventions")

a = f.attrs
def typed(name, value, dtype):
    check(a[name] == value, name + " value " + repr(a[name]))
    check(np.asarray(a[name]).dtype == dtype, name + " dtype " + str(np.asarray(a[name]).dtype))
def text(name, value):
    check(isinstance(a[name], str), name + " is " + str(type(a[name])))
    check(a[name] == value, name + " value " + repr(a[name]))
typed("step", 1234567890123, np.int64)
typed("time_days", 12.75, np.float64)
typed("cell_size_m", 0.5, np.float64)
typed("nx", nx, np.int64)
typed("ny", ny, np.int64)
typed("unit_m", 2.0 ** -32, np.float64)
typed("seed", 2 ** 64 - 59, np.uint64)
check(json.loads(a["job_spec"])["name"] == "test \u00fc", "job_spec JSON")
text("erg_version", "0.1.0")
text("sand_units_total", "123456789012345678901234567890")
text("bedrock_units_total", "-42")
text("airborne_units_total", "0")
text("backend", "cpu")
text("periodic", "xy")
text("units", "m")
print("OK")
)PY";
  testing::write_bytes(dir.file("check.py"), script);
  const std::string out = dir.file("out.txt");
  const std::string cmd =
      "/usr/bin/python3 " + dir.file("check.py") + " " + path + " >" + out + " 2>&1";
  const int status = std::system(cmd.c_str());
  const std::string output = read_bytes(out);
  EXPECT_EQ(status, 0) << output;
  EXPECT_EQ(output, "OK\n");
}

TEST(Snapshot, MissingFieldIsRejectedBeforeWriting) {
  TempDir dir;
  Sample s;
  SnapshotFields f = s.fields(false);
  f[erg::fields::kWindX].data = nullptr;
  EXPECT_THROW(write_snapshot(dir.file("snap.h5"), s.meta, f), IoError);
  EXPECT_TRUE(dir.entries().empty());
}

TEST(Snapshot, ReadErrorsNameTheFileAndCause) {
  TempDir dir;
  auto message = [](const std::string& path) {
    try {
      read_snapshot(path);
    } catch (const IoError& e) {
      return std::string(e.what());
    }
    return std::string("no IoError");
  };
  const std::string missing = dir.file("missing.h5");
  std::string m = message(missing);
  EXPECT_NE(m.find(missing), std::string::npos) << m;
  EXPECT_NE(m.find("No such file"), std::string::npos) << m;

  const std::string text = dir.file("text.h5");
  testing::write_bytes(text, "this is not HDF5\n");
  m = message(text);
  EXPECT_NE(m.find(text), std::string::npos) << m;
  EXPECT_NE(m.find("not an HDF5 file"), std::string::npos) << m;

  // A snapshot cut in half (what a non-atomic writer would leave behind).
  Sample s;
  const std::string good = dir.file("good.h5");
  write_snapshot(good, s.meta, s.fields(true));
  const std::string bytes = read_bytes(good);
  const std::string cut = dir.file("cut.h5");
  testing::write_bytes(cut, bytes.substr(0, bytes.size() / 2));
  m = message(cut);
  EXPECT_NE(m.find(cut), std::string::npos) << m;
}

TEST(Snapshot, MissingAttributeIsNamed) {
  TempDir dir;
  Sample s;
  const std::string path = dir.file("snap.h5");
  write_snapshot(path, s.meta, s.fields(false));
  hid_t f = H5Fopen(path.c_str(), H5F_ACC_RDWR, H5P_DEFAULT);
  ASSERT_GE(f, 0);
  ASSERT_GE(H5Adelete(f, "seed"), 0);
  H5Fclose(f);
  try {
    read_snapshot(path);
    FAIL() << "expected IoError";
  } catch (const IoError& e) {
    EXPECT_NE(std::string(e.what()).find("'seed'"), std::string::npos) << e.what();
  }
}

// ---- XDMF ---------------------------------------------------------------------

// Minimal XML well-formedness: every element closed in order, one root.
// Returns the sequence of start tags (with their attributes) in document order.
std::vector<std::string> parse_tags(const std::string& xml, std::string* error) {
  std::vector<std::string> tags, stack;
  std::size_t i = 0;
  int roots = 0;
  while ((i = xml.find('<', i)) != std::string::npos) {
    std::size_t end = xml.find('>', i);
    if (end == std::string::npos) {
      *error = "unterminated tag";
      return {};
    }
    std::string tag = xml.substr(i + 1, end - i - 1);
    i = end + 1;
    if (tag.empty()) {
      *error = "empty tag";
      return {};
    }
    if (tag[0] == '?' || tag[0] == '!') continue;  // declaration, DOCTYPE, comment
    if (tag[0] == '/') {
      std::string name = tag.substr(1);
      if (stack.empty() || stack.back() != name) {
        *error = "mismatched </" + name + ">";
        return {};
      }
      stack.pop_back();
      continue;
    }
    if (stack.empty()) ++roots;
    tags.push_back(tag);
    bool self_closing = tag.back() == '/';
    std::string name = tag.substr(0, tag.find_first_of(" \t\n/"));
    if (!self_closing) stack.push_back(name);
  }
  if (!stack.empty()) *error = "unclosed <" + stack.back() + ">";
  if (roots != 1) *error = "expected one root element, got " + std::to_string(roots);
  return tags;
}

TEST(Xdmf, IsWellFormedAndReferencesTheSnapshot) {
  TempDir dir;
  Sample s;
  const std::string xmf = dir.file("snap_000042.xmf");
  write_xdmf(xmf, "snap_000042.h5", s.meta,
             std::vector<erg::fields::Id>{erg::fields::kBedrock, erg::fields::kSand,
                                          erg::fields::kVegetation, erg::fields::kWindX,
                                          erg::fields::kWindY, erg::fields::kAirborne});
  const std::string xml = read_bytes(xmf);

  std::string error;
  std::vector<std::string> tags = parse_tags(xml, &error);
  ASSERT_EQ(error, "") << xml;
  ASSERT_FALSE(tags.empty());
  EXPECT_EQ(tags.front().rfind("Xdmf ", 0), 0u) << tags.front();

  // Each attribute is present, node-centred, and points at its dataset by a
  // path relative to the XDMF file.
  for (const char* name : {"bedrock", "sand", "vegetation", "wind", "height", "airborne"}) {
    EXPECT_NE(xml.find(std::string("<Attribute Name=\"") + name + "\""), std::string::npos) << name;
  }
  EXPECT_EQ(xml.find("Name=\"shadow\""), std::string::npos);
  EXPECT_EQ(xml.find("Center=\"Cell\""), std::string::npos);
  for (const char* ds : {"bedrock", "sand", "vegetation", "wind_x", "wind_y", "airborne"}) {
    EXPECT_NE(xml.find(std::string(">snap_000042.h5:/") + ds + "<"), std::string::npos) << ds;
  }
  EXPECT_NE(xml.find("AttributeType=\"Vector\""), std::string::npos);
  EXPECT_EQ(xml.find(dir.path().string()), std::string::npos) << "must not embed absolute paths";

  // Mesh (XDMF orders z y x): one layer of ny x nx nodes at the cell centres,
  // spacing the cell size; the data items are the [1][ny][nx] datasets, the
  // wind a 3-vector; time in days. (pvbatch checks what ParaView makes of it:
  // tests/paraview.)
  EXPECT_NE(xml.find("TopologyType=\"3DCoRectMesh\" Dimensions=\"1 23 37\""), std::string::npos);
  EXPECT_NE(xml.find(">0 0.25 0.25</DataItem>"), std::string::npos);
  EXPECT_NE(xml.find(">0.5 0.5 0.5</DataItem>"), std::string::npos);
  EXPECT_NE(xml.find("Dimensions=\"1 23 37 3\""), std::string::npos);
  EXPECT_NE(xml.find("<Time Value=\"12.75\"/>"), std::string::npos);

  // A real XML parser agrees, where one is installed.
  if (std::system("command -v xmllint >/dev/null 2>&1") == 0) {
    EXPECT_EQ(std::system(("xmllint --noout " + xmf).c_str()), 0);
  }
  EXPECT_EQ(dir.entries(), std::set<std::string>{"snap_000042.xmf"});
}

TEST(Xdmf, EscapesFileNamesAndKeepsFullTimePrecision) {
  TempDir dir;
  Sample s;
  s.meta.time_days = 0.1;  // not exact in binary: needs 17 digits to round-trip
  const std::string xmf = dir.file("a.xmf");
  write_xdmf(xmf, "run&co<1>.h5", s.meta,
             std::vector<erg::fields::Id>{erg::fields::kBedrock, erg::fields::kSand,
                                          erg::fields::kVegetation, erg::fields::kWindX,
                                          erg::fields::kWindY, erg::fields::kShadow});
  const std::string xml = read_bytes(xmf);
  std::string error;
  parse_tags(xml, &error);
  EXPECT_EQ(error, "");
  EXPECT_NE(xml.find(">run&amp;co&lt;1&gt;.h5:/shadow<"), std::string::npos) << xml;
  const std::size_t at = xml.find("<Time Value=\"");
  ASSERT_NE(at, std::string::npos);
  std::istringstream is(xml.substr(at + 13));
  double t = 0;
  is >> t;
  EXPECT_EQ(t, 0.1);
}

// DIR/run.xdmf: every snapshot's grid in step order (not name order), HDF5
// paths relative to DIR, inside one temporal collection; rewritten whole.
TEST(Xdmf, RunCollectsEverySnapshotInStepOrder) {
  TempDir dir;
  std::filesystem::create_directories(dir.file("snapshots"));
  Sample s;
  for (long long step : {20, 100000000, 5}) {
    s.meta.step = step;
    s.meta.time_days = static_cast<double>(step) * 0.5;
    const std::string name =
        "step_" + std::string(step < 100000000 ? 8 - std::to_string(step).size() : 0, '0') +
        std::to_string(step);
    write_xdmf(dir.file("snapshots/" + name + ".xdmf"), name + ".h5", s.meta,
               std::vector<erg::fields::Id>{erg::fields::kBedrock, erg::fields::kSand,
                                            erg::fields::kVegetation, erg::fields::kWindX,
                                            erg::fields::kWindY});
    write_run_xdmf(dir.path().string());
  }
  testing::write_bytes(dir.file("snapshots/notes.xdmf"), "not a snapshot");
  write_run_xdmf(dir.path().string());
  const std::string xml = read_bytes(dir.file("run.xdmf"));
  std::string error;
  parse_tags(xml, &error);
  ASSERT_EQ(error, "") << xml;
  EXPECT_NE(xml.find("GridType=\"Collection\" CollectionType=\"Temporal\""), std::string::npos);
  const std::size_t a = xml.find("<Time Value=\"2.5\"/>"), b = xml.find("<Time Value=\"10\"/>"),
                    c = xml.find("<Time Value=\"50000000\"/>");
  ASSERT_NE(a, std::string::npos) << xml;
  ASSERT_NE(b, std::string::npos);
  ASSERT_NE(c, std::string::npos);
  EXPECT_LT(a, b);
  EXPECT_LT(b, c);
  EXPECT_NE(xml.find(">snapshots/step_00000020.h5:/sand<"), std::string::npos);
  EXPECT_NE(xml.find(">snapshots/step_100000000.h5:/wind_y<"), std::string::npos);
  EXPECT_EQ(xml.find(">step_"), std::string::npos);
  EXPECT_EQ(xml.find("notes"), std::string::npos);
  std::size_t grids = 0;
  for (std::size_t k = xml.find("GridType=\"Uniform\""); k != std::string::npos;
       k = xml.find("GridType=\"Uniform\"", k + 1))
    ++grids;
  EXPECT_EQ(grids, 3u);
}

}  // namespace
}  // namespace erg::io
