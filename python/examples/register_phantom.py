#!/usr/bin/env python3
"""Render three C-arm X-rays of a femur phantom, start from a perturbed pose, register, print errors.

    PYTHONPATH=build/python python3 python/examples/register_phantom.py [--size 64] [--pixels 256]

The Python twin of `fluoro demo` (docs/python.md), on a smaller phantom so that it runs in seconds.
"""
import argparse
import time

import numpy as np

import fluoro


def main(size=64, pixels=256, start_mm=5.0, backend_name="cpu", verbose=True):
    t0 = time.perf_counter()
    phantom = fluoro.make_phantom("femur", size=size, fiducials=True)
    backend = fluoro.make_backend(backend_name)
    mu = backend.upload(fluoro.hu_to_attenuation(phantom.hu))

    # The truth and three views (AP, 60 degrees oblique, lateral tilted 15 degrees towards the head).
    truth = fluoro.pose([0.05, -0.03, 0.10], [4.0, -3.0, 6.0])
    pixel_mm = 0.6 * 512 / pixels
    cameras = [fluoro.c_arm_view(0, pixels=pixels, pixel_mm=pixel_mm),
               fluoro.c_arm_view(60, pixels=pixels, pixel_mm=pixel_mm),
               fluoro.c_arm_view(100, 15, pixels=pixels, pixel_mm=pixel_mm)]
    drrs = backend.drr(mu, truth, cameras, step_mm=0.5)  # (3, pixels, pixels) line integrals
    views = []
    for name, drr, camera in zip(["ap", "oblique60", "lateral_tilted"], drrs, cameras):
        a, b = fluoro.display_mapping(drr, 1000.0)
        views.append((name, fluoro.drr_to_xray(drr, a, b), camera))  # log domain, bone dark

    # A start pose start_mm from the truth (mean distance over the bone surface).
    surface = fluoro.surface_points(phantom.hu, 250, 2000)
    start = fluoro.start_pose_at_distance(truth, surface, fluoro.mean_point(surface), start_mm, seed=2026)

    reg = fluoro.PreparedRegistration(backend, phantom.hu, views)
    report = reg.run(start)
    before = fluoro.registration_errors(start, truth, surface, phantom.fiducials, cameras)
    after = fluoro.registration_errors(report.pose, truth, surface, phantom.fiducials, cameras)
    if verbose:
        print(f"fluoro {fluoro.__version__}, backend {backend.name}, phantom {size}^3, X-rays {pixels}^2")
        print(f"before: {before}")
        print(f"after:  {after}")
        print(f"report: {report}")
        for s in report.stages:
            print(f"  {s}")
        print(f"preparation {reg.preparation_seconds:.2f} s, registration {report.seconds:.2f} s, "
              f"whole script {time.perf_counter() - t0:.2f} s")
    return before, after, report


if __name__ == "__main__":
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--size", type=int, default=64, help="phantom voxels per side")
    p.add_argument("--pixels", type=int, default=256, help="X-ray pixels per side")
    p.add_argument("--start-mm", type=float, default=5.0, help="start distance from the truth, mm")
    p.add_argument("--backend", default="cpu")
    a = p.parse_args()
    main(a.size, a.pixels, a.start_mm, a.backend)
