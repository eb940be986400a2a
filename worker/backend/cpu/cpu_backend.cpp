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
      smoother_(model.coarse) {
  bedrock_.reset(g_);
  sand_.reset(g_);
  airborne_.reset(g_);
  vegetation_.reset(g_);
  resistance_.reset(g_);
  obstacles_.reset(g_);
  height_m_.reset(g_);
  wind_x_.reset(g_);
  wind_y_.reset(g_);
  shadow_.reset(g_);
  echo_.reset(g_);
  landed_.reset(g_);
  reptation_.reset(g_);
  height_units_.reset(g_);
  tan_l_.reset(g_);
  sand_next_.reset(g_);
  h_a_.reset(g_);
  frac_.reset(g_);
  coarse_h_.assign(static_cast<size_t>(m_.coarse.nx) * m_.coarse.ny, 0.0);
}

void CpuBackend::upload(const TileState& s) {
  bedrock_ = s.bedrock;
  sand_ = s.sand;
  airborne_ = s.airborne;
  vegetation_ = s.vegetation;
  resistance_ = s.resistance;
  obstacles_ = s.obstacles;
  bedrock_changed_ = true;
  update_repose();
  obstacles_changed();
}

void CpuBackend::obstacles_changed() {
  ex_.fill(obstacles_, g_.halo);
  const float* o = obstacles_.data();
  bool any = false;
  for (size_t i = 0; i < obstacles_.size(); ++i) any |= obstacles::is_obstacle(o[i]);
  any_obstacles_ = any;
}

void CpuBackend::download(TileState& s) {
  s.geom = g_;
  s.bedrock = bedrock_;
  s.sand = sand_;
  s.airborne = airborne_;
  s.vegetation = vegetation_;
  s.resistance = resistance_;
  s.obstacles = obstacles_;
}

void CpuBackend::download_wind(std::vector<float>& wind_xy) {
  wind_xy.resize(static_cast<size_t>(g_.nx) * g_.ny * 2);
  for (int y = 0; y < g_.ny; ++y)
    for (int x = 0; x < g_.nx; ++x) {
      const size_t i = (static_cast<size_t>(y) * g_.nx + x) * 2;
      wind_xy[i] = wind_x_(x, y);
      wind_xy[i + 1] = wind_y_(x, y);
    }
}

void CpuBackend::download_shadow(std::vector<float>& shadow) {
  shadow.resize(static_cast<size_t>(g_.nx) * g_.ny);
  for (int y = 0; y < g_.ny; ++y)
    std::memcpy(&shadow[static_cast<size_t>(y) * g_.nx], shadow_.row(y), sizeof(float) * g_.nx);
}

void CpuBackend::update_repose() {
#pragma omp parallel for num_threads(threads_) schedule(static)
  for (int y = 0; y < g_.ny; ++y) {
    const float* v = vegetation_.row(y);
    float* t = tan_l_.row(y);
    for (int x = 0; x < g_.nx; ++x)
      t[x] = vegetation::repose_tan(v[x], m_.tan_l_sand, m_.tan_l_vegetated);
  }
  // Avalanching reads the tangents inside its whole halo.
  ex_.fill(tan_l_, m_.halo_avalanche() + 1);
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
    units_t* s = sand_.row(y);
    const float* o = obstacles_.row(y);
    for (int x = 0; x < g_.nx; ++x) {
      units_t d = events::brush_units(b, centre_x(g_, x), centre_y(g_, y));
      if (d < -s[x]) d = -s[x];                 // never below bare ground
      if (obstacles::is_obstacle(o[x])) d = 0;  // obstacles hold no sand
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
    units_t* r = bedrock_.row(y);
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
    float* v = vegetation_.row(y);
    for (int x = 0; x < g_.nx; ++x)
      if (events::in_region(r, centre_x(g_, x), centre_y(g_, y))) v[x] = r.value;
  }
  update_repose();
}

total_t CpuBackend::set_obstacle(const obstacles::Shape& sh, bool remove) {
  total_t change = 0;
#pragma omp parallel for num_threads(threads_) schedule(static) reduction(+ : change)
  for (int y = 0; y < g_.ny; ++y) {
    float* o = obstacles_.row(y);
    units_t* s = sand_.row(y);
    units_t* a = airborne_.row(y);
    for (int x = 0; x < g_.nx; ++x) {
      if (!obstacles::covers(sh, centre_x(g_, x), centre_y(g_, y))) continue;
      if (remove) {
        o[x] = 0.0f;
      } else {
        o[x] = std::max(o[x], sh.height_m);
        change -= s[x] + a[x];  // an obstacle holds no sand, on the ground or in the air
        s[x] = 0;
        a[x] = 0;
      }
    }
  }
  obstacles_changed();
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
    const units_t* ps = sand_.row(y);
    const units_t* pa = airborne_.row(y);
    const units_t* pb = bedrock_.row(y);
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
