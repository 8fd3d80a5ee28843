#!/usr/bin/env python3
"""The binding's overhead per drr call against the same call made from C++ (docs/python.md).

    PYTHONPATH=build/python python3 python/bench_overhead.py [--size 256] [--pixels 256] [--poses 8] [--rounds 7]

One process, one backend, one uploaded volume: each round times `repeats` Python calls
(backend.drr: pose conversion, GIL release, the call, the (N, H, W) array) and then `repeats`
C++ calls of Backend::drr timed from C++ (fluoro._drr_seconds_in_cpp), alternating so that both
see the same machine load. Prints the medians and the overhead (Python - C++) / C++.
"""
import argparse
import statistics
import time

import numpy as np

import fluoro


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
    backend.drr(mu, poses, camera)  # warm up (thread pool, caches)

    py_times, cpp_times = [], []
    for _ in range(a.rounds):
        for _ in range(a.repeats):
            t0 = time.perf_counter()
            out = backend.drr(mu, poses, camera)
            py_times.append(time.perf_counter() - t0)
        assert out.shape == (a.poses, a.pixels, a.pixels)
        cpp_times += fluoro._drr_seconds_in_cpp(backend, mu, poses, camera, 1.0, a.repeats)
    py, cpp = statistics.median(py_times), statistics.median(cpp_times)
    print(f"drr batch: {a.poses} poses x {a.pixels}^2 pixels, {a.size}^3 femur phantom, backend {backend.name}, "
          f"{len(py_times)} calls per side")
    print(f"  C++ Backend::drr   median {cpp * 1e3:8.3f} ms  (min {min(cpp_times) * 1e3:.3f})")
    print(f"  Python backend.drr median {py * 1e3:8.3f} ms  (min {min(py_times) * 1e3:.3f})")
    print(f"  overhead {(py - cpp) * 1e3:+.3f} ms per call = {100 * (py - cpp) / cpp:+.2f} % (medians), "
          f"{100 * (min(py_times) - min(cpp_times)) / min(cpp_times):+.2f} % (minima)")


if __name__ == "__main__":
    main()
