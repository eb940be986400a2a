// SPDX-License-Identifier: Apache-2.0
#include "init/layers.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <stdexcept>

#include "core/philox.h"
#include "init/noise.h"
#include "io/io.h"
#include "job/map_file.h"
#include "job/spec.h"

namespace erg::init {

namespace {

constexpr double kPi = 3.14159265358979323846;

// Shortest signed offset on a circle of length `period`.
double wrap_delta(double d, double period) {
  d = std::fmod(d, period);
  if (d >= 0.5 * period) d -= period;
  if (d < -0.5 * period) d += period;
  return d;
}

double smoothstep01(double t) {
  t = std::clamp(t, 0.0, 1.0);
  return t * t * (3 - 2 * t);
}

struct Domain {
  int gnx, gny;
  double l, lx, ly;
};

void add_fbm(const erg::v1::Fbm& f, std::uint32_t seed, const Domain& d, const TileGeom& t,
             std::vector<double>& out) {
  for (int o = 0; o < f.octaves(); ++o) {
    const double wavelength = f.wavelength_m() / std::ldexp(1.0, o);
    const int px = std::max(1, static_cast<int>(std::lround(d.lx / (wavelength * f.anisotropy()))));
    const int py = std::max(1, static_cast<int>(std::lround(d.ly / wavelength)));
    const double amp = f.amplitude() * std::pow(f.gain(), o);
    const std::uint32_t s = seed + 1013u * static_cast<std::uint32_t>(o);
    for (int y = 0; y < t.ny; ++y)
      for (int x = 0; x < t.nx; ++x) {
        const double gx = (t.x0 + x + 0.5) / d.gnx, gy = (t.y0 + y + 0.5) / d.gny;
        double n = periodic_gradient_noise(gx * px, gy * py, px, py, s);
        if (f.ridged()) n = 1.0 - 2.0 * std::min(1.0, std::fabs(n));
        out[static_cast<size_t>(y) * t.nx + x] += amp * n;
      }
  }
  for (auto& v : out) v += f.offset();
}

void add_uniform(const erg::v1::UniformRandom& u, std::uint64_t seed, const TileGeom& t,
                 std::vector<double>& out) {
  for (int y = 0; y < t.ny; ++y)
    for (int x = 0; x < t.nx; ++x) {
      const Philox4 r = random4(seed, 0, t.global_index(x, y), RandomStream::kGenerator);
      out[static_cast<size_t>(y) * t.nx + x] +=
          u.min() + (u.max() - u.min()) * u01d(r.v[0], r.v[1]);
    }
}

double pile_height(const erg::v1::Pile& p, double dist) {
  const double r = p.radius_m();
  switch (p.shape()) {
    case erg::v1::Pile::GAUSSIAN: {
      const double s = 0.5 * r;
      return p.height() * std::exp(-dist * dist / (2 * s * s));
    }
    case erg::v1::Pile::CYLINDER:
      return dist <= r ? p.height() : 0.0;
    default:
      return p.height() * std::max(0.0, 1.0 - dist / r);
  }
}

void add_piles(const erg::v1::Layer& layer, const Domain& d, const TileGeom& t,
               std::vector<double>& out) {
  for (const auto& p : layer.piles())
    for (int y = 0; y < t.ny; ++y)
      for (int x = 0; x < t.nx; ++x) {
        const double cx = (t.x0 + x + 0.5) * d.l, cy = (t.y0 + y + 0.5) * d.l;
        const double dx = wrap_delta(cx - p.x_m(), d.lx), dy = wrap_delta(cy - p.y_m(), d.ly);
        out[static_cast<size_t>(y) * t.nx + x] += pile_height(p, std::hypot(dx, dy));
      }
}

// Disks with centres from a counter-based sequence; their number gives the
// target coverage in expectation for a Poisson process of disks:
// coverage = 1 - exp(-n pi r^2 / A).
void add_patches(const erg::v1::SandPatches& sp, std::uint64_t seed, const Domain& d,
                 const TileGeom& t, std::vector<double>& out) {
  const double r = sp.radius_m();
  const double area = d.lx * d.ly;
  const double n_real = -std::log(1.0 - sp.coverage()) * area / (kPi * r * r);
  if (n_real > 5e7)
    throw std::runtime_error("layers.*.patches: " + std::to_string(static_cast<long long>(n_real)) +
                             " disks of radius " + std::to_string(r) +
                             " m are needed for this coverage; use a larger radius_m");
  const long n = std::lround(n_real);
  // Buckets at least 2 r wide: a disk reaches only its bucket's neighbours.
  const int bx = std::max(1, static_cast<int>(d.lx / (2 * r)));
  const int by = std::max(1, static_cast<int>(d.ly / (2 * r)));
  // The disks of the last call, kept: a tile is generated in bands
  // (sim/simulation.h initial_rows), each of which needs the same disks.
  struct Disks {
    std::uint64_t seed = 0;
    long n = -1;
    int bx = 0, by = 0;
    double lx = 0, ly = 0;
    std::vector<std::vector<std::pair<double, double>>> buckets;
  };
  static thread_local Disks cache;
  if (cache.seed != seed || cache.n != n || cache.bx != bx || cache.by != by || cache.lx != d.lx ||
      cache.ly != d.ly) {
    cache = Disks{seed, n, bx, by, d.lx, d.ly, {}};
    cache.buckets.resize(static_cast<size_t>(bx) * by);
    for (long k = 0; k < n; ++k) {
      const Philox4 rr = random4(seed, 1, static_cast<std::uint64_t>(k), RandomStream::kPatches);
      const double cx = u01d(rr.v[0], rr.v[1]) * d.lx, cy = u01d(rr.v[2], rr.v[3]) * d.ly;
      const int ix = std::min(bx - 1, static_cast<int>(cx / d.lx * bx));
      const int iy = std::min(by - 1, static_cast<int>(cy / d.ly * by));
      cache.buckets[static_cast<size_t>(iy) * bx + ix].emplace_back(cx, cy);
    }
  }
  const auto& buckets = cache.buckets;
  const double inner = std::max(0.0, r - sp.falloff_m());
  for (int y = 0; y < t.ny; ++y)
    for (int x = 0; x < t.nx; ++x) {
      const double px = (t.x0 + x + 0.5) * d.l, py = (t.y0 + y + 0.5) * d.l;
      const int ix = std::min(bx - 1, static_cast<int>(px / d.lx * bx));
      const int iy = std::min(by - 1, static_cast<int>(py / d.ly * by));
      double h = 0;
      // Visit each distinct neighbouring bucket once (few buckets wrap onto
      // the same one on small domains).
      int seen[9];
      int nseen = 0;
      for (int oy = -1; oy <= 1; ++oy)
        for (int ox = -1; ox <= 1; ++ox) {
          const int b = ((iy + oy + by) % by) * bx + ((ix + ox + bx) % bx);
          if (std::find(seen, seen + nseen, b) != seen + nseen) continue;
          seen[nseen++] = b;
          for (const auto& [cx, cy] : buckets[static_cast<size_t>(b)]) {
            const double dist = std::hypot(wrap_delta(px - cx, d.lx), wrap_delta(py - cy, d.ly));
            if (dist >= r) continue;
            h += sp.height() * (dist <= inner ? 1.0 : smoothstep01((r - dist) / (r - inner)));
          }
        }
      out[static_cast<size_t>(y) * t.nx + x] += h;
    }
}

void add_map(const erg::v1::MapFile& m, const erg::v1::JobSpec& spec, const TileGeom& t,
             const std::string& base_dir, std::vector<double>& out) {
  io::Map map;
  try {
    map = job::load_map(m, spec, base_dir);
  } catch (const job::MapError& e) {
    throw std::runtime_error("map" + std::string(e.what()));
  }
  for (int y = 0; y < t.ny; ++y)
    for (int x = 0; x < t.nx; ++x) {
      const size_t g = static_cast<size_t>(t.y0 + y) * map.nx + static_cast<size_t>(t.x0 + x);
      out[static_cast<size_t>(y) * t.nx + x] += m.offset() + m.scale() * map.values[g];
    }
}

}  // namespace

std::vector<double> generate_layer(const erg::v1::Layer& layer, LayerKind kind,
                                   const erg::v1::JobSpec& spec, const TileGeom& tile,
                                   const std::string& base_dir) {
  std::vector<double> out(static_cast<size_t>(tile.nx) * tile.ny, 0.0);
  const Domain d{tile.gnx, tile.gny, spec.domain().cell_size_m(),
                 tile.gnx * spec.domain().cell_size_m(), tile.gny * spec.domain().cell_size_m()};
  const std::uint64_t salt = static_cast<std::uint64_t>(kind) << 40;
  if (layer.has_constant())
    for (auto& v : out) v += layer.constant();
  if (layer.has_fbm())
    add_fbm(layer.fbm(),
            static_cast<std::uint32_t>(static_cast<std::uint64_t>(spec.seed()) * 2654435761u +
                                       static_cast<std::uint32_t>(kind) * 97u +
                                       static_cast<std::uint64_t>(layer.fbm().seed_offset())),
            d, tile, out);
  if (layer.has_uniform())
    add_uniform(layer.uniform(),
                spec.seed() ^ salt ^ static_cast<std::uint64_t>(layer.uniform().seed_offset()),
                tile, out);
  if (layer.has_patches())
    add_patches(layer.patches(),
                spec.seed() ^ salt ^ static_cast<std::uint64_t>(layer.patches().seed_offset()), d,
                tile, out);
  if (layer.piles_size() > 0) add_piles(layer, d, tile, out);
  if (layer.has_map()) add_map(layer.map(), spec, tile, base_dir, out);
  return out;
}

std::vector<obstacles::Shape> obstacle_shapes(const erg::v1::Obstacle& o, double lx_m,
                                              double ly_m) {
  std::vector<obstacles::Shape> out;
  const auto h = static_cast<float>(o.height_m());
  switch (o.shape_case()) {
    case erg::v1::Obstacle::kDisk:
      out.push_back({obstacles::kDisk, o.disk().x_m(), o.disk().y_m(), 0, 0, o.disk().radius_m(), h,
                     lx_m, ly_m});
      break;
    case erg::v1::Obstacle::kRect:
      out.push_back({obstacles::kRect, o.rect().x_m(), o.rect().y_m(), o.rect().size_x_m(),
                     o.rect().size_y_m(), 0, h, lx_m, ly_m});
      break;
    case erg::v1::Obstacle::kRoad: {
      const auto& r = o.road();
      for (int k = 0; k + 1 < r.points_size(); ++k)
        out.push_back({obstacles::kCapsule, r.points(k).x_m(), r.points(k).y_m(),
                       r.points(k + 1).x_m(), r.points(k + 1).y_m(), 0.5 * r.width_m(), h, lx_m,
                       ly_m});
      break;
    }
    default:
      break;
  }
  return out;
}

std::vector<double> generate_obstacles(const erg::v1::Obstacles& obs, const erg::v1::JobSpec& spec,
                                       const TileGeom& tile, const std::string& base_dir) {
  std::vector<double> out(static_cast<size_t>(tile.nx) * tile.ny, 0.0);
  if (obs.has_map()) {
    add_map(obs.map(), spec, tile, base_dir, out);
    for (auto& v : out) v = std::max(v, 0.0);
  }
  const double l = spec.domain().cell_size_m();
  const double lx = tile.gnx * l, ly = tile.gny * l;
  for (const auto& o : obs.shapes())
    for (const obstacles::Shape& s : obstacle_shapes(o, lx, ly))
      for (int y = 0; y < tile.ny; ++y)
        for (int x = 0; x < tile.nx; ++x) {
          const double px = (tile.x0 + x + 0.5) * l, py = (tile.y0 + y + 0.5) * l;
          double& v = out[static_cast<size_t>(y) * tile.nx + x];
          if (obstacles::covers(s, px, py)) v = std::max(v, static_cast<double>(s.height_m));
        }
  return out;
}

}  // namespace erg::init
