// SPDX-License-Identifier: Apache-2.0
// A run of the aeolian model on one tile: the state, the backend and the
// per-step pipeline (the task list in Simulation::step, read top to bottom).
#pragma once

#include <array>
#include <cstddef>
#include <functional>
#include <initializer_list>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "backend/backend.h"
#include "erg/v1/job.pb.h"
#include "io/io.h"
#include "sim/calibration.h"
#include "sim/model.h"
#include "sim/state.h"

namespace erg {

// Where a simulation's tile sits in the domain, and how it reaches the other
// tiles. The default is one tile that is the whole torus.
struct Placement {
  int x0 = 0, y0 = 0, nx = 0, ny = 0;  // owned cells; nx = 0: the whole domain
  dist::Exchange* exchange = nullptr;  // null: the periodic wrap of one tile
  int local_rank = 0;                  // picks the GPU
  // Avalanching rounds (sim/model.h); none: kOneTileRounds on one tile,
  // else kTiledRounds.
  std::optional<AvalancheRounds> rounds;
};

struct RunOptions {
  BackendKind backend = BackendKind::kAuto;
  int threads = 0;                    // 0: all hardware threads (OMP_NUM_THREADS)
  bool avalanche_everywhere = false;  // see Model (tests)
};

// Pipeline stages, for timing.
enum Stage { kEvents, kWind, kShadow, kSaltation, kReptation, kAvalanche, kBedrock, kStageCount };
inline constexpr const char* kStageNames[kStageCount] = {
    "events", "wind", "shadow", "saltation", "reptation", "avalanching", "bedrock_avalanching"};

struct StageTimes {
  std::array<double, kStageCount> ms{};  // accumulated wall time per stage
  long long steps = 0;
  long long avalanche_iterations = 0;  // iterations that moved sand
  int avalanche_most = 0;              // the most of them in one step
  // Steps whose sand avalanching reached model.avalanche_iterations (the
  // cap) with sand still moving, and the first of them (-1: none).
  long long avalanche_capped_steps = 0;
  std::int64_t first_capped_step = -1;
};

// The halo exchanges of a step, as Simulation::step lists them: the ghosts
// of the listed fields, each as wide as the stages that read it reach (its
// registry Reach, Model::ghost_width) unless a width is given, all of them in
// one message per neighbour and phase.
class Halo {
 public:
  Halo(Backend& b, const Model& m) : b_(&b), m_(&m) {}
  void fill(std::initializer_list<fields::Id> ids) { run(GhostOp::kFill, ids, -1); }
  void fill(std::initializer_list<fields::Id> ids, int width) { run(GhostOp::kFill, ids, width); }
  // A fill split around work that reads none of these ghosts.
  void begin_fill(std::initializer_list<fields::Id> ids) { run(GhostOp::kBeginFill, ids, -1); }
  void finish_fill(std::initializer_list<fields::Id> ids) { run(GhostOp::kFinishFill, ids, -1); }
  // Ghosts added into their owners (a scatter across tile edges).
  void sum(std::initializer_list<fields::Id> ids) { run(GhostOp::kSum, ids, -1); }

 private:
  void run(GhostOp op, std::initializer_list<fields::Id> ids, int width);
  Backend* b_;
  const Model* m_;
};

class Simulation {
 public:
  // A new run: generates the initial layers of a defaults-filled, validated
  // spec. base_dir resolves relative map paths.
  Simulation(const erg::v1::JobSpec& spec, const std::string& base_dir, const RunOptions& opt,
             const Placement& place = {});
  // A run continued from a checkpoint (its spec is inside). Its arrays hold
  // the tile's cells (the whole domain when place is the default).
  Simulation(const io::Checkpoint& ckpt, const RunOptions& opt, const Placement& place = {});
  // A run continued from a checkpoint read band by band: `header` without
  // its arrays; then load_rows for the bands of every state field the file
  // has (io::read_checkpoint_parallel's sink), then loaded() (collective:
  // fills the ghosts). A field the file lacks keeps its default.
  struct Deferred {};
  Simulation(const io::Checkpoint& header, const RunOptions& opt, const Placement& place, Deferred);
  void load_rows(fields::Id id, int y0, int y1, const void* in) {
    backend_->upload_rows(id, y0, y1, in);
  }
  void loaded();

  // Advances one step: the step's events, then the pipeline.
  void step();
  // Called at the end of every stage of step(), with the stage that ended
  // (after the backend finished its work): tests compare two backends stage
  // by stage there (tests/common/stage_agreement.h). None by default.
  using StageObserver = std::function<void(Stage)>;
  void set_stage_observer(StageObserver observer) { observer_ = std::move(observer); }

  // Appends timeline events to the spec (steering a running job). They take
  // effect like the job's own events: an event at step S applies at the start
  // of step S, after the events listed before it, so one whose step is
  // step_index() applies in the next step(). The spec in checkpoints and
  // snapshots carries them. Every tile of a run must add the same events.
  void add_events(const std::vector<erg::v1::Event>& events);

  std::int64_t step_index() const { return step_; }
  // Physical time: steps x the calibrated time per step (sim/calibration.h),
  // measured on first use.
  const Calibration& calibration();
  double time_s() { return static_cast<double>(step_) * calibration().dt_s; }
  double time_days() {
    return calibration().physical ? time_s() / 86400.0
                                  : static_cast<double>(step_) * model_.time_step_days;
  }
  const erg::v1::JobSpec& spec() const { return spec_; }
  const Model& model() const { return model_; }
  Backend& backend() { return *backend_; }
  dist::Exchange& exchange() { return *exchange_; }
  Totals totals() { return backend_->totals(); }
  const StageTimes& times() const { return times_; }
  // Exact change of the totals made by timeline events so far.
  total_t sand_added_by_events() const { return sand_added_; }
  total_t bedrock_added_by_events() const { return bedrock_added_; }

  // The exact state of this tile (downloaded from the backend).
  TileState state();
  // The tile's exact state; nx, ny are the global domain size.
  io::Checkpoint checkpoint();
  // The same without its arrays (step, grid, spec, ledger): a checkpoint
  // written band by band from state_rows.
  io::Checkpoint checkpoint_header() const;
  // Rows [y0, y1) of a state field at the owned cells, as stored (int64
  // units or float; io::TileRows).
  void state_rows(fields::Id id, int y0, int y1, void* out) {
    backend_->download_rows(id, y0, y1, out);
  }
  // Rows [y0, y1) of a snapshot layer at the owned cells, in its unit
  // (float metres for integer fields; io::TileRows).
  void layer_rows(fields::Id id, int y0, int y1, float* out);

  // The snapshot layers of the registry (core/fields.h) at the tile's owned
  // cells, row-major, in their units (empty for fields not in snapshots).
  struct Output {
    std::array<std::vector<float>, fields::kCount> layers;
    const std::vector<float>& operator[](fields::Id id) const {
      return layers[static_cast<std::size_t>(id)];
    }
  };
  Output output();
  io::SnapshotMeta snapshot_meta();

 private:
  void place_tile(const Placement& place);
  // The backend, its state to be set by upload_rows, then ready().
  void make_backend_for(const RunOptions& opt);
  void ready();
  // The initial layers generated band by band into the backend.
  void generate_initial_state(const std::string& base_dir);
  void apply_events(std::int64_t step);

  erg::v1::JobSpec spec_;
  std::string spec_json_;
  Model model_;
  std::unique_ptr<dist::Exchange> own_exchange_;  // when the placement gives none
  dist::Exchange* exchange_ = nullptr;
  int local_rank_ = 0;
  std::unique_ptr<Backend> backend_;
  std::optional<Halo> halo_;
  StageObserver observer_;
  std::int64_t step_ = 0;
  total_t sand_added_ = 0, bedrock_added_ = 0;
  StageTimes times_;
  std::optional<Calibration> calibration_;
};

// Generates the initial exact state of a tile from the spec.
TileState initial_state(const erg::v1::JobSpec& spec, const Model& model,
                        const std::string& base_dir);
// The same, rows [y0, y1) of the tile at a time: set(id, y0, y1, values)
// gets each state field the layers give (int64 units or float, row-major
// [y1 - y0][nx]); airborne sand starts at its default. Rows are generated in
// bands of about kInitialBandCells cells, so that no layer of the whole tile
// is ever held in doubles.
inline constexpr std::size_t kInitialBandCells = std::size_t{1} << 20;
void initial_rows(const erg::v1::JobSpec& spec, const Model& model, const std::string& base_dir,
                  const std::function<void(fields::Id, int, int, const void*)>& set);

}  // namespace erg
