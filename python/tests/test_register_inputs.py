"""What `fluoro register` takes besides the X-rays: the initial pose from landmarks, traced or
livewire-clicked contours, and the ITK transform file it writes; against a generated scene's truth
and the program's results, bit for bit."""
import json

import numpy as np
import pytest

import fluoro

TRUTH = fluoro.pose([0.05, -0.03, 0.10], [4.0, -3.0, 6.0])


def transform(T, points):
    return points @ T[:3, :3].T + T[:3, 3]


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    d = tmp_path_factory.mktemp("reg")
    phantom = fluoro.make_phantom("femur", size=48, fiducials=True)
    fluoro.write_volume(phantom.hu, str(d / "ct.nii.gz"))
    cameras = [fluoro.c_arm_view(0, pixels=128, pixel_mm=2.4), fluoro.c_arm_view(90, pixels=128, pixel_mm=2.4)]
    b = fluoro.make_backend("cpu")
    drrs = b.drr(b.upload(fluoro.hu_to_attenuation(phantom.hu)), TRUTH, cameras, step_mm=1.0)
    views = []
    for i, (drr, camera) in enumerate(zip(drrs, cameras)):
        xray = fluoro.drr_to_xray(drr, *fluoro.display_mapping(drr, 1000.0))
        fluoro.write_image(xray, str(d / f"x{i}.tif"))
        fluoro.write_camera(camera, str(d / f"c{i}.json"))
        views.append((str(d / f"x{i}.tif"), fluoro.read_image(str(d / f"x{i}.tif")), camera))
    return d, phantom, cameras, views


def write_landmarks(path, fiducials, cameras, noise_px, seed=4):
    rng = np.random.default_rng(seed)
    marks = []
    for k, p in enumerate(fiducials):
        pixels = [(c.project(transform(TRUTH, p[None, :]))[0] + rng.uniform(-noise_px, noise_px, 2)).tolist()
                  for c in cameras]
        marks.append({"name": f"f{k}", "ct": p.tolist(), "pixels": pixels})
    path.write_text(json.dumps({"landmarks": marks}))


def test_landmarks_give_the_true_pose(scene, tmp_path):
    d, phantom, cameras, _ = scene
    assert len(phantom.fiducials) >= 3
    write_landmarks(tmp_path / "lm.json", phantom.fiducials, cameras, noise_px=0.0)
    lm = fluoro.register_landmarks(str(tmp_path / "lm.json"), cameras)
    # Exact pixels: the rays meet at the fiducials, and the rigid fit is the truth.
    assert lm["landmarks_used"] == len(phantom.fiducials) and lm["fre_rms_mm"] < 1e-6
    np.testing.assert_allclose(lm["T_world_ct"], TRUTH, atol=1e-6)
    assert max(lm["ray_distance_mm"]) < 1e-6
    with pytest.raises(ValueError, match=r"lm\.json"):
        fluoro.register_landmarks(str(tmp_path / "lm.json"), cameras[:1] * 3)  # 2 pixels a landmark, 3 cameras


def test_landmarks_contours_and_tfm_are_the_programs(cli, scene, tmp_path):
    # With --livewire, the longer of the two contour paths (clicks joined along the X-ray's edges;
    # the registration itself takes its contours from either the same way). One run of each side:
    # the scene is small (128^2, a 48^3 CT) to keep the test fast, too coarse to judge accuracy by,
    # which the example and the C++ tests do.
    livewire = True
    d, phantom, cameras, views = scene
    write_landmarks(tmp_path / "lm.json", phantom.fiducials, cameras, noise_px=1.0)  # a start off the truth
    # Contours on view 0 only: the bone's outline as a user would click it, a few edge pixels in
    # order around their centre (the livewire joins them along the edges, else straight segments).
    pixels, _ = fluoro.detect_edge_pixels(views[0][1])
    centre = pixels.mean(axis=0)
    order = np.argsort(np.arctan2(*(pixels - centre).T[::-1]))
    clicks = pixels[order][:: max(1, len(order) // 10)]
    (tmp_path / "c.json").write_text(json.dumps({"views": [{"polylines": [clicks.tolist()]}, {}]}))
    args = ["register", "--ct", d / "ct.nii.gz", "--view", f"{d / 'x0.tif'}:{d / 'c0.json'}",
            "--view", f"{d / 'x1.tif'}:{d / 'c1.json'}", "--landmarks", tmp_path / "lm.json",
            "--contours", tmp_path / "c.json", "--tfm", tmp_path / "cli.tfm", "--out", tmp_path / "r.json"]
    cli(*args, *(["--livewire"] if livewire else []))
    expected = json.loads((tmp_path / "r.json").read_text())

    start = fluoro.register_landmarks(str(tmp_path / "lm.json"), cameras)
    assert np.array_equal(start["T_world_ct"], np.array(expected["initial_T_world_ct"]))
    assert start["fre_rms_mm"] == expected["initial"]["fre_rms_mm"]
    reg = fluoro.PreparedRegistration(fluoro.make_backend("cpu"), fluoro.read_volume(str(d / "ct.nii.gz")), views,
                                      contours=str(tmp_path / "c.json"), livewire=livewire)
    report = reg.run(start["T_world_ct"])
    assert report.ok and np.array_equal(report.pose, np.array(expected["T_world_ct"]))
    fluoro.write_itk_transform(report.pose, str(tmp_path / "py.tfm"))
    assert (tmp_path / "py.tfm").read_bytes() == (tmp_path / "cli.tfm").read_bytes()
    # The file holds T_world_ct^-1 (ITK: fixed = world, moving = CT).
    text = (tmp_path / "py.tfm").read_text()
    params = [float(x) for x in text.split("Parameters: ")[1].splitlines()[0].split()]
    inverse = np.linalg.inv(report.pose)
    np.testing.assert_allclose(np.array(params[:9]).reshape(3, 3), inverse[:3, :3], atol=1e-12)
    np.testing.assert_allclose(params[9:12], inverse[:3, 3], atol=1e-9)
    with pytest.raises(ValueError, match=r"^x\.mat: unsupported transform file extension \(use \.tfm, \.txt, \.h5 or \.hdf5\)$"):
        fluoro.write_itk_transform(report.pose, "x.mat")
    with pytest.raises(ValueError, match=r"^livewire: needs contours"):
        fluoro.PreparedRegistration(fluoro.make_backend("cpu"), phantom.hu, views, livewire=True)
