// SPDX-License-Identifier: Apache-2.0
// A backend runs the stages of the step pipeline on one tile's data, on the
// CPU (backend/cpu) or a CUDA GPU (backend/cuda). The order of the stages,
// the wind regime and the events live in sim/simulation.cpp; the per-cell
// math lives in stages/ and is shared by both backends.
#pragma once

#include <functional>
#include <initializer_list>
#include <memory>
#include <span>
#include <stdexcept>
#include <string>
#include <vector>

#include "core/fields.h"
#include "core/vec2.h"
#include "dist/exchange.h"
#include "sim/model.h"
#include "sim/state.h"
#include "stages/events.h"
#include "stages/obstacles.h"
#include "stages/wind_primitives.h"

namespace erg {

// A field whose ghosts an exchange moves, and how wide (sim/simulation.h Halo).
struct FieldGhosts {
  fields::Id id;
  int width;
};
using dist::GhostOp;
// The ghosts of the listed fields, `width` cells wide, refilled between the
// rounds of an avalanching stage (the step passes it: Simulation::step).
using Refill = std::function<void(std::initializer_list<fields::Id> ids, int width)>;

// The refill at the start of an avalanche round of ghost width e (the last
// round's: e_last), the same on every backend: the ghosts of the layer that
// moves, and of bedrock under sand too when the round is wider than the last
// (its heights are then recomputed further out), in one message.
inline void refill_round(const Refill& refill, bool bedrock, int e, int e_last) {
  if (e > e_last && !bedrock)
    refill({fields::kSand, fields::kBedrock}, e + 1);
  else
    refill({bedrock ? fields::kBedrock : fields::kSand}, e + 1);
}

// upload_owned's preconditions, the same on every backend.
inline void check_owned_upload(fields::Id id, const std::vector<float>& in, const TileGeom& g) {
  if (fields::info(id).type != fields::Type::kFloat)
    throw std::invalid_argument(std::string("upload_owned: ") + fields::info(id).name +
                                " is held in integer units");
  if (in.size() != static_cast<std::size_t>(g.nx) * g.ny)
    throw std::invalid_argument(std::string("upload_owned: ") + fields::info(id).name +
                                " needs one value per owned cell");
}

// download_rows' and upload_rows' preconditions, the same on every backend:
// rows within the tile; uploads to state fields only.
inline void check_rows(fields::Id id, int y0, int y1, const TileGeom& g, bool upload) {
  if (y0 < 0 || y1 > g.ny || y0 > y1)
    throw std::invalid_argument(std::string(upload ? "upload_rows: " : "download_rows: ") +
                                fields::info(id).name + " rows [" + std::to_string(y0) + ", " +
                                std::to_string(y1) + ") are not within the tile's " +
                                std::to_string(g.ny));
  if (upload && !fields::info(id).state)
    throw std::invalid_argument(std::string("upload_rows: ") + fields::info(id).name +
                                " is not exact state");
}
// Bytes per value of a registry field as stored.
inline std::size_t stored_bytes(fields::Id id) {
  return fields::info(id).type == fields::Type::kUnits ? sizeof(units_t) : sizeof(float);
}

// What a step's sand avalanching did: the iterations that moved sand, and
// whether it reached model.avalanche_iterations, the cap, with sand still
// moving (the same on every tile).
struct AvalancheResult {
  int moved = 0;
  bool capped = false;
};

class Backend {
 public:
  virtual ~Backend() = default;
  virtual std::string name() const = 0;
  // How this backend's ghosts reach the other tiles (dist/halo_path.h): on
  // the host, on the device (one tile), staged through host memory, or
  // handed to a CUDA-aware MPI.
  virtual dist::HaloPath halo_path() const { return dist::HaloPath::kHost; }

  // Exact state in and out (host TileState <-> backend storage).
  virtual void upload(const TileState& s) = 0;
  virtual void download(TileState& s) = 0;
  // Any registry field (core/fields.h) at the owned cells, row-major
  // [ny][nx], in its unit (integer units as metres): what snapshots hold.
  virtual void download_owned(fields::Id id, std::vector<float>& out) = 0;
  // Sets a float field's owned cells from row-major [ny][nx] values (a
  // kUnits field is refused: conserved sand enters only through upload).
  // For tests that hand two backends the same inputs at a stage boundary
  // (tests/common/stage_agreement.h); the ghosts are the next exchange's.
  virtual void upload_owned(fields::Id id, const std::vector<float>& in) = 0;
  // Rows [y0, y1) of a registry field's owned cells, row-major [y1 - y0][nx],
  // as stored (int64 units or float: `out` holds that many values of the
  // field's type). Checkpoints and snapshots are written from these a band
  // of rows at a time, so no copy of a whole field is ever made.
  virtual void download_rows(fields::Id id, int y0, int y1, void* out) = 0;
  // Sets rows [y0, y1) of a state field's owned cells, as download_rows
  // gives them (initial layers and checkpoints are read in bands); once
  // every state field is set, upload_done() derives what depends on them.
  // The ghosts are the next exchange's.
  virtual void upload_rows(fields::Id id, int y0, int y1, const void* in) = 0;
  virtual void upload_done() = 0;

  // --- ghosts ---------------------------------------------------------------
  // Moves the ghosts of the listed fields through the exchange (a fill, the
  // two halves of a split fill, or a sum back into the owners). The step
  // decides which fields and when (Simulation::step); a backend only hands
  // over its buffers (the GPU through host memory, or on the device when the
  // tile is the whole torus). Stages never exchange.
  virtual void ghosts(GhostOp op, std::span<const FieldGhosts> fields) = 0;
  // The obstacles' ghosts were filled: refresh what depends on them.
  virtual void obstacles_changed() = 0;

  // --- the stages, in pipeline order --------------------------------------
  // Heights b + s + o in metres at the owned cells, and the exact block sums
  // of the coarse wind cells this tile owns.
  virtual void heights() = 0;
  // Surface wind: the coarse grid gathered and smoothed, venturi [P19 4.2]
  // and multi-scale warping of the high-altitude wind a, at every owned cell
  // (reads no ghosts).
  virtual void wind(Vec2 a) = 0;
  // Local wind primitives [P19 4.4]: adds their curl-of-psi perturbation to
  // the surface wind at every owned cell, batch after batch.
  virtual void perturb_wind(const std::vector<wind_primitives::Batch>& batches) = 0;
  // Wind shadow [N24 eq. 4].
  virtual void shadow() = 0;
  // Saltation, first half: lift, and every airborne amount one hop downwind
  // into the landed sand (owned cells and ghosts).
  virtual void saltation_hop(std::int64_t step) = 0;
  // Second half, once the landed ghosts are summed into their owners:
  // deposition, bounces and abrasion; leaves the reptation strength for the
  // next stage and the deposited sand for snapshots.
  virtual void saltation_impact(std::int64_t step) = 0;
  // Reptation [N24 eqs. 6-8].
  virtual void reptation() = 0;
  // Sand avalanching [N24 eqs. 9-11], iterated until nothing moves (at most
  // model.avalanche_iterations). Rounds after the first refill their ghosts
  // with `refill`.
  virtual AvalancheResult avalanche_sand(const Refill& refill) = 0;
  // Bedrock avalanching at the bedrock repose angle.
  virtual void avalanche_bedrock(const Refill& refill) = 0;

  // --- timeline events ------------------------------------------------------
  // Returns the exact change of the layer's total (units).
  virtual total_t apply_sand_brush(const events::Brush& b) = 0;
  virtual total_t apply_bedrock_brush(const events::Brush& b) = 0;
  virtual void set_vegetation(const events::Region& r) = 0;
  // Builds (remove = false: cells take the larger height; their sand and
  // airborne sand are removed) or clears an obstacle shape. Returns the
  // exact change of the sand total (units, <= 0).
  virtual total_t set_obstacle(const obstacles::Shape& s, bool remove) = 0;

  virtual Totals totals() = 0;
  // Wait for queued device work (timing); no-op on the CPU.
  virtual void synchronize() {}
};

enum class BackendKind { kAuto, kCpu, kCuda };

// Creates the backend for a model. kAuto picks CUDA when a device exists and
// falls back to the CPU otherwise, with a log line on stderr. `ex` (which
// must outlive the backend) connects the tile to the others; `local_rank`
// picks the GPU (local_rank % devices).
std::unique_ptr<Backend> make_backend(BackendKind kind, const Model& model, int threads,
                                      dist::Exchange& ex, int local_rank = 0);

// True when this build has the CUDA backend and the runtime sees a device.
bool cuda_device_available();

// The GPU a CUDA backend on `local_rank` uses (local_rank % devices, as
// make_backend picks it) and its memory bandwidth measured now: the best of
// 10 device-to-device cudaMemcpy of 256 MiB, counting the bytes read and the
// bytes written (2 x 256 MiB per copy), the figure erg-bench divides its
// bytes-moved model by. Throws std::runtime_error without a CUDA device.
struct CudaDeviceInfo {
  std::string name;                             // cudaDeviceProp::name
  int major = 0, minor = 0;                     // compute capability
  double memory_bytes = 0;                      // global memory
  int multiprocessors = 0;                      // SM count
  double copy_bytes_per_s = 0;                  // measured, read + write
  int runtime_version = 0, driver_version = 0;  // cudaRuntimeGetVersion, cudaDriverGetVersion
};
CudaDeviceInfo cuda_device_info(int local_rank = 0);

}  // namespace erg
