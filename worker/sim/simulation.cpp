// SPDX-License-Identifier: Apache-2.0
#include "sim/simulation.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <stdexcept>
#include <string>
#include <vector>

#include "init/layers.h"
#include "job/spec.h"
#include "wind/primitives.h"
#include "wind/regime.h"

namespace erg {

namespace {
using Clock = std::chrono::steady_clock;
double ms_since(Clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

events::Brush brush_of(const erg::v1::Brush& b, const Model& m) {
  return {b.x_m(),
          b.y_m(),
          b.radius_m(),
          b.falloff_m(),
          b.height(),
          m.tile.gnx * static_cast<double>(m.tile.cell_m),
          m.tile.gny * static_cast<double>(m.tile.cell_m)};
}
}  // namespace

void initial_rows(const erg::v1::JobSpec& spec, const Model& model, const std::string& base_dir,
                  const std::function<void(fields::Id, int, int, const void*)>& set) {
  using init::LayerKind;
  const auto& L = spec.layers();
  const TileGeom& tile = model.tile;
  const int band = static_cast<int>(
      std::clamp<std::size_t>(kInitialBandCells / static_cast<std::size_t>(std::max(tile.nx, 1)), 1,
                              static_cast<std::size_t>(std::max(tile.ny, 1))));
  std::vector<units_t> bedrock, sand;
  std::vector<float> vegetation, resistance, obstacles;
  for (int y0 = 0; y0 < tile.ny; y0 += band) {
    const int y1 = std::min(y0 + band, tile.ny);
    // The band as a tile of its own: every generator is a function of the
    // global cell, so the bands give the tile's values.
    TileGeom g = tile;
    g.y0 = tile.y0 + y0;
    g.ny = y1 - y0;
    const auto convert = [&](const std::vector<double>& v, auto& out, auto f) {
      out.resize(v.size());
      for (std::size_t i = 0; i < v.size(); ++i) out[i] = f(v[i]);
    };
    convert(init::generate_layer(L.bedrock(), LayerKind::kBedrock, spec, g, base_dir), bedrock,
            [](double m) { return m_to_units(m); });
    convert(init::generate_layer(L.sand(), LayerKind::kSand, spec, g, base_dir), sand,
            [](double m) { return m_to_units(std::max(0.0, m)); });
    convert(init::generate_layer(L.vegetation(), LayerKind::kVegetation, spec, g, base_dir),
            vegetation, [](double v) { return static_cast<float>(std::clamp(v, 0.0, 1.0)); });
    convert(init::generate_layer(L.resistance(), LayerKind::kResistance, spec, g, base_dir),
            resistance, [](double v) { return static_cast<float>(std::clamp(v, 0.0, 1.0)); });
    convert(init::generate_obstacles(L.obstacles(), spec, g, base_dir), obstacles,
            [](double o) { return static_cast<float>(o); });
    // Obstacles hold no sand [BR04 4]: initial sand inside them is dropped.
    for (std::size_t i = 0; i < sand.size(); ++i)
      if (obstacles::is_obstacle(obstacles[i])) sand[i] = 0;
    set(fields::kBedrock, y0, y1, bedrock.data());
    set(fields::kSand, y0, y1, sand.data());
    set(fields::kVegetation, y0, y1, vegetation.data());
    set(fields::kResistance, y0, y1, resistance.data());
    set(fields::kObstacles, y0, y1, obstacles.data());
  }
}

TileState initial_state(const erg::v1::JobSpec& spec, const Model& model,
                        const std::string& base_dir) {
  TileState s;
  s.allocate(model.tile);
  initial_rows(spec, model, base_dir, [&](fields::Id id, int y0, int y1, const void* in) {
    const bool units = fields::info(id).type == fields::Type::kUnits;
    for (int y = y0; y < y1; ++y)
      for (int x = 0; x < model.tile.nx; ++x) {
        const std::size_t i = static_cast<std::size_t>(y - y0) * model.tile.nx + x;
        if (units)
          s.units[id](x, y) = static_cast<const units_t*>(in)[i];
        else
          s.reals[id](x, y) = static_cast<const float*>(in)[i];
      }
  });
  return s;
}

void Simulation::place_tile(const Placement& place) {
  const int gnx = static_cast<int>(spec_.domain().nx()),
            gny = static_cast<int>(spec_.domain().ny());
  if (place.exchange) {
    exchange_ = place.exchange;
  } else {
    own_exchange_ = std::make_unique<dist::PeriodicExchange>();
    exchange_ = own_exchange_.get();
  }
  local_rank_ = place.local_rank;
  const AvalancheRounds round = place.rounds             ? *place.rounds
                                : exchange_->tiles() > 1 ? kTiledRounds
                                                         : kOneTileRounds;
  if (place.nx > 0)
    model_ = make_model(spec_, place.nx, place.ny, place.x0, place.y0, round);
  else
    model_ = make_model(spec_, gnx, gny, 0, 0, round);
}

Simulation::Simulation(const erg::v1::JobSpec& spec, const std::string& base_dir,
                       const RunOptions& opt, const Placement& place)
    : spec_(spec) {
  spec_json_ = job::to_json(spec_);
  place_tile(place);
  make_backend_for(opt);
  initial_rows(spec_, model_, base_dir, [&](fields::Id id, int y0, int y1, const void* in) {
    backend_->upload_rows(id, y0, y1, in);
  });
  ready();
}

Simulation::Simulation(const io::Checkpoint& ckpt, const RunOptions& opt, const Placement& place)
    : Simulation(ckpt, opt, place, Deferred{}) {
  // Every state field of the registry; one that an older checkpoint lacks
  // keeps its default.
  fields::each([&](fields::Id id, const fields::Info& f) {
    if (!f.state || ckpt.size(id) == 0) return;
    if (ckpt.size(id) != static_cast<std::size_t>(model_.tile.nx) * model_.tile.ny)
      throw std::invalid_argument(std::string("checkpoint field ") + f.name +
                                  " does not hold the tile's cells");
    if (f.type == fields::Type::kUnits)
      load_rows(id, 0, model_.tile.ny, ckpt.units[id].data());
    else
      load_rows(id, 0, model_.tile.ny, ckpt.reals[id].data());
  });
  loaded();
}

Simulation::Simulation(const io::Checkpoint& ckpt, const RunOptions& opt, const Placement& place,
                       Deferred) {
  spec_ = job::parse_json(ckpt.job_spec_json, "checkpoint job_spec");
  job::apply_defaults(spec_);
  spec_json_ = job::to_json(spec_);
  place_tile(place);
  step_ = ckpt.step;
  for (const auto& [name, value] : ckpt.ledger) {
    if (name == "sand_added_by_events") sand_added_ = parse_decimal(value);
    if (name == "bedrock_added_by_events") bedrock_added_ = parse_decimal(value);
  }
  make_backend_for(opt);
}

void Simulation::loaded() {
  ready();
}

void Halo::run(GhostOp op, std::initializer_list<fields::Id> ids, int width) {
  std::vector<FieldGhosts> list;
  for (const fields::Id id : ids)
    list.push_back({id, width >= 0 ? width : m_->ghost_width(fields::info(id).ghosts)});
  b_->ghosts(op, list);
}

void Simulation::make_backend_for(const RunOptions& opt) {
  model_.avalanche_everywhere = opt.avalanche_everywhere;
  backend_ = make_backend(opt.backend, model_, opt.threads, *exchange_, local_rank_);
  halo_.emplace(*backend_, model_);
}

void Simulation::ready() {
  backend_->upload_done();
  // Per-cell constants read in the ghosts: repose tangents (avalanching; the
  // CPU backend derives them from vegetation, ghosts included) and obstacles
  // (hop paths, echo dunes, walls).
  halo_->fill({fields::kTanL, fields::kVegetation, fields::kObstacles});
  backend_->obstacles_changed();
}

void Simulation::add_events(const std::vector<erg::v1::Event>& events) {
  if (events.empty()) return;
  for (const auto& e : events) *spec_.add_events() = e;
  // Nothing caches the event list: apply_events and wind::at_step read spec_
  // at every step. The JSON goes into checkpoints and snapshots.
  spec_json_ = job::to_json(spec_);
}

void Simulation::apply_events(std::int64_t step) {
  const double lx = model_.tile.gnx * static_cast<double>(model_.tile.cell_m);
  const double ly = model_.tile.gny * static_cast<double>(model_.tile.cell_m);
  bool vegetation = false, obstacles = false;  // changed: their ghosts are refilled
  for (const auto& e : spec_.events()) {
    if (e.step() != step) continue;
    switch (e.action_case()) {
      case erg::v1::Event::kSand:
        sand_added_ += backend_->apply_sand_brush(brush_of(e.sand(), model_));
        break;
      case erg::v1::Event::kBedrock:
        bedrock_added_ += backend_->apply_bedrock_brush(brush_of(e.bedrock(), model_));
        break;
      case erg::v1::Event::kVegetation: {
        const auto& v = e.vegetation();
        events::Region r{v.x_m(),
                         v.y_m(),
                         v.width_m(),
                         v.height_m(),
                         v.has_radius_m() ? v.radius_m() : -1.0,
                         static_cast<float>(v.density()),
                         lx,
                         ly};
        backend_->set_vegetation(r);
        vegetation = true;
        break;
      }
      case erg::v1::Event::kAddObstacle:
      case erg::v1::Event::kRemoveObstacle: {
        const bool add = e.action_case() == erg::v1::Event::kAddObstacle;
        for (const obstacles::Shape& s :
             init::obstacle_shapes(add ? e.add_obstacle() : e.remove_obstacle(), lx, ly))
          sand_added_ += backend_->set_obstacle(s, !add);
        obstacles = true;
        break;
      }
      default:  // wind switches are read by wind::at_step
        break;
    }
  }
  if (vegetation && obstacles)
    halo_->fill({fields::kTanL, fields::kVegetation, fields::kObstacles});
  else if (vegetation)
    halo_->fill({fields::kTanL, fields::kVegetation});
  else if (obstacles)
    halo_->fill({fields::kObstacles});
  if (obstacles) backend_->obstacles_changed();
}

// The step pipeline ([P19] Fig. 3, [N24] 3.2, docs/design.md "The step
// pipeline"), with every halo exchange between the stages that need it. The
// widths follow from the fields' registry Reach (core/fields.h).
void Simulation::step() {
  auto t = Clock::now();
  auto lap = [&](Stage s) {
    backend_->synchronize();
    times_.ms[s] += ms_since(t);
    if (observer_) observer_(s);
    t = Clock::now();
  };
  Halo& halo = *halo_;
  apply_events(step_);  // refills the ghosts of the per-cell constants it changed
  lap(kEvents);
  backend_->heights();
  // The shadow march reads the heights upwind: their ghosts travel while the
  // wind is warped, which reads none.
  halo.begin_fill({fields::kHeight});
  backend_->wind(wind::at_step(spec_, step_));  // high-altitude wind, venturi, warping
  halo.finish_fill({fields::kHeight});
  // Local wind primitives [P19 4.4], w = warped + u, before the shadow reads w.
  if (const auto active = wind::primitives_at(spec_, step_); !active.empty())
    backend_->perturb_wind(wind::batches(active));
  lap(kWind);
  backend_->shadow();
  lap(kShadow);
  backend_->saltation_hop(step_);     // lift, hop
  halo.sum({fields::kLanded});        // sand that left the tile lands on its neighbours
  backend_->saltation_impact(step_);  // deposit, bounce, abrade
  lap(kSaltation);
  // One exchange for reptation and the first avalanching round, which run on
  // the tile grown by that round's halo.
  if (model_.reptation_k > 0.0f)
    halo.fill({fields::kSand, fields::kBedrock, fields::kReptation});
  else
    halo.fill({fields::kSand, fields::kBedrock});
  backend_->reptation();
  lap(kReptation);
  // Later avalanching rounds refill the layers that moved (docs/design.md
  // "Tiling"): with one tile before every iteration, with several at most
  // once per step, after the tiles agree that something still moves.
  const Refill refill = [&](std::initializer_list<fields::Id> ids, int width) {
    halo.fill(ids, width);
  };
  const AvalancheResult av = backend_->avalanche_sand(refill);
  times_.avalanche_iterations += av.moved;
  times_.avalanche_most = std::max(times_.avalanche_most, av.moved);
  if (av.capped) {
    if (times_.avalanche_capped_steps++ == 0) times_.first_capped_step = step_;
  }
  lap(kAvalanche);
  backend_->avalanche_bedrock(refill);
  lap(kBedrock);
  ++step_;
  ++times_.steps;
}

const Calibration& Simulation::calibration() {
  if (!calibration_) calibration_ = calibrate(spec_);
  return *calibration_;
}

TileState Simulation::state() {
  TileState s;
  s.allocate(model_.tile);
  backend_->download(s);
  return s;
}

io::Checkpoint Simulation::checkpoint_header() const {
  io::Checkpoint c;
  c.step = step_;
  c.nx = model_.tile.gnx;
  c.ny = model_.tile.gny;
  c.job_spec_json = spec_json_;
  c.ledger = {{"sand_added_by_events", to_decimal(sand_added_)},
              {"bedrock_added_by_events", to_decimal(bedrock_added_)}};
  return c;
}

io::Checkpoint Simulation::checkpoint() {
  io::Checkpoint c = checkpoint_header();
  const TileGeom& g = model_.tile;
  const std::size_t n = static_cast<std::size_t>(g.nx) * g.ny;
  fields::each([&](fields::Id id, const fields::Info& f) {
    if (!f.state) return;
    if (f.type == fields::Type::kUnits) {
      c.units[id].resize(n);
      state_rows(id, 0, g.ny, c.units[id].data());
    } else {
      c.reals[id].resize(n);
      state_rows(id, 0, g.ny, c.reals[id].data());
    }
  });
  return c;
}

void Simulation::layer_rows(fields::Id id, int y0, int y1, float* out) {
  if (fields::info(id).type == fields::Type::kFloat) {
    backend_->download_rows(id, y0, y1, out);
    return;
  }
  // Integer units as metres, as download_owned gives them.
  const std::size_t n =
      static_cast<std::size_t>(y1 - y0) * static_cast<std::size_t>(model_.tile.nx);
  std::vector<units_t> band(n);
  backend_->download_rows(id, y0, y1, band.data());
  for (std::size_t i = 0; i < n; ++i) out[i] = static_cast<float>(units_to_m_d(band[i]));
}

Simulation::Output Simulation::output() {
  Output o;
  for (const fields::Id id : fields::snapshot_order())
    backend_->download_owned(id, o.layers[static_cast<std::size_t>(id)]);
  return o;
}

io::SnapshotMeta Simulation::snapshot_meta() {
  const Totals t = totals();
  io::SnapshotMeta m;
  m.step = step_;
  m.time_days = time_days();
  m.cell_size_m = spec_.domain().cell_size_m();
  m.nx = model_.tile.gnx;
  m.ny = model_.tile.gny;
  m.job_spec_json = spec_json_;
  m.erg_version = ERG_VERSION;
  m.unit_m = kUnitM;
  m.sand_units_total = to_decimal(t.sand);
  m.bedrock_units_total = to_decimal(t.bedrock);
  m.airborne_units_total = to_decimal(t.airborne);
  m.seed = static_cast<std::uint64_t>(spec_.seed());
  m.backend = backend_->name();
  const Calibration& c = calibration();
  m.time_s = time_s();
  m.physical = c.physical;
  m.dt_s = c.dt_s;
  const Vec2 a = wind::at_step(spec_, step_);
  m.wind_speed_mps = length(a);
  m.wind_direction_deg = std::atan2(a.y, a.x) * 180.0 / 3.14159265358979323846;
  if (c.physical) {
    m.shear_velocity_mps = wind::shear_velocity_at(spec_, step_);
    m.threshold_mps = c.ustar_t;
    m.reference_shear_velocity_mps = c.ustar_ref;
    m.calibration_flux_m2_per_step = c.q_model_m2_step;
    m.calibration_law_flux_m2_per_s = c.q_law_m2_s;
    m.flux_law = c.law;
  }
  return m;
}

}  // namespace erg
