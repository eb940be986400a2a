// SPDX-License-Identifier: Apache-2.0
// erg export: a snapshot of an output directory to GeoTIFF, 16-bit PNG,
// OpenEXR or OBJ (worker/export/).
#include <cstdio>
#include <iostream>
#include <string>
#include <vector>

#include "commands.h"
#include "export/export.h"

namespace erg::client {

namespace {

bool parse_int(const std::string& s, long long lo, long long hi, long long* out) {
  try {
    std::size_t used = 0;
    const long long v = std::stoll(s, &used);
    if (used != s.size() || v < lo || v > hi) return false;
    *out = v;
    return true;
  } catch (const std::exception&) {
    return false;
  }
}

}  // namespace

int cmd_export(const std::vector<std::string>& args) {
  using namespace erg::exporting;
  Request r;
  std::string format, layer = "height";
  auto bad = [](const std::string& what) {
    std::cerr << "erg: export: " << what << "\n" << usage_of("export");
    return 2;
  };
  for (std::size_t k = 0; k < args.size(); ++k) {
    const std::string& a = args[k];
    auto value = [&](std::string* v) {
      if (k + 1 >= args.size()) return false;
      *v = args[++k];
      return true;
    };
    std::string v;
    if (a == "--normals") {
      r.normals = true;
    } else if (a == "--no-amplify") {
      r.amplify = false;
    } else if (a.rfind("--", 0) == 0 && !value(&v)) {
      return bad(a + " needs a value");
    } else if (a == "--step") {
      if (!parse_int(v, 0, 1LL << 62, &r.step)) return bad("--step " + v + ": not a step number");
    } else if (a == "--format") {
      format = v;
    } else if (a == "--layer") {
      layer = v;
    } else if (a == "--out") {
      r.out = v;
    } else if (a == "--upsample") {
      long long k2 = 0;
      if (!parse_int(v, 1, 64, &k2)) return bad("--upsample " + v + ": allowed 1 to 64");
      r.upsample = static_cast<int>(k2);
    } else if (a == "--tiles") {
      int n = 0, m = 0;
      char x = 0, tail = 0;
      if (std::sscanf(v.c_str(), "%d%c%d%c", &n, &x, &m, &tail) != 3 || (x != 'x' && x != 'X') ||
          n < 1 || m < 1 || n > 256 || m > 256)
        return bad("--tiles " + v + ": expected NxM, 1 to 256 each (e.g. 4x4)");
      r.tiles_x = n;
      r.tiles_y = m;
      r.tiled = true;
    } else if (a == "--region") {
      Region g;
      char tail = 0;
      if (std::sscanf(v.c_str(), "%d,%d,%d,%d%c", &g.x0, &g.y0, &g.w, &g.h, &tail) != 4 ||
          g.w < 1 || g.h < 1)
        return bad("--region " + v + ": expected X0,Y0,W,H in cells with W, H >= 1");
      r.region = g;
    } else if (a.rfind("--", 0) == 0) {
      return bad("unknown option " + a);
    } else if (r.dir.empty()) {
      r.dir = a;
    } else {
      return bad("unexpected argument " + a);
    }
  }
  if (r.dir.empty()) return bad("name the output directory of a run");
  if (r.out.empty()) return bad("--out FILE is required");
  if (format == "geotiff")
    r.format = Format::kGeoTiff;
  else if (format == "png16")
    r.format = Format::kPng16;
  else if (format == "exr")
    r.format = Format::kExr;
  else if (format == "obj")
    r.format = Format::kObj;
  else
    return bad("--format '" + format + "': allowed geotiff, png16, exr, obj");
  if (layer == "height")
    r.layer = Layer::kHeight;
  else if (layer == "sand")
    r.layer = Layer::kSand;
  else if (layer == "bedrock")
    r.layer = Layer::kBedrock;
  else if (layer == "vegetation")
    r.layer = Layer::kVegetation;
  else
    return bad("--layer '" + layer + "': allowed height, sand, bedrock, vegetation");
  try {
    for (const auto& f : run_export(r)) std::cout << f << "\n";
    return 0;
  } catch (const std::exception& e) {
    std::cerr << "erg: export: " << e.what() << "\n";
    return 1;
  }
}

}  // namespace erg::client
