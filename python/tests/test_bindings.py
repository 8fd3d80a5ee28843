"""The Python bindings against the fluoro program and against the documented shapes, orientation,
dtypes and error messages (docs/python.md)."""
import numpy as np
import pytest

import fluoro


def small_camera(orbit_deg=30, pixels=64):
    return fluoro.c_arm_view(orbit_deg, pixels=pixels, pixel_mm=0.6 * 512 / pixels)


TRUTH = fluoro.pose([0.05, -0.03, 0.10], [4.0, -3.0, 6.0])


def test_version_is_the_programs(cli):
    assert cli("--version").stdout == f"fluoro {fluoro.__version__}\n"
    assert len(fluoro.__version__.split(".")) == 3


def test_phantom_is_the_programs_bit_for_bit(cli, tmp_path):
    cli("phantom", "--kind", "pelvis", "--size", 40, "--out", tmp_path / "p.nii.gz")
    from_file = fluoro.read_volume(str(tmp_path / "p.nii.gz"))
    phantom = fluoro.make_phantom("pelvis", size=40)
    assert phantom.hu.array.dtype == np.float32 and phantom.hu.array.shape == (40, 40, 40)
    assert np.array_equal(from_file.array, phantom.hu.array)
    assert np.allclose(from_file.spacing, phantom.hu.spacing) and np.allclose(from_file.origin, phantom.hu.origin)
    assert phantom.hu.array.max() > 1000  # bone


@pytest.mark.parametrize("backend,step", [("cpu", 1.0), ("reference", 2.0)])
def test_drr_is_the_programs_bit_for_bit(cli, tmp_path, backend, step):
    ct, cam, pose, out = (str(tmp_path / n) for n in ("ct.nii.gz", "cam.json", "pose.json", "drr.tif"))
    fluoro.write_volume(fluoro.make_phantom("femur", size=48).hu, ct)
    camera = small_camera()
    fluoro.write_camera(camera, cam)
    fluoro.write_pose(TRUTH, pose)
    cli("drr", "--ct", ct, "--camera", cam, "--pose", pose, "--out", out, "--backend", backend, "--step", step)
    expected = fluoro.read_image(out)

    b = fluoro.make_backend(backend)
    drr = b.drr(b.upload(fluoro.hu_to_attenuation(fluoro.read_volume(ct))), TRUTH, fluoro.read_camera(cam), step_mm=step)
    assert drr.dtype == np.float32 and drr.shape == (64, 64)
    assert drr.max() > 2.0  # 100 mm of water-equivalent path: the phantom is in view
    assert np.array_equal(drr, expected)


def test_batch_shapes_and_pose_forms():
    b = fluoro.make_backend("cpu")
    mu = b.upload(fluoro.hu_to_attenuation(fluoro.make_phantom("femur", size=48).hu))
    cams = [small_camera(0, 48), small_camera(90, 48)]
    poses = np.stack([TRUTH, fluoro.pose([0, 0, 0.2], [0, 0, 0]), np.eye(4)])
    batch = b.drr(mu, poses, cams)
    assert batch.shape == (3, 2, 48, 48) and batch.dtype == np.float32 and batch.flags.c_contiguous
    for p in range(3):
        for v in range(2):
            assert np.array_equal(batch[p, v], b.drr(mu, poses[p], cams[v]))
    assert b.drr(mu, poses, cams[0]).shape == (3, 48, 48)
    assert b.drr(mu, TRUTH, cams).shape == (2, 48, 48)
    assert np.array_equal(b.drr(mu, TRUTH[:3], cams[0]), b.drr(mu, TRUTH, cams[0]))  # (3, 4) is [R | t]
    win = b.drr(mu, TRUTH, cams[0], window=(10, 5, 20, 8))
    assert win.shape == (8, 20)
    assert np.array_equal(win, b.drr(mu, TRUTH, cams[0])[5:13, 10:30])


@pytest.mark.parametrize("direction", [np.eye(3), np.array([[0, 0, 1], [-1, 0, 0], [0, -1, 0]], dtype=float)])
def test_orientation_index_order_and_rows(direction):
    # A bright 4-voxel cube at voxel (i, j, k) = (20..23, 6..9, 13..16) of a 32 x 24 x 28 volume.
    array = np.zeros((28, 24, 32), np.float32)
    array[13:17, 6:10, 20:24] = 0.05
    vol = fluoro.Volume(array, origin=(-30, -20, -25), spacing=(2.0, 2.5, 1.5), direction=direction)
    assert vol.size == (32, 24, 28)
    centre = vol.index_to_physical([21.5, 7.5, 14.5])
    camera = fluoro.c_arm_view(20, 10, pixels=96, pixel_mm=3.2)
    b = fluoro.make_backend("cpu")
    drr = b.drr(b.upload(vol), np.eye(4), camera, step_mm=0.5)
    u, v = camera.project(centre[None, :])[0]
    row, col = np.unravel_index(np.argmax(drr), drr.shape)
    # array[row, col] is pixel (u, v) = (col, row), row 0 at the top.
    assert abs(row - v) < 2.0 and abs(col - u) < 2.0, (row, col, u, v)
    assert drr.max() > 0.05 * 4 * 1.5 * 0.9  # about 4 voxels of 1.5 to 2.5 mm each


def test_volume_views_and_geometry_round_trip():
    phantom = fluoro.make_phantom("femur", size=48)
    vol = phantom.hu
    view = vol.array
    assert view.shape == (48, 48, 48) and view.dtype == np.float32
    view[1, 2, 3] = 1234.0  # a view: writes reach the volume
    assert vol.array[1, 2, 3] == 1234.0
    copy = fluoro.Volume(vol.array, geometry=vol.geometry)  # SimpleITK's (origin, spacing, direction)
    assert np.array_equal(copy.array, vol.array) and not np.shares_memory(copy.array, vol.array)
    assert np.array_equal(copy.direction, vol.direction) and np.array_equal(copy.origin, vol.origin)
    assert len(vol.geometry[2]) == 9
    as_int = fluoro.Volume(np.ones((2, 3, 4), np.int16))  # converted to float32
    assert as_int.array.dtype == np.float32 and as_int.size == (4, 3, 2)


def test_camera_matrices_round_trip():
    cam = small_camera(45)
    again = fluoro.Camera(cam.K, cam.R, cam.t, cam.width, cam.height)
    assert np.array_equal(again.P, cam.P)
    from_p = fluoro.Camera.from_projection(2.5 * cam.P, cam.width, cam.height)
    assert np.allclose(from_p.K, cam.K) and np.allclose(from_p.R, cam.R) and np.allclose(from_p.t, cam.t)
    assert np.allclose(cam.source, -cam.R.T @ cam.t)
    x = np.array([[10.0, -20.0, 5.0]])
    h = cam.P @ np.append(x[0], 1.0)
    assert np.allclose(cam.project(x)[0], h[:2] / h[2])


def test_bad_input_raises_the_programs_message(cli, tmp_path):
    missing = str(tmp_path / "missing.nii.gz")
    cam = str(tmp_path / "cam.json")
    fluoro.write_camera(small_camera(), cam)
    r = cli("drr", "--ct", missing, "--camera", cam, "--out", tmp_path / "d.tif", check=False)
    assert r.returncode == 2
    with pytest.raises(ValueError) as e:
        fluoro.read_volume(missing)
    assert r.stderr == f"fluoro: {e.value}\n"
    assert missing in str(e.value)

    r = cli("drr", "--ct", missing, "--camera", cam, "--out", tmp_path / "d.tif", "--backend", "nope", check=False)
    assert r.returncode == 2
    with pytest.raises(ValueError) as e:
        fluoro.make_backend("nope")
    assert r.stderr == f"fluoro: {e.value}\n"
    assert "unknown backend" in str(e.value)


def test_bad_values_raise_value_error():
    with pytest.raises(ValueError, match="pose"):
        fluoro.check_pose(np.diag([2.0, 1, 1, 1]))  # not a rotation
    with pytest.raises(ValueError, match="camera"):
        fluoro.Camera(np.zeros((3, 3)), np.eye(3), [0, 0, 500], 64, 64)  # singular K
    with pytest.raises(ValueError, match="spacing"):
        fluoro.Volume(np.zeros((2, 2, 2)), spacing=(1, 0, 1))
    with pytest.raises(ValueError):
        fluoro.Volume(np.zeros((2, 2)))
    b = fluoro.make_backend("cpu")
    mu = b.upload(fluoro.Volume(np.zeros((4, 4, 4))))
    with pytest.raises(ValueError, match="step"):
        b.drr(mu, np.eye(4), small_camera(), step_mm=0.0)
    with pytest.raises(ValueError, match="leaves the"):
        b.drr(mu, np.eye(4), small_camera(), window=(60, 0, 10, 10))
    with pytest.raises(ValueError, match="NaN|finite|non-finite"):
        b.upload(fluoro.Volume(np.full((4, 4, 4), np.nan)))
    with pytest.raises(ValueError, match="belongs to another backend"):  # std::invalid_argument
        fluoro.make_backend("reference").drr(mu, np.eye(4), small_camera())
    options = fluoro.RegistrationOptions()
    assert options.correlation_polish == "auto"
    options.correlation_polish = "on"
    assert options.correlation_polish == "on"
    with pytest.raises(ValueError, match="correlation_polish"):
        options.correlation_polish = "sometimes"
    assert options.correlation_polish == "on"


def test_gradient_field_and_gpr_score():
    phantom = fluoro.make_phantom("femur", size=48)
    b = fluoro.make_backend("cpu")
    mu = b.upload(fluoro.hu_to_attenuation(phantom.hu))
    g = b.gradient_field(mu, sigma_mm=2.0)
    assert g.components == 3 and g.size == (48, 48, 48)
    field = b.download_gradient(g)
    assert field.shape == (48, 48, 48, 3) and field.dtype == np.float32
    assert np.abs(field).max() > 0

    cams = [small_camera(0, 96), small_camera(90, 96)]
    xrays = b.drr(mu, TRUTH, cams)
    edges = [fluoro.detect_edge_pixels(fluoro.drr_to_xray(x, 1000.0, 10.0)) for x in xrays]
    for pixels, directions in edges:
        assert pixels.shape == directions.shape and pixels.shape[1] == 2 and len(pixels) > 20
        assert np.allclose(np.linalg.norm(directions, axis=1), 1.0, atol=1e-4)
    off = fluoro.pose([0, 0.1, 0], [8.0, 0, 0]) @ TRUTH
    scores = b.gpr_score(g, np.stack([TRUTH, off]), cams, edges)
    assert scores.shape == (2,) and scores.dtype == np.float64
    assert scores[0] > 1.2 * scores[1]  # the true pose scores higher (166 against 132 when written)
    assert scores[0] == b.gpr_score(g, TRUTH, cams, edges)  # a float for one pose, the same value
    proj = b.gradient_projection(g, TRUTH, cams, [e[0] for e in edges])
    assert len(proj) == 2 and proj[0].shape == edges[0][0].shape


def test_the_gil_is_released_during_kernel_calls():
    # While one thread is inside a long drr call (about 1 s), another runs Python: it sees the flag
    # the worker raised just before the call and lowers just after it many times (1.2 million on
    # the development machine). With the GIL held through the call it could run only until the
    # worker takes the GIL back, one switch interval (5 ms): a C call holding the GIL for 1 s
    # (sum(range(10**8))) in place of drr lets it count 17 thousand.
    import threading
    b = fluoro.make_backend("cpu")
    mu = b.upload(fluoro.hu_to_attenuation(fluoro.make_phantom("femur", size=64).hu))
    poses = np.stack([fluoro.pose([0, 0, 0.01 * i], [i, 0, 0]) for i in range(24)])
    camera = small_camera(0, 256)
    expected = b.drr(mu, poses, camera)
    inside = [False]
    result = [None]

    def work():
        inside[0] = True
        result[0] = b.drr(mu, poses, camera)
        inside[0] = False

    worker = threading.Thread(target=work)
    seen_inside = 0
    worker.start()
    while worker.is_alive():
        seen_inside += inside[0]
    worker.join()
    assert seen_inside > 100_000, seen_inside
    assert np.array_equal(result[0], expected)  # and the concurrent call computed the same images
