// SPDX-License-Identifier: Apache-2.0
// The CUDA backend's halo packer (backend/cuda/device_packer.h), the one a
// CUDA-aware MPI gets, under mpirun (label gpu: it needs a device). The
// MPI library need not be CUDA-aware: the message buffers are managed
// memory, which any MPI can read. Fields on the device exchanged through it
// must end bit for bit as the same fields exchanged on the host: fill,
// split fill with kernels in between, and sum, for int64 and float fields
// of different widths in one list, on 1, 2 and 4 ranks.
#include <cuda_runtime_api.h>
#include <gtest/gtest.h>
#include <mpi.h>

#include <cstdint>
#include <cstring>
#include <memory>
#include <string>
#include <vector>

#include "backend/cuda/device_packer.h"
#include "dist/decomposition.h"
#include "dist/halo.h"

namespace erg {
namespace {

#define CHECK_CUDA(call) ASSERT_EQ((call), cudaSuccess) << #call

// A device copy of a host field (same layout).
template <class T>
class OnDevice {
 public:
  explicit OnDevice(const Field<T>& h) : n_(h.size()) {
    if (cudaMalloc(reinterpret_cast<void**>(&p_), n_ * sizeof(T)) != cudaSuccess) p_ = nullptr;
    if (p_) cudaMemcpy(p_, h.data(), n_ * sizeof(T), cudaMemcpyHostToDevice);
  }
  ~OnDevice() {
    if (p_) cudaFree(p_);
  }
  OnDevice(const OnDevice&) = delete;
  OnDevice& operator=(const OnDevice&) = delete;
  T* get() { return p_; }
  Field<T> to_host(const TileGeom& g) const {
    Field<T> h(g);
    cudaMemcpy(h.data(), p_, n_ * sizeof(T), cudaMemcpyDeviceToHost);
    return h;
  }

 private:
  T* p_ = nullptr;
  std::size_t n_;
};

template <class T>
bool same_bits(const Field<T>& a, const Field<T>& b) {
  return a.size() == b.size() && std::memcmp(a.data(), b.data(), a.size() * sizeof(T)) == 0;
}

// Every stored cell a value of its own (owned: by global index; ghosts and
// padding: by rank and position, so that a sum has something to add).
template <class T>
Field<T> values(const TileGeom& g, int rank, int salt) {
  Field<T> f(g);
  for (int y = -g.halo; y < g.ny + g.halo; ++y)
    for (int x = -g.halo; x < g.pitch - g.halo; ++x) {
      const bool owned = x >= 0 && x < g.nx && y >= 0 && y < g.ny;
      const long long k = owned ? static_cast<long long>(g.global_index(x, y))
                                : 1000000LL + rank * 100000LL + (y + 64) * 256LL + (x + 64);
      f(x, y) = static_cast<T>((k * 7 + salt) % 4093 - 2000) + static_cast<T>(salt % 2) / 2;
    }
  return f;
}

class CudaHalo : public ::testing::Test {
 protected:
  void SetUp() override {
    int size = 1;
    MPI_Comm_size(MPI_COMM_WORLD, &size);
    MPI_Comm_rank(MPI_COMM_WORLD, &rank_);
    const dist::Decomposition d = dist::decompose(48, 40, size, 1, 0, 0);
    int dims[2] = {d.px, d.py}, periods[2] = {1, 1}, coords[2] = {0, 0};
    MPI_Cart_create(MPI_COMM_WORLD, 2, dims, periods, 0, &cart_);
    int r = 0;
    MPI_Comm_rank(cart_, &r);
    MPI_Cart_coords(cart_, r, 2, coords);
    g_.nx = d.nx(coords[0]);
    g_.ny = d.ny(coords[1]);
    g_.halo = 6;
    g_.pitch = padded_pitch(g_.nx, g_.halo);
    g_.x0 = d.x0(coords[0]);
    g_.y0 = d.y0(coords[1]);
    g_.gnx = d.gnx;
    g_.gny = d.gny;
  }
  void TearDown() override {
    MPI_Comm_free(&cart_);
    int mine = HasFailure() ? 1 : 0, any = 0;
    MPI_Allreduce(&mine, &any, 1, MPI_INT, MPI_MAX, MPI_COMM_WORLD);
    if (any && !mine) ADD_FAILURE() << "failed on another rank";
  }
  int rank_ = 0;
  MPI_Comm cart_ = MPI_COMM_NULL;
  TileGeom g_;
};

TEST_F(CudaHalo, DevicePackerGivesTheHostExchangesBits) {
  int devices = 0;
  ASSERT_EQ(cudaGetDeviceCount(&devices), cudaSuccess);
  ASSERT_GT(devices, 0);
  dist::HaloExchanger hx(cart_, g_);
  cudaStream_t stream = nullptr;
  CHECK_CUDA(cudaStreamCreateWithFlags(&stream, cudaStreamNonBlocking));
  const std::unique_ptr<dist::HaloPacker> packer = gpu::make_device_packer(stream, true);
  const int w64 = 5, w32 = 3;
  for (const dist::GhostOp op :
       {dist::GhostOp::kFill, dist::GhostOp::kBeginFill, dist::GhostOp::kSum}) {
    const int salt = static_cast<int>(op) + 1;
    Field<std::int64_t> want64 = values<std::int64_t>(g_, rank_, salt);
    Field<float> want32 = values<float>(g_, rank_, salt);
    OnDevice<std::int64_t> d64(want64);
    OnDevice<float> d32(want32);
    ASSERT_TRUE(d64.get() && d32.get());
    // Host fields naming type and geometry; the host exchange of the same
    // values is the reference.
    Field<std::int64_t> name64(g_);
    Field<float> name32(g_);
    const dist::Ghosts list[2] = {{&name64, w64, d64.get()}, {&name32, w32, d32.get()}};
    const dist::Ghosts host[2] = {{&want64, w64}, {&want32, w32}};
    if (op == dist::GhostOp::kSum) {
      hx.sum(host);
    } else {
      hx.fill(host);
    }
    hx.set_packer(packer.get());
    if (op == dist::GhostOp::kSum) {
      hx.sum(list);
    } else if (op == dist::GhostOp::kFill) {
      hx.fill(list);
    } else {
      hx.begin_fill(list);
      CHECK_CUDA(cudaDeviceSynchronize());  // the backend's stages run here
      hx.finish_fill(list);
    }
    hx.set_packer(nullptr);
    CHECK_CUDA(cudaStreamSynchronize(stream));
    const std::string what = "op " + std::to_string(static_cast<int>(op));
    EXPECT_TRUE(same_bits(d64.to_host(g_), want64)) << what << " int64";
    EXPECT_TRUE(same_bits(d32.to_host(g_), want32)) << what << " float";
  }
  CHECK_CUDA(cudaStreamDestroy(stream));
}

}  // namespace
}  // namespace erg

int main(int argc, char** argv) {
  MPI_Init(&argc, &argv);
  ::testing::InitGoogleTest(&argc, argv);
  int rank = 0;
  MPI_Comm_rank(MPI_COMM_WORLD, &rank);
  if (rank != 0) {
    ::testing::TestEventListeners& l = ::testing::UnitTest::GetInstance()->listeners();
    delete l.Release(l.default_result_printer());
  }
  const int mine = RUN_ALL_TESTS();
  int worst = 0;
  MPI_Allreduce(&mine, &worst, 1, MPI_INT, MPI_MAX, MPI_COMM_WORLD);
  MPI_Finalize();
  return worst;
}
