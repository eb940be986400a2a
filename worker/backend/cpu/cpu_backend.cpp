// SPDX-License-Identifier: Apache-2.0
#include "backend/cpu/cpu_backend.h"

#include <omp.h>

#include <algorithm>
#include <cstring>

#include "stages/vegetation.h"

namespace erg::cpu {

CpuBackend::CpuBackend(const Model& model, int threads, dist::Exchange& ex)
    : m_(model),
      g_(model.tile),
      threads_(threads > 0 ? threads : omp_get_max_threads()),
      ex_(ex),
      smoother_(model.coarse, model.tile.nx / model.coarse.cx, model.tile.ny / model.coarse.cy) {
  // A buffer for each field that owns one (core/fields.h Storage); the
  // others are views of the shared buffers (see cpu_backend.h).
  fields::each([&](fields::Id id, const fields::Info& f) {
    if (f.storage != fields::Storage::kOwn) return;
    if (id == fields::kEcho && !m_.echo.on) return;  // read as no_echo_
    if (f.type == fields::Type::kUnits)
      units(id).reset(g_, static_cast<units_t>(f.initial));
    else
      reals(id).reset(g_, f.initial);
  });
  work_.reset(g_);
  spare_.reset(g_);
  if (m_.repose_isotropic) tan_d_.reset(g_);
  float* half = reinterpret_cast<float*>(work_.data());
  f_.wind_x.view(half, g_);
  f_.wind_y.view(half + g_.size(), g_);
  h_a_.view(half, g_);
  frac_.view(half + g_.size(), g_);
  f_.shadow.view(spare_.data(), g_);
  f_.reptation.view(spare_.data(), g_);
  f_.tan_l.view(spare_.data(), g_);
  f_.landed.view(f_.deposited.data(), g_);
  no_echo_.assign(static_cast<std::size_t>(g_.pitch), 0.0f);
  static_assert(fields::info(fields::kWindX).storage == fields::Storage::kRecomputed &&
                fields::info(fields::kWindY).storage == fields::Storage::kRecomputed &&
                fields::info(fields::kShadow).storage == fields::Storage::kRecomputed &&
                fields::info(fields::kTanL).storage == fields::Storage::kRecomputed &&
                fields::info(fields::kReptation).storage == fields::Storage::kReplaced &&
                fields::info(fields::kLanded).storage == fields::Storage::kReplaced);
}

void CpuBackend::upload(const TileState& s) {
  fields::each([&](fields::Id id, const fields::Info& f) {
    if (!f.state) return;
    if (f.type == fields::Type::kUnits)
      units(id) = s.units[id];
    else
      reals(id) = s.reals[id];
  });
  bedrock_changed_ = true;
}

void CpuBackend::ghosts(GhostOp op, std::span<const FieldGhosts> fields) {
  std::vector<dist::Ghosts> list;
  for (const FieldGhosts& f : fields) {
    if (fields::info(f.id).type == fields::Type::kUnits)
      list.push_back({&units(f.id), f.width});
    else
      list.push_back({&reals(f.id), f.width});
  }
  ex_.ghosts(op, list);
}

void CpuBackend::obstacles_changed() {
  const float* o = f_.obstacles.data();
  bool any = false;
  for (size_t i = 0; i < f_.obstacles.size(); ++i) any |= obstacles::is_obstacle(o[i]);
  any_obstacles_ = any;
}

void CpuBackend::download(TileState& s) {
  s.geom = g_;
  fields::each([&](fields::Id id, const fields::Info& f) {
    if (!f.state) return;
    if (f.type == fields::Type::kUnits)
      s.units[id] = units(id);
    else
      s.reals[id] = reals(id);
  });
}

void CpuBackend::restore_outputs(fields::Id id) {
  if (id == fields::kWindX || id == fields::kWindY || id == fields::kShadow) {
    if (!wind_valid_ && wind_ran_) {
      warp_rows(last_a_);
      if (!last_batches_.empty()) perturb_wind(last_batches_);
    }
    wind_valid_ = true;
  }
  if (id == fields::kShadow && !shadow_valid_) {
    if (shadow_of_wind_) {
      shadow();
    } else {
      // Between the wind stage and the shadow stage: this step's shadow is
      // not computed yet and the last one cannot be (its wind is gone).
      // Defined as 0, as before the first step.
      std::fill(spare_.data(), spare_.data() + spare_.size(), 0.0f);
    }
    shadow_valid_ = true;
  }
}

void CpuBackend::download_owned(fields::Id id, std::vector<float>& out) {
  if (id == fields::kTanL) {  // from vegetation: its storage holds other things between avalanches
    out = owned_cells<float>(f_.vegetation, [&](float v) {
      return vegetation::repose_tan(v, m_.tan_l_sand, m_.tan_l_vegetated);
    });
    return;
  }
  if (id == fields::kEcho && !m_.echo.on) {
    out.assign(static_cast<std::size_t>(g_.nx) * g_.ny, 0.0f);
    return;
  }
  restore_outputs(id);
  if (fields::info(id).type == fields::Type::kUnits)
    out = owned_cells<float>(units(id),
                             [](units_t u) { return static_cast<float>(units_to_m_d(u)); });
  else
    out = owned_cells(reals(id));
}

void CpuBackend::upload_owned(fields::Id id, const std::vector<float>& in) {
  check_owned_upload(id, in, g_);
  set_owned_cells(reals(id), in);
}

void CpuBackend::download_rows(fields::Id id, int y0, int y1, void* out) {
  check_rows(id, y0, y1, g_, false);
  if ((id == fields::kTanL) || (id == fields::kEcho && !m_.echo.on)) {
    std::vector<float> all;
    download_owned(id, all);
    std::memcpy(out, all.data() + static_cast<std::size_t>(y0) * g_.nx,
                sizeof(float) * static_cast<std::size_t>(y1 - y0) * g_.nx);
    return;
  }
  restore_outputs(id);
  const std::size_t row = stored_bytes(id) * static_cast<std::size_t>(g_.nx);
  auto* o = static_cast<char*>(out);
  for (int y = y0; y < y1; ++y, o += row)
    std::memcpy(o,
                fields::info(id).type == fields::Type::kUnits
                    ? static_cast<const void*>(units(id).row(y))
                    : static_cast<const void*>(reals(id).row(y)),
                row);
}

void CpuBackend::upload_rows(fields::Id id, int y0, int y1, const void* in) {
  check_rows(id, y0, y1, g_, true);
  const std::size_t row = stored_bytes(id) * static_cast<std::size_t>(g_.nx);
  const auto* i = static_cast<const char*>(in);
  // Rows equal to what the field holds are not written: a layer of zeros
  // stays in untouched pages (copy_changed, core/field.h).
  for (int y = y0; y < y1; ++y, i += row)
    copy_changed(fields::info(id).type == fields::Type::kUnits
                     ? static_cast<void*>(units(id).row(y))
                     : static_cast<void*>(reals(id).row(y)),
                 i, row);
}

void CpuBackend::upload_done() {
  bedrock_changed_ = true;
}

// Over the ghosts the avalanching reads too: vegetation's ghosts are filled
// that wide (fields::Reach::kAvalanche), and each cell's tangent is a
// function of its vegetation alone, so a ghost gets its owner's value.
void CpuBackend::repose_tangents() {
  const int w = m_.ghost_width(fields::Reach::kAvalanche);
#pragma omp parallel for num_threads(threads_) schedule(static)
  for (int y = -w; y < g_.ny + w; ++y) {
    const float* v = f_.vegetation.row(y);
    float* t = f_.tan_l.row(y);
    for (int x = -w; x < g_.nx + w; ++x)
      t[x] = vegetation::repose_tan(v[x], m_.tan_l_sand, m_.tan_l_vegetated);
  }
}

namespace {
// Cell centre of local cell (x, y) in global metres.
inline double centre_x(const TileGeom& g, int x) {
  return (g.x0 + x + 0.5) * g.cell_m;
}
inline double centre_y(const TileGeom& g, int y) {
  return (g.y0 + y + 0.5) * g.cell_m;
}
}  // namespace

total_t CpuBackend::apply_sand_brush(const events::Brush& b) {
  total_t change = 0;
#pragma omp parallel for num_threads(threads_) schedule(static) reduction(+ : change)
  for (int y = 0; y < g_.ny; ++y) {
    units_t* s = f_.sand.row(y);
    const float* o = f_.obstacles.row(y);
    for (int x = 0; x < g_.nx; ++x) {
      const units_t d = events::sand_brush_change(b, centre_x(g_, x), centre_y(g_, y), s[x], o[x]);
      s[x] += d;
      change += d;
    }
  }
  std::vector<total_t> all{change};
  ex_.sum_exact(all);
  return all[0];
}

total_t CpuBackend::apply_bedrock_brush(const events::Brush& b) {
  total_t change = 0;
#pragma omp parallel for num_threads(threads_) schedule(static) reduction(+ : change)
  for (int y = 0; y < g_.ny; ++y) {
    units_t* r = f_.bedrock.row(y);
    for (int x = 0; x < g_.nx; ++x) {
      const units_t d = events::brush_units(b, centre_x(g_, x), centre_y(g_, y));
      r[x] += d;
      change += d;
    }
  }
  bedrock_changed_ = true;
  std::vector<total_t> all{change};
  ex_.sum_exact(all);
  return all[0];
}

void CpuBackend::set_vegetation(const events::Region& r) {
#pragma omp parallel for num_threads(threads_) schedule(static)
  for (int y = 0; y < g_.ny; ++y) {
    float* v = f_.vegetation.row(y);
    for (int x = 0; x < g_.nx; ++x)
      if (events::in_region(r, centre_x(g_, x), centre_y(g_, y))) v[x] = r.value;
  }
}

total_t CpuBackend::set_obstacle(const obstacles::Shape& sh, bool remove) {
  total_t change = 0;
#pragma omp parallel for num_threads(threads_) schedule(static) reduction(+ : change)
  for (int y = 0; y < g_.ny; ++y) {
    float* o = f_.obstacles.row(y);
    units_t* s = f_.sand.row(y);
    units_t* a = f_.airborne.row(y);
    for (int x = 0; x < g_.nx; ++x) {
      change -=
          obstacles::edit_cell(sh, remove, centre_x(g_, x), centre_y(g_, y), o[x], s[x], a[x]);
    }
  }
  std::vector<total_t> all{change};
  ex_.sum_exact(all);
  return all[0];
}

Totals CpuBackend::totals() {
  Totals t;
  // Per-row sums, then a fixed-order total (integers: order cannot matter,
  // but this keeps the reduction simple and exact).
  std::vector<total_t> rs(g_.ny), ra(g_.ny), rb(g_.ny);
#pragma omp parallel for num_threads(threads_) schedule(static)
  for (int y = 0; y < g_.ny; ++y) {
    total_t s = 0, a = 0, b = 0;
    const units_t* ps = f_.sand.row(y);
    const units_t* pa = f_.airborne.row(y);
    const units_t* pb = f_.bedrock.row(y);
    for (int x = 0; x < g_.nx; ++x) {
      s += ps[x];
      a += pa[x];
      b += pb[x];
    }
    rs[y] = s;
    ra[y] = a;
    rb[y] = b;
  }
  for (int y = 0; y < g_.ny; ++y) {
    t.sand += rs[y];
    t.airborne += ra[y];
    t.bedrock += rb[y];
  }
  std::vector<total_t> all{t.sand, t.airborne, t.bedrock};
  ex_.sum_exact(all);
  return {all[0], all[1], all[2]};
}

}  // namespace erg::cpu
