// SPDX-License-Identifier: Apache-2.0
// erg amplify: one region of a snapshot, upsampled and amplified with
// ripples and sand bumps [P19 6] (worker/amplify/), written as an HDF5
// heightmap plus a hillshaded PNG preview. Small on purpose: `erg export`
// takes the same steps.
#include "amplify/amplify.h"

#include <filesystem>
#include <iostream>
#include <string>
#include <vector>

#include "commands.h"
#include "io/io.h"
#include "io/run_files.h"

namespace erg::client {

namespace fs = std::filesystem;

namespace {

// The snapshot of DIR at `step` (-1: the latest); DIR may also be the file.
std::string snapshot_path(const std::string& dir, long long step) {
  if (fs::is_regular_file(dir)) return dir;
  const fs::path snaps = fs::path(dir) / "snapshots";
  if (step >= 0) {
    return (snaps / (step_name(step) + ".h5")).string();
  }
  std::string latest;
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(snaps, ec)) {
    const std::string n = e.path().filename().string();
    if (e.path().extension() == ".h5" && n.rfind("step_", 0) == 0 && n > latest) latest = n;
  }
  if (latest.empty()) throw std::runtime_error(snaps.string() + ": no snapshot step_*.h5");
  return (snaps / latest).string();
}

}  // namespace

int cmd_amplify(const std::vector<std::string>& args) {
  std::string dir, out, region_text;
  long long step = -1;
  int upsample = 4;
  try {
    for (size_t i = 0; i < args.size(); ++i) {
      const std::string& a = args[i];
      auto value = [&]() -> std::string {
        if (i + 1 >= args.size()) throw std::invalid_argument(a + " needs a value");
        return args[++i];
      };
      if (a == "--step") {
        step = std::stoll(value());
        if (step < 0) throw std::invalid_argument("--step must be >= 0");
      } else if (a == "--region") {
        region_text = value();
      } else if (a == "--upsample") {
        upsample = std::stoi(value());
        if (upsample < 1 || upsample > 64)
          throw std::invalid_argument("--upsample = " + std::to_string(upsample) +
                                      " is out of range; allowed [1, 64]");
      } else if (a == "--out") {
        out = value();
      } else if (dir.empty() && a.rfind("--", 0) != 0) {
        dir = a;
      } else {
        throw std::invalid_argument("unexpected argument '" + a + "'");
      }
    }
    if (dir.empty() || out.empty()) throw std::invalid_argument("DIR and --out are required");
  } catch (const std::exception& e) {
    std::cerr << "erg: amplify: " << e.what() << "\n" << usage_of("amplify");
    return 2;
  }
  try {
    const std::string snap = snapshot_path(dir, step);
    erg::v1::JobSpec spec;
    const amplify::AmplifyInput in = amplify::input_from_snapshot(snap, spec);
    const amplify::Region region = region_text.empty()
                                       ? amplify::Region{0, 0, in.nx, in.ny}
                                       : amplify::parse_region(region_text, in.nx, in.ny);
    const amplify::AmplifiedLayers a =
        amplify::amplify_layers(in, region, upsample, spec.amplify());
    io::HeightmapMeta meta;
    meta.nx = a.nx;
    meta.ny = a.ny;
    meta.cell_size_m = a.cell_size_m;
    meta.source = snap;
    meta.attrs = {{"region_x0", region.x0},
                  {"region_y0", region.y0},
                  {"region_w", region.w},
                  {"region_h", region.h},
                  {"upsample", upsample}};
    io::write_heightmap(out, meta, a.height.data());
    // Preview: the amplified sand over the upsampled bedrock.
    std::vector<float> sand(a.height.size());
    for (size_t c = 0; c < sand.size(); ++c) sand[c] = a.height[c] - a.bedrock[c];
    const std::string png = fs::path(out).replace_extension(".png").string();
    io::write_preview_png(png, a.nx, a.ny, a.cell_size_m, a.bedrock.data(), sand.data(), nullptr);
    std::cout << out << "\n" << png << "\n";
    return 0;
  } catch (const std::invalid_argument& e) {
    std::cerr << "erg: amplify: " << e.what() << "\n";
    return 2;
  } catch (const std::exception& e) {
    std::cerr << "erg: amplify: " << e.what() << "\n";
    return 1;
  }
}

}  // namespace erg::client
