#!/usr/bin/env python3
"""The binding's overhead per drr call against the same call made from C++ (docs/python.md).

    PYTHONPATH=build/python python3 python/bench_overhead.py [--size 256] [--pixels 256] [--poses 8] [--rounds 7]

One process, one backend, one uploaded volume. Two measures:
1. direct: each round times `repeats` Python calls (backend.drr: pose conversion, GIL release, the
   call, the (N, H, W) array) and then `repeats` C++ calls of Backend::drr timed from C++
   (fluoro._drr_seconds_in_cpp), alternating so that both see the same machine load. The
   difference of the medians is the overhead, within the noise of the kernel's own time.
2. decomposed, robust to load: the overhead's fixed part is the same comparison with a one-pixel
   window (the kernel does almost nothing, the Python work is the same but the copy), and its
   part that grows with the pixels is the copy of the batch into the array, timed as np.copy of
   an array of that size.
"""
import argparse
import statistics
import time

import numpy as np

import fluoro


def alternate(backend, mu, poses, camera, rounds, repeats, window=None):
    py_times, cpp_times = [], []
    for _ in range(rounds):
        for _ in range(repeats):
            t0 = time.perf_counter()
            backend.drr(mu, poses, camera, window=window)
            py_times.append(time.perf_counter() - t0)
        cpp_times += fluoro._drr_seconds_in_cpp(backend, mu, poses, camera, 1.0, repeats, window)
    return py_times, cpp_times


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--size", type=int, default=256, help="phantom voxels per side")
    p.add_argument("--pixels", type=int, default=256, help="DRR pixels per side")
    p.add_argument("--poses", type=int, default=8, help="poses per batch")
    p.add_argument("--rounds", type=int, default=7)
    p.add_argument("--repeats", type=int, default=5, help="calls per round and side")
    p.add_argument("--backend", default="cpu")
    a = p.parse_args()

    backend = fluoro.make_backend(a.backend)
    mu = backend.upload(fluoro.hu_to_attenuation(fluoro.make_phantom("femur", size=a.size).hu))
    camera = fluoro.c_arm_view(0, pixels=a.pixels, pixel_mm=0.6 * 512 / a.pixels)
    poses = np.stack([fluoro.pose([0, 0, 0.02 * i], [i, 0, 0]) for i in range(a.poses)])
    out = backend.drr(mu, poses, camera)  # warm up (thread pool, caches)
    assert out.shape == (a.poses, a.pixels, a.pixels)

    py_times, cpp_times = alternate(backend, mu, poses, camera, a.rounds, a.repeats)
    py, cpp = statistics.median(py_times), statistics.median(cpp_times)
    print(f"drr batch: {a.poses} poses x {a.pixels}^2 pixels, {a.size}^3 femur phantom, backend {backend.name}")
    print(f"1. direct, {len(py_times)} calls per side:")
    print(f"   C++ Backend::drr   median {cpp * 1e3:9.3f} ms  (min {min(cpp_times) * 1e3:.3f})")
    print(f"   Python backend.drr median {py * 1e3:9.3f} ms  (min {min(py_times) * 1e3:.3f})")
    print(f"   difference {(py - cpp) * 1e3:+.3f} ms = {100 * (py - cpp) / cpp:+.2f} % of the C++ median")

    center = (a.pixels // 2, a.pixels // 2, 1, 1)
    fpy, fcpp = alternate(backend, mu, poses, camera, a.rounds, 20, center)
    fixed = statistics.median(fpy) - statistics.median(fcpp)
    big = np.empty((a.poses, a.pixels, a.pixels), np.float32)
    copies = []
    for _ in range(50):
        t0 = time.perf_counter()
        np.copy(big)
        copies.append(time.perf_counter() - t0)
    copy = statistics.median(copies)
    print(f"2. decomposed: fixed part {fixed * 1e6:.1f} us (one-pixel window: Python {statistics.median(fpy) * 1e6:.1f} us, "
          f"C++ {statistics.median(fcpp) * 1e6:.1f} us), copy of {big.nbytes / 2**20:.1f} MiB {copy * 1e6:.1f} us")
    print(f"   overhead {(fixed + copy) * 1e3:.3f} ms = {100 * (fixed + copy) / cpp:.3f} % of the C++ median")


if __name__ == "__main__":
    main()
