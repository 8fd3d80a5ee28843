"""The point tools against closed forms: a pivot about a known point, a known rigid transform
recovered by paired points and by ICP, and the Fitzpatrick-West TRE at the fiducials' centroid."""
import numpy as np
import pytest

import fluoro

TRUTH = fluoro.pose([0.3, -0.2, 0.5], [12.0, -7.0, 30.0])


def transform(T, points):
    return points @ T[:3, :3].T + T[:3, 3]


def test_pivot_about_a_known_point():
    rng = np.random.default_rng(1)
    tip, pivot = np.array([3.0, -2.0, 150.0]), np.array([100.0, 50.0, -20.0])
    poses = []
    for _ in range(12):  # swings of up to ~30 degrees about two axes, the tip held at the pivot
        T = fluoro.pose(np.r_[rng.uniform(-0.5, 0.5, 2), rng.uniform(-1, 1)], [0, 0, 0])
        T[:3, 3] = pivot - T[:3, :3] @ tip
        poses.append(T)
    r = fluoro.pivot_calibration(np.stack(poses))
    assert r.ok and r.poses == 12
    np.testing.assert_allclose(r.tip_in_tool, tip, atol=1e-9)
    np.testing.assert_allclose(r.pivot_in_tracker, pivot, atol=1e-9)
    assert r.rms_mm < 1e-9 and r.rotation_spread_deg > 10

    same_axis = [fluoro.pose([0, 0, a], [0, 0, 0]) for a in (0.1, 0.5, 0.9)]  # the tip's z is free
    r = fluoro.pivot_calibration(np.stack(same_axis))
    assert not r.ok and r.failure_reason


def test_paired_points_recover_a_known_transform():
    rng = np.random.default_rng(2)
    moving = rng.uniform(-50, 50, (6, 3))
    centroid = moving.mean(axis=0)
    r = fluoro.register_points(transform(TRUTH, moving), moving, targets=[centroid, centroid + 100], fle_mm=0.5)
    assert r.ok
    np.testing.assert_allclose(r.T_fixed_moving, TRUTH, atol=1e-9)
    assert r.fre_rms_mm < 1e-9 and r.fle_rms_mm == 0.5 and not r.fle_estimated
    # At the centroid the d_k vanish: TRE = FLE / sqrt(N); away from it the prediction grows.
    assert r.predicted_tre_rms_mm[0] == pytest.approx(0.5 / np.sqrt(6), rel=1e-12)
    assert r.predicted_tre_rms_mm[1] > r.predicted_tre_rms_mm[0]

    weighted = fluoro.register_points(transform(TRUTH, moving), moving, weights=np.arange(1.0, 7.0))
    np.testing.assert_allclose(weighted.T_fixed_moving, TRUTH, atol=1e-9)

    # A given FLE is checked against the residuals: 0.5 mm explains none; a fiducial moved by
    # 5 mm refutes it, with the TRE the residuals' FLE predicts beside.
    assert r.fle_check["consistent"] and weighted.fle_check is None
    moved = transform(TRUTH, moving)
    moved[0] += [5.0, 0.0, 0.0]
    bad = fluoro.register_points(moved, moving, targets=[centroid, centroid + 100], fle_mm=0.5)
    assert bad.ok and not bad.fle_check["consistent"]
    assert bad.fle_check["chi2"] > bad.fle_check["chi2_limit"]
    assert len(bad.fle_check["predicted_tre_rms_mm"]) == 2
    assert bad.fle_check["predicted_tre_rms_mm"][0] > bad.predicted_tre_rms_mm[0]

    with pytest.raises(ValueError, match=r"^moving: 5 points, but fixed has 6: the lists must pair point by point$"):
        fluoro.register_points(moving, moving[:5])
    with pytest.raises(ValueError, match=r"^weights: weight 2 must be a positive number$"):
        fluoro.register_points(moving, moving, weights=[1, 1, 0, 1, 1, 1])
    collinear = np.outer(np.arange(4.0), [1, 2, 3])
    assert not fluoro.register_points(collinear, collinear).ok


def box():
    # A 40 x 60 x 80 mm box: its faces fix all six pose parameters near the truth.
    v = np.array([[x, y, z] for x in (0, 40) for y in (0, 60) for z in (0, 80)], dtype=float)
    quads = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    t = np.array([tri for a, b, c, d in quads for tri in ((a, b, c), (a, c, d))])
    return v, t


def test_icp_recovers_a_known_pose(tmp_path):
    rng = np.random.default_rng(3)
    v, t = box()
    # Points on the faces (model frame): uniform in each triangle, then moved by the truth.
    a, b, c = v[t[:, 0]], v[t[:, 1]], v[t[:, 2]]
    k = rng.integers(0, len(t), 400)
    u = rng.uniform(0, 1, (400, 2))
    u[u.sum(axis=1) > 1] = 1 - u[u.sum(axis=1) > 1]
    model_points = a[k] + u[:, :1] * (b[k] - a[k]) + u[:, 1:] * (c[k] - a[k])
    start = fluoro.pose([0.02, -0.03, 0.01], [2.0, -1.0, 1.5]) @ TRUTH

    r = fluoro.icp(transform(TRUTH, model_points), (v, t), start, keep_fraction=1.0)
    assert r.ok and r.kept == 400 and r.inlier_fraction == 1.0
    np.testing.assert_allclose(r.T_world_model, TRUTH, atol=1e-6)
    assert r.rms_mm < 1e-6

    obj = tmp_path / "box.obj"  # the same mesh as a file gives the same result, bit for bit
    obj.write_text("".join(f"v {x!r} {y!r} {z!r}\n" for x, y, z in v) +
                   "".join(f"f {i + 1} {j + 1} {k + 1}\n" for i, j, k in t))
    from_file = fluoro.icp(transform(TRUTH, model_points), str(obj), start, keep_fraction=1.0)
    assert np.array_equal(from_file.T_world_model, r.T_world_model)

    with pytest.raises(ValueError, match=r"^mesh triangles: triangle 0 has vertex index 8, not one of the 8 vertices$"):
        fluoro.icp(model_points, (v, np.array([[0, 1, 8]])))
    with pytest.raises(ValueError, match=r"^keep_fraction: must be in \(0, 1\]$"):
        fluoro.icp(model_points, (v, t), keep_fraction=0)
