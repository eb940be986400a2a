// SPDX-License-Identifier: Apache-2.0
#include "dist/mpi_exchange.h"

#include <stdexcept>
#include <string>

namespace erg::dist {

namespace {
void check(int rc, const char* what) {
  if (rc == MPI_SUCCESS) return;
  char text[MPI_MAX_ERROR_STRING];
  int n = 0;
  MPI_Error_string(rc, text, &n);
  throw std::runtime_error(std::string(what) + ": " + std::string(text, static_cast<size_t>(n)));
}
}  // namespace

void MpiExchange::ghosts(GhostOp op, std::span<const Ghosts> fields) {
  switch (op) {
    case GhostOp::kFill:
      halo_.fill(fields);
      break;
    case GhostOp::kBeginFill:
      halo_.begin_fill(fields);
      break;
    case GhostOp::kFinishFill:
      halo_.finish_fill(fields);
      break;
    case GhostOp::kSum:
      halo_.sum(fields);
      break;
  }
}

MpiExchange::MpiExchange(MPI_Comm cart, const Decomposition& d, const TileGeom& g, int cx, int cy)
    : cart_(cart), d_(d), cx_(cx), cy_(cy), halo_(cart, g) {
  check(MPI_Comm_size(cart_, &size_), "MPI_Comm_size");
  const int n = size_;
  cx0_.resize(n);
  cy0_.resize(n);
  cnx_.resize(n);
  cny_.resize(n);
  counts_.resize(n);
  displs_.resize(n);
  int offset = 0;
  for (int r = 0; r < n; ++r) {
    int coords[2];
    check(MPI_Cart_coords(cart_, r, 2, coords), "MPI_Cart_coords");
    cx0_[r] = d_.x0(coords[0]) / cx_;
    cy0_[r] = d_.y0(coords[1]) / cy_;
    cnx_[r] = d_.nx(coords[0]) / cx_;
    cny_[r] = d_.ny(coords[1]) / cy_;
    counts_[r] = cnx_[r] * cny_[r];
    displs_[r] = offset;
    offset += counts_[r];
  }
}

// 128-bit totals as two int64 halves (MPI has no 128-bit integer): the low
// 32 bits and the rest, each summed exactly, then recombined. Exact for any
// number of ranks below 2^31.
void MpiExchange::sum_exact(std::vector<total_t>& v) {
  const size_t n = v.size();
  std::vector<long long> parts(2 * n), sums(2 * n);
  for (size_t i = 0; i < n; ++i) {
    parts[2 * i] = static_cast<long long>(static_cast<unsigned long long>(v[i]) & 0xffffffffull);
    parts[2 * i + 1] = static_cast<long long>(v[i] >> 32);
  }
  check(MPI_Allreduce(parts.data(), sums.data(), static_cast<int>(2 * n), MPI_LONG_LONG, MPI_SUM,
                      cart_),
        "MPI_Allreduce (exact sums)");
  for (size_t i = 0; i < n; ++i)
    v[i] = static_cast<total_t>(sums[2 * i + 1]) * (static_cast<total_t>(1) << 32) + sums[2 * i];
}

bool MpiExchange::any(bool local) {
  int in = local ? 1 : 0, out = 0;
  check(MPI_Allreduce(&in, &out, 1, MPI_INT, MPI_LOR, cart_), "MPI_Allreduce (any)");
  return out != 0;
}

void MpiExchange::gather_coarse(const std::vector<double>& mine, std::vector<double>& all) {
  int rank = 0;
  check(MPI_Comm_rank(cart_, &rank), "MPI_Comm_rank");
  if (static_cast<int>(mine.size()) != counts_[rank])
    throw std::logic_error(
        "gather_coarse: this tile's coarse cells do not match the decomposition");
  std::vector<double> packed(static_cast<size_t>(displs_.back() + counts_.back()));
  check(MPI_Allgatherv(mine.data(), counts_[rank], MPI_DOUBLE, packed.data(), counts_.data(),
                       displs_.data(), MPI_DOUBLE, cart_),
        "MPI_Allgatherv (coarse wind grid)");
  const int gcnx = d_.gnx / cx_, gcny = d_.gny / cy_;
  all.assign(static_cast<size_t>(gcnx) * gcny, 0.0);
  for (int r = 0; r < size_; ++r)
    for (int J = 0; J < cny_[r]; ++J)
      for (int I = 0; I < cnx_[r]; ++I)
        all[static_cast<size_t>(cy0_[r] + J) * gcnx + (cx0_[r] + I)] =
            packed[static_cast<size_t>(displs_[r]) + static_cast<size_t>(J) * cnx_[r] + I];
}

}  // namespace erg::dist
