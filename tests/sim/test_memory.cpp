// SPDX-License-Identifier: Apache-2.0
// Memory of the CPU backend (docs/design.md "Memory"): the storage shared
// between fields whose lifetimes do not overlap gives back, for a snapshot,
// the very wind and shadow the step's stages computed; a tile holds at most
// 64 bytes per stored cell while stepping, and layers that are zero
// everywhere take no memory.
#include <gtest/gtest.h>
#include <sys/mman.h>

#include <array>
#include <bit>
#include <cstdint>
#include <fstream>
#include <iostream>
#include <string>
#include <vector>

#include "sim/simulation.h"
#include "sim_test_util.h"

namespace erg {
namespace {

// Obstacles, vegetation, echo dunes and a wind primitive: every input the
// wind and the shadow read.
const char* kScene = R"({
  "name": "memory", "domain": {"nx": 96, "ny": 64, "cell_size_m": 1.0},
  "layers": {"sand": {"constant": 1.0, "uniform": {"min": 0, "max": 2}},
             "bedrock": {"fbm": {"amplitude": 6, "wavelength_m": 40, "octaves": 2}},
             "vegetation": {"uniform": {"min": 0, "max": 0.3}},
             "obstacles": {"shapes": [{"height_m": 4,
                                       "rect": {"x_m": 30, "y_m": 20, "size_x_m": 6, "size_y_m": 10}}]}},
  "wind": {"constant": {"speed_mps": 6, "direction_deg": 20}},
  "model": {"echo_dunes": true, "reptation_k": 0.2},
  "seed": 5, "run": {"steps": 4}
})";

std::vector<std::uint32_t> bits(const std::vector<float>& v) {
  std::vector<std::uint32_t> b(v.size());
  for (std::size_t i = 0; i < v.size(); ++i) b[i] = std::bit_cast<std::uint32_t>(v[i]);
  return b;
}

TEST(Memory, SnapshotWindAndShadowAreThoseTheStepComputed) {
  const auto spec = test::spec_from(kScene);
  Simulation sim(spec, ".", test::cpu_threads(2));
  const std::array<fields::Id, 3> ids = {fields::kWindX, fields::kWindY, fields::kShadow};
  std::array<std::vector<float>, 3> computed;
  sim.set_stage_observer([&](Stage s) {
    if (s != kShadow) return;
    for (std::size_t k = 0; k < ids.size(); ++k) sim.backend().download_owned(ids[k], computed[k]);
  });
  const int nx = sim.model().tile.nx, ny = sim.model().tile.ny;
  for (int step = 0; step < 4; ++step) {
    sim.step();
    for (std::size_t k = 0; k < ids.size(); ++k) {
      // Read back after reptation and avalanching reused their storage, in
      // two bands as the writers read them.
      std::vector<float> out(static_cast<std::size_t>(nx) * ny);
      sim.layer_rows(ids[k], 0, ny / 2, out.data());
      sim.layer_rows(ids[k], ny / 2, ny, out.data() + static_cast<std::size_t>(ny / 2) * nx);
      EXPECT_EQ(bits(out), bits(computed[k]))
          << "step " << step << ", " << fields::info(ids[k]).name;
    }
    double shadowed = 0;
    for (const float s : computed[2]) shadowed += s;
    EXPECT_GT(shadowed, 0.0) << "the scene casts a shadow";
  }
}

// Before the first step the wind, shadow and deposited layers are 0, as
// they always were.
TEST(Memory, LayersBeforeTheFirstStepAreZero) {
  Simulation sim(test::spec_from(kScene), ".", test::cpu_threads(1));
  const int nx = sim.model().tile.nx, ny = sim.model().tile.ny;
  for (const fields::Id id :
       {fields::kWindX, fields::kWindY, fields::kShadow, fields::kDeposited}) {
    std::vector<float> out(static_cast<std::size_t>(nx) * ny, 1.0f);
    sim.layer_rows(id, 0, ny, out.data());
    for (const float v : out) ASSERT_EQ(v, 0.0f) << fields::info(id).name;
  }
}

long long status_kb(const char* key) {
  std::ifstream in("/proc/self/status");
  for (std::string line; std::getline(in, line);)
    if (line.rfind(key, 0) == 0) return std::stoll(line.substr(std::string(key).size()));
  return -1;
}

// Whether this kernel maps its shared zero page when untouched anonymous
// memory is read. Linux does, unless told not to (some virtual machines
// boot with it off, e.g. `pvm_no_zero_page`): then every page a stage reads
// becomes resident, written or not, and a layer that is zero everywhere
// costs its full size as soon as a stage reads it.
bool kernel_maps_the_zero_page_on_reads() {
  constexpr std::size_t n = std::size_t{16} << 20;
  void* p = mmap(nullptr, n, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
  if (p == MAP_FAILED) return true;
  const long long before = status_kb("VmRSS:");
  const volatile unsigned char* c = static_cast<const unsigned char*>(p);
  unsigned sum = 0;
  for (std::size_t i = 0; i < n; i += 4096) sum += c[i];
  const long long after = status_kb("VmRSS:");
  munmap(p, n);
  return sum == 0 && after - before < 4096;  // kB: under a quarter of what was read
}

// The resident memory a 1024 x 1024 tile of `layers` adds, stepping and
// reading a snapshot's layers back, in bytes per stored cell (halo
// included), less 4 MiB for everything else (coarse grids, masks, threads).
double bytes_per_stored_cell(const std::string& layers) {
  const auto spec = test::spec_from(R"({
    "name": "steady", "domain": {"nx": 1024, "ny": 1024, "cell_size_m": 1.0},
    "layers": )" + layers + R"(,
    "wind": {"constant": {"speed_mps": 5, "direction_deg": 0}}, "seed": 1, "run": {"steps": 2}
  })");
  {
    // What any first simulation sets up once (threads, libraries' state)
    // is not the tile's.
    Simulation warm(test::spec_from(kScene), ".", test::cpu_threads(2));
    warm.step();
  }
  const long long before = status_kb("VmRSS:");
  Simulation sim(spec, ".", test::cpu_threads(2));
  sim.step();
  sim.step();
  const TileGeom& g = sim.model().tile;
  std::vector<float> band(static_cast<std::size_t>(g.nx) * 64);
  for (const fields::Id id : fields::snapshot_order()) sim.layer_rows(id, 0, 64, band.data());
  const double added = static_cast<double>(status_kb("VmRSS:") - before) * 1024.0;
  return (added - 4.0 * (1 << 20)) / static_cast<double>(g.size());
}

// Every layer in use: vegetation and bedrock resistance everywhere, an
// obstacle.
const char* kAllLayers = R"({
    "sand": {"constant": 0.5, "uniform": {"min": 0, "max": 1.5}},
    "vegetation": {"uniform": {"min": 0.05, "max": 0.3}},
    "resistance": {"constant": 0.5},
    "obstacles": {"shapes": [{"height_m": 3,
                              "rect": {"x_m": 100, "y_m": 100, "size_x_m": 8, "size_y_m": 8}}]}})";

// At most 64 bytes a stored cell with every layer in use. Less than the
// registry's 60 is resident: the halo rows no stage reads are never written
// (1024 x 1024 tiles have a 93-cell halo, 28 % of the stored cells), nor
// are the obstacles' pages away from the obstacle. Measured 47.1 (58.9 on a
// kernel that maps no zero page on reads); under 40 the measure is broken.
TEST(Memory, ASteppingTileHoldsAtMost64BytesPerCell) {
  if (status_kb("VmRSS:") < 0) GTEST_SKIP() << "no /proc/self/status";
  const double b = bytes_per_stored_cell(kAllLayers);
  std::cout << b << " bytes a stored cell\n";
  EXPECT_LE(b, 64.0);
  EXPECT_GE(b, 40.0) << "the measure is broken";
}

// A layer that is zero everywhere (no vegetation, bedrock resistance or
// obstacles: the defaults) is never written, so its pages are never
// resident (core/field.h copy_changed). Vegetation and resistance alone
// hold at least 5.7 bytes a stored cell here when in use (4 bytes each on
// the owned cells), so with them resident this tile would hold at least
// 45; measured 39.2 (each test runs in a process of its own: memory freed
// by one measure would be reused by the next).
// On a kernel that maps no zero page the property does not hold (the
// stages read these layers), and the test says so and is counted as not run
// (SKIP_REGULAR_EXPRESSION, tests/sim/CMakeLists.txt), never as a pass.
TEST(Memory, LayersThatAreZeroEverywhereTakeNoMemory) {
  if (status_kb("VmRSS:") < 0) GTEST_SKIP() << "no /proc/self/status";
  if (!kernel_maps_the_zero_page_on_reads())
    GTEST_SKIP() << "this kernel maps no zero page on reads: a layer read is resident";
  const double b =
      bytes_per_stored_cell(R"({"sand": {"constant": 0.5, "uniform": {"min": 0, "max": 1.5}}})");
  std::cout << b << " bytes a stored cell\n";
  EXPECT_LE(b, 42.0);
  EXPECT_GE(b, 28.0) << "the measure is broken";
}

}  // namespace
}  // namespace erg
