// SPDX-License-Identifier: Apache-2.0
// The CPU backend: OpenMP threads over rows of padded fields. Every stage is
// a gather or an integer scatter, so the result does not depend on the thread
// count (docs/design.md, "Exactness"); inner loops are written to vectorise.
#pragma once

#include <vector>

#include "backend/backend.h"
#include "core/field.h"
#include "dist/exchange.h"
#include "stages/shear_stress.h"
#include "stages/wind_warping.h"

namespace erg::cpu {

// Gaussian smoothing and gradients of one tile's coarse window
// (stages/wind_warping.h: truncated Gaussians, separable, central
// differences), double.
class CoarseSmoother {
 public:
  // tcnx x tcny: the tile's coarse cells.
  CoarseSmoother(const CoarseGrid& c, int tcnx, int tcny);
  // window: the coarse mean heights (metres) of the tile and its coarse halo
  // (Exchange::coarse_window). Fills grad_x[s], grad_y[s] for scale s (0
  // large, 1 small) as float [tcny + 2][tcnx + 2], the tile's coarse cells
  // -1 .. tcn.
  void gradients(const std::vector<double>& window, std::vector<float> grad_x[2],
                 std::vector<float> grad_y[2], int threads);
  wind_warping::TileWindow tile() const { return t_; }

 private:
  CoarseGrid c_;
  wind_warping::TileWindow t_;
  std::vector<double> kx_[2], ky_[2];  // wind_warping::gaussian_kernel per scale and axis
};

class CpuBackend final : public Backend {
 public:
  // `ex` fills ghosts and sums across tiles; it must outlive the backend.
  CpuBackend(const Model& model, int threads, dist::Exchange& ex);
  std::string name() const override { return "cpu"; }
  void upload(const TileState& s) override;
  void download(TileState& s) override;
  void download_owned(fields::Id id, std::vector<float>& out) override;
  void upload_owned(fields::Id id, const std::vector<float>& in) override;
  void download_rows(fields::Id id, int y0, int y1, void* out) override;
  void upload_rows(fields::Id id, int y0, int y1, const void* in) override;
  void upload_done() override;

  void ghosts(GhostOp op, std::span<const FieldGhosts> fields) override;
  void obstacles_changed() override;  // updates any_obstacles_

  void heights() override;
  void wind(Vec2 a) override;
  void perturb_wind(const std::vector<wind_primitives::Batch>& batches) override;
  void shadow() override;
  void saltation_hop(std::int64_t step) override;
  void saltation_impact(std::int64_t step) override;
  void reptation() override;
  AvalancheResult avalanche_sand(const Refill& refill) override;
  void avalanche_bedrock(const Refill& refill) override;

  total_t apply_sand_brush(const events::Brush& b) override;
  total_t apply_bedrock_brush(const events::Brush& b) override;
  void set_vegetation(const events::Region& r) override;
  total_t set_obstacle(const obstacles::Shape& s, bool remove) override;
  Totals totals() override;

 private:
  // One avalanching sweep structure shared by sand and bedrock (avalanching.cpp).
  // settled (optional): set when an iteration moved nothing and no donor is
  // stuck, i.e. running again on the same heights would be the identity.
  AvalancheResult avalanche(bool bedrock, int iterations, const Refill& refill, bool* settled);

  Model m_;
  TileGeom g_;
  int threads_;
  dist::Exchange& ex_;
  // One padded field per registry entry (core/fields.h), by id or by the
  // name the stages use (f_.sand, f_.reptation, ...).
  fields::Named<Field> f_;
  Field<units_t>& units(fields::Id id) { return f_.units[id]; }
  Field<float>& reals(fields::Id id) { return f_.reals[id]; }
  bool any_obstacles_ = false;   // on this tile or its ghosts (saltation's slow path)
  bool bedrock_changed_ = true;  // since bedrock avalanching last found it settled
  // Storage shared between fields whose lifetimes within a step do not
  // overlap (core/fields.h Storage; docs/design.md "Memory"):
  //  - work_, 8 bytes a cell: the surface wind (wind_x, wind_y: its two
  //    float halves) from the wind stage to saltation; reptation's new sand
  //    (sand_next_, int64); avalanching's heights and fractions (h_a_,
  //    frac_: the two halves again);
  //  - spare_, 4 bytes a cell: the wind shadow until saltation's impacts,
  //    which write the reptation strength s_r over it cell by cell; then the
  //    repose tangents (tan_l), recomputed from vegetation when avalanching
  //    begins;
  //  - landed sand, which the impacts replace cell by cell with the
  //    deposited sand (deposited_m) kept for snapshots.
  // What a snapshot reads after its storage was reused, wind and shadow, is
  // computed again from the step's heights and wind (restore_outputs).
  Field<units_t> work_;
  Field<float> spare_;
  Field<units_t>& sand_next_ = work_;
  Field<float> h_a_, frac_;  // views of work_'s halves
  // Avalanching's donor tangents, pass 1 to pass 2: only with model.repose
  // ISOTROPIC (from the 3 x 3 heights; the pairs' tangent is tan_l itself).
  Field<float> tan_d_;
  std::vector<float> no_echo_;  // a row of zeros: echo dunes off, no echo field
  const float* echo_row(int y) { return m_.echo.on ? f_.echo.row(y) : no_echo_.data() + g_.halo; }
  // Whether wind and shadow still hold the last step's values, and what
  // computed them (to compute them again).
  bool wind_valid_ = true, shadow_valid_ = true, wind_ran_ = false;
  bool shadow_of_wind_ = false;  // the last shadow() read the wind wind_valid_ is about
  Vec2 last_a_{};
  std::vector<wind_primitives::Batch> last_batches_;
  void warp_rows(Vec2 a);  // the wind at every owned cell, from the gradients
  void restore_outputs(fields::Id id);
  void repose_tangents();  // tan_l from vegetation, ghosts included
  // wind warping
  CoarseSmoother smoother_;
  std::vector<double> coarse_mine_, window_;  // this tile's coarse cells, with their halo
  std::vector<float> grad_x_[2], grad_y_[2];
  // shear stress over relief (physical modes): taps, e . grad h over the
  // window, tau1 / tau0 at the tile's coarse cells -1 .. tcn
  shear_stress::Kernel shear_kernel_;
  std::vector<double> shear_slope_, shear_slope_perp_;  // along and across the wind
  std::vector<float> shear_tau_, shear_tau_y_;          // tau1 / tau0 and tau_y / tau0
  bool shear_field(Vec2 a);  // wind.cpp: false when there is none (model units, still air)
  bool shear_on_ = false;    // shear_field's answer for the last wind(), which warp_rows reads
  // Coarse interpolation stencils: per column (as arrays) and per row.
  std::vector<int> axis_x_i0_, axis_x_i1_;
  std::vector<float> axis_x_t_;
  std::vector<wind_warping::Axis> axis_y_;
  // shadow: height maxima and minima per block, bounds per block of owned cells
  std::vector<float> block_max_, block_min_, bound_;
};

}  // namespace erg::cpu
