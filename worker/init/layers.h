// SPDX-License-Identifier: Apache-2.0
// Initial layers: evaluate a Layer (sum of its sources) at the owned cells of
// a tile. Every generator is a function of the global cell and the seed only,
// so any tiling of the domain generates the same field.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "core/grid.h"
#include "erg/v1/job.pb.h"
#include "stages/obstacles.h"

namespace erg::init {

// Which layer is generated: salts the random streams so that layers differ.
enum class LayerKind : std::uint32_t { kBedrock = 1, kSand = 2, kVegetation = 3, kResistance = 4 };

// Values at the tile's owned cells, row-major [ny][nx], in the layer's unit
// (metres, or a fraction). base_dir resolves relative map paths.
std::vector<double> generate_layer(const erg::v1::Layer& layer, LayerKind kind,
                                   const erg::v1::JobSpec& spec, const TileGeom& tile,
                                   const std::string& base_dir);

// The shapes of one obstacle (a road gives one capsule per segment of its
// polyline) on a domain of lx_m x ly_m metres.
std::vector<obstacles::Shape> obstacle_shapes(const erg::v1::Obstacle& o, double lx_m, double ly_m);

// Obstacle heights o >= 0 (metres) at the tile's owned cells, row-major: the
// largest of the shapes and the map covering each cell (stages/obstacles.h).
std::vector<double> generate_obstacles(const erg::v1::Obstacles& obs, const erg::v1::JobSpec& spec,
                                       const TileGeom& tile, const std::string& base_dir);

}  // namespace erg::init
