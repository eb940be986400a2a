#!/usr/bin/env python3
# SPDX-License-Identifier: Apache-2.0
"""Weak-scaling model of erg to 4096 GPUs and 4096 CPU nodes, and the cost
of the sand sea (sand_sea.json: 80640 x 80640 cells of 10 m, 650,000 km^2)
on N GPUs or N nodes. Every input is marked MEASURED (on the 2-core
development machine, with the command in README "Performance") or ASSUMED
(with where the number comes from). Run: python3 examples/sand_sea/estimate.py
"""
import math

# ---- inputs -------------------------------------------------------------------
INPUTS = {
    # MEASURED: erg-bench --scene A --size 1024 --steps 30 --warmup 5 --threads 2
    # (README "Performance"): 30.5 ms per step for 1024^2 cells on 2 cores.
    "cpu_ns_per_cell_2cores": (30.5e6 / 1024**2, "measured"),
    # MEASURED: the roofline of the same run, 12.5 ms at the STREAM triad's
    # 26-29 GB/s: bytes moved per cell and step.
    "bytes_per_cell_step": (12.5e-3 * 27.5e9 / 1024**2, "measured"),
    # MEASURED: peak resident bytes per cell, CPU backend, --ranks 2, 16384^2
    # cells (README "Memory": 51 at peak and while stepping, a job without
    # vegetation, resistance or obstacles, as sand_sea.json).
    "peak_bytes_per_cell": (51.0, "measured"),
    "stepping_bytes_per_cell": (51.0, "measured"),
    # MEASURED: halo messages per rank and step at 16, 32 and 64 ranks
    # (e2e.Ranks/ManyRanks.*: the same at every P; the Exchange counters).
    "messages_per_rank_step": (20.0, "measured"),
    # COMPUTED from the halo widths and CROSS-CHECKED against the measured
    # bytes of 2-rank runs (README "Scaling"): 10.1 MB per step for an
    # 8192^2 tile at 1 m cells (scene A's physics), proportional to the
    # tile's side; plus the coarse wind window, 7.0 MB from 8 neighbours.
    "halo_bytes_8192": (10.1e6 + 7.0e6, "computed"),
    # MEASURED: 763.3 steps per simulated year for sand_sea.json
    # (`erg check examples/sand_sea/sand_sea.json`: the calibrated step,
    # 4.134e4 s, at the rose's reference shear velocity).
    "steps_per_year": (763.3, "measured"),
    # ASSUMED: GPU compute. No GPU was available. [N24]'s CUDA code runs
    # scene A at 1024^2 in 1.0 ms per step on an RTX 4080: 0.95 ns per cell
    # and step. A data-centre GPU (H100/H200, 3.4-4.8 TB/s against the 4080's
    # 0.72 TB/s) would be faster; we keep the 4080's number.
    "gpu_ns_per_cell": (1.0e6 / 1024**2, "assumed (N24, RTX 4080)"),
    # ASSUMED: GPU memory per cell: the registry's 60 bytes of fields, each
    # its own device buffer, plus work buffers and halo frames (not
    # measured: no GPU here; kept conservative).
    "gpu_bytes_per_cell": (110.0, "assumed (registry fields + work buffers + frames)"),
    "gpu_memory_bytes": (141e9, "assumed (H200, 141 GB)"),
    # ASSUMED: a CPU node of 64 cores with 300 GB/s of STREAM bandwidth (two
    # sockets of DDR5); its step is the larger of 32 x the 2-core compute
    # and the bytes per cell over its bandwidth.
    "node_cores": (64, "assumed"),
    "node_bandwidth": (300e9, "assumed (2-socket DDR5 node)"),
    "node_memory_bytes": (512e9, "assumed"),
    # ASSUMED: InfiniBand HDR, one 200 Gb/s port per GPU or node: 25 GB/s,
    # 1 us MPI latency (NVIDIA ConnectX-6 HDR: 200 Gb/s, sub-microsecond
    # switch-to-switch latency); host staging of GPU halos over PCIe 4.0
    # x16, 25 GB/s, 4 x the message bytes (pack, copy out, copy in, unpack:
    # worker/dist/halo_frame.h).
    "link_bytes_per_s": (25e9, "assumed (IB HDR 200 Gb/s)"),
    "latency_s": (1e-6, "assumed (IB HDR)"),
    "pcie_bytes_per_s": (25e9, "assumed (PCIe 4.0 x16)"),
    # ASSUMED: 3 small collectives per step (avalanching logical ors, rank
    # 0's decision broadcast), each 2 log2(P) latencies.
    "collectives_per_step": (3, "assumed (counted in Simulation::step and the runner)"),
}


def v(name):
    return INPUTS[name][0]


def halo_time(tile_side, gpu):
    bytes_ = v("halo_bytes_8192") * tile_side / 8192
    t = v("messages_per_rank_step") * v("latency_s") + bytes_ / v("link_bytes_per_s")
    if gpu:
        t += 4 * bytes_ / v("pcie_bytes_per_s")
    return t


def collective_time(p):
    return v("collectives_per_step") * 2 * math.log2(p) * v("latency_s") if p > 1 else 0.0


def node_ns_per_cell():
    compute = v("cpu_ns_per_cell_2cores") * 2 / v("node_cores")
    memory = v("bytes_per_cell_step") / v("node_bandwidth") * 1e9
    return max(compute, memory)


def step_time(cells_per_rank, p, gpu):
    side = math.sqrt(cells_per_rank)
    compute = cells_per_rank * (v("gpu_ns_per_cell") if gpu else node_ns_per_cell()) * 1e-9
    comm = (halo_time(side, gpu) if p > 1 else 0.0) + collective_time(p)
    return compute, comm


def weak_scaling():
    print("Weak scaling, 8192^2 cells per GPU or node (scene A physics, 1 m cells)\n")
    print("| P | domain | GPU step | GPU efficiency | node step | node efficiency |")
    print("|---|---|---|---|---|---|")
    cells = 8192**2
    base = {g: sum(step_time(cells, 1, g)) for g in (True, False)}
    for p in (1, 4, 16, 64, 256, 1024, 4096):
        side = int(8192 * math.sqrt(p))
        row = [str(p), f"{side}²"]
        for g in (True, False):
            t = sum(step_time(cells, p, g))
            row += [f"{t * 1e3:.1f} ms", f"{base[g] / t * 100:.0f} %"]
        print("| " + " | ".join(row) + " |")


def sand_sea():
    cells = 80640**2
    print(f"\nSand sea: {cells:.3g} cells of 10 m ({cells * 100 / 1e6:,.0f} km^2), "
          f"{v('steps_per_year'):.0f} steps per simulated year\n")
    print("| N | GPU memory each | GPU time per simulated year | node memory each | "
          "node time per simulated year |")
    print("|---|---|---|---|---|")
    for n in (16, 64, 256, 1024, 4096):
        per = cells / n
        g = sum(step_time(per, n, True)) * v("steps_per_year")
        c = sum(step_time(per, n, False)) * v("steps_per_year")
        gm = per * v("gpu_bytes_per_cell")
        nm = per * v("peak_bytes_per_cell")
        fits_g = "" if gm < v("gpu_memory_bytes") else " (does not fit)"
        fits_n = "" if nm < v("node_memory_bytes") else " (does not fit)"
        print(f"| {n} | {gm / 1e9:.1f} GB{fits_g} | {fmt(g)} | {nm / 1e9:.1f} GB{fits_n} | "
              f"{fmt(c)} |")


def fmt(s):
    if s < 120:
        return f"{s:.0f} s"
    if s < 7200:
        return f"{s / 60:.0f} min"
    return f"{s / 3600:.1f} h"


if __name__ == "__main__":
    print("Inputs:")
    for k, (val, how) in INPUTS.items():
        print(f"  {k} = {val:.4g}  [{how}]")
    print()
    weak_scaling()
    sand_sea()
