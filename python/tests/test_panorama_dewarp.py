"""The dewarp map in Python (`fluoro dewarp apply`, `fluoro panorama --dewarp --overlay`): frames
bent by a fitted map's own distortion come back straight; the panorama through a map keeps the
bone's true length, and its document, image and overlay are the program's (the calibration demo's
map, 256 px frames)."""
import json
import struct
import zlib

import numpy as np
import pytest

import fluoro


@pytest.fixture(scope="module")
def scene():
    return fluoro.make_panorama_scene(pixels=256, frames=6, seed=2)


@pytest.fixture(scope="module")
def demo_map(cli, tmp_path_factory):
    d = tmp_path_factory.mktemp("cal")
    cli("demo", "--calibration", "--out-dir", d, "--pixels", 256)
    return str(d / "MAP.json")


@pytest.fixture(scope="module")
def wide_map(demo_map, tmp_path_factory):
    # The demo's map (a 2.4 degree turn, a scale and a mild distortion) with its field of view
    # widened to the whole image: the generated frames' ruler runs close to their edges, where the
    # demo's round field of view would cut it.
    d = json.loads(open(demo_map).read())
    d["lattice"]["covered"] = ["1" * len(row) for row in d["lattice"]["covered"]]
    path = tmp_path_factory.mktemp("wide") / "MAP.json"
    path.write_text(json.dumps(d))
    return str(path)


def read_rgb_png(path):
    # The program's 8-bit RGB PNGs (engine/png_writer.cpp: every row filtered with "Sub").
    data = open(path, "rb").read()
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    pos, idat = 8, b""
    while pos < len(data):
        n, kind = struct.unpack(">I4s", data[pos:pos + 8])
        if kind == b"IHDR":
            w, h, depth, colour = struct.unpack(">IIBB", data[pos + 8:pos + 18])
            assert depth == 8 and colour == 2
        if kind == b"IDAT":
            idat += data[pos + 8:pos + 8 + n]
        pos += 12 + n
    rows = np.frombuffer(zlib.decompress(idat), np.uint8).reshape(h, 1 + 3 * w)
    assert np.all(rows[:, 0] == 1)
    return (np.cumsum(rows[:, 1:].reshape(h, w, 3).astype(np.int64), axis=1) % 256).astype(np.uint8)


def bilinear(image, points):
    # image sampled at (u, v) = (column, row) points (N, 2); NaN points give 0, as outside a map's view.
    h, w = image.shape
    inside = np.all(np.isfinite(points), axis=1)
    u = np.clip(np.nan_to_num(points[:, 0]), 0, w - 1.000001)
    v = np.clip(np.nan_to_num(points[:, 1]), 0, h - 1.000001)
    u0, v0 = np.floor(u).astype(int), np.floor(v).astype(int)
    fu, fv = u - u0, v - v0
    out = (image[v0, u0] * (1 - fu) * (1 - fv) + image[v0, u0 + 1] * fu * (1 - fv) +
           image[v0 + 1, u0] * (1 - fu) * fv + image[v0 + 1, u0 + 1] * fu * fv)
    return np.where(inside, out, 0).astype(np.float32)


def distort(image, map_path):
    # The frame as an intensifier bent it: the acquired pixel d shows the straight frame at the
    # map's correction of d (dewarp_points: distorted -> corrected).
    h, w = image.shape
    grid = np.stack(np.meshgrid(np.arange(w, dtype=float), np.arange(h, dtype=float)), axis=-1).reshape(-1, 2)
    return bilinear(image, fluoro.dewarp_points(grid, map_path)).reshape(h, w)


def test_dewarp_image_and_points_are_the_programs(cli, demo_map, tmp_path):
    rng = np.random.default_rng(5)
    image = rng.uniform(0, 1000, (256, 256)).astype(np.float32)
    fluoro.write_image(image, str(tmp_path / "in.tif"))
    cli("dewarp", "apply", "--map", demo_map, "--in", tmp_path / "in.tif", "--out", tmp_path / "out.tif")
    mine = fluoro.dewarp_image(image, demo_map)
    assert mine.shape == (256, 256) and mine.dtype == np.float32
    assert np.array_equal(mine, fluoro.read_image(str(tmp_path / "out.tif")))
    assert np.array_equal(fluoro.dewarp_image(image, json.loads(open(demo_map).read())), mine)  # the dict form

    pts = np.array([[10.5, 20.25], [128.0, 128.0], [250.0, 3.0], [-400.0, 900.0]])
    (tmp_path / "pts.json").write_text(json.dumps({"points": pts.tolist()}))
    cli("dewarp", "apply", "--map", demo_map, "--points", tmp_path / "pts.json", "--out", tmp_path / "c.json")
    expected = json.loads((tmp_path / "c.json").read_text())["points"]
    corrected = fluoro.dewarp_points(pts, demo_map)
    for mine_p, theirs in zip(corrected, expected):
        assert (theirs is None and np.all(np.isnan(mine_p))) or list(mine_p) == theirs
    assert expected[-1] is None  # far outside the field of view

    with pytest.raises(ValueError, match=r"^image: is 64x64, the map is for 256x256$"):
        fluoro.dewarp_image(np.zeros((64, 64)), demo_map)


def test_a_distorted_frame_comes_back_straight(demo_map, scene):
    straight = scene["images"][0]
    back = fluoro.dewarp_image(distort(straight, demo_map), demo_map)
    # Inside the field of view, away from its edge: twice resampled, the same picture.
    covered = fluoro.dewarp_image(np.ones_like(straight), demo_map) > 0.999
    interior = covered & np.roll(covered, 3, 0) & np.roll(covered, -3, 0) & np.roll(covered, 3, 1) & np.roll(covered, -3, 1)
    assert interior.mean() > 0.5
    moved = np.abs(distort(straight, demo_map) - straight)[interior].mean()
    residual = np.abs(back - straight)[interior].mean()
    assert residual < 0.2 * moved, (residual, moved)  # the distortion is undone, not merely blurred


def landmark_in_panorama(scene, doc, k, map_path):
    # From the frame where the landmark lies nearest the image centre; its pixel as acquired goes
    # through the map first, as the frames did (H maps corrected pixels).
    px = scene["landmark_px"][:, k]
    centre = (np.array(scene["images"][0].shape[::-1]) - 1) / 2
    f = int(np.argmin(np.linalg.norm(px - centre, axis=1)))
    q = np.array(doc["frames"][f]["H_panorama_frame"]) @ np.r_[fluoro.dewarp_points(px[f][None, :], map_path)[0], 1.0]
    return q[:2] / q[2]


def test_panorama_with_dewarp_and_overlay_is_the_programs(cli, wide_map, scene, tmp_path):
    paths = []
    for i, im in enumerate(scene["images"]):
        paths.append(str(tmp_path / f"f{i}.tif"))  # float TIFF: the 16-bit values exactly
        fluoro.write_image(im, paths[-1])
    (tmp_path / "C.json").write_text(json.dumps(scene["contours"]))
    cli("panorama", "--images", *paths, "--dewarp", wide_map, "--plane-contours", tmp_path / "C.json",
        "--out", tmp_path / "pano.png", "--report", tmp_path / "pano.json", "--overlay", tmp_path / "overlay.png")
    expected = json.loads((tmp_path / "pano.json").read_text())

    # The frames as acquired; the map turns, scales and bends them, the contours and landmarks alike.
    doc, image, overlay = fluoro.panorama(scene["images"], contours=scene["contours"], dewarp=wide_map, names=paths,
                                          overlay=True)
    assert doc["status"] == "ok" and doc["plane"] == "contours" and not doc["partial"] and doc["dewarp"] == wide_map
    a, b = landmark_in_panorama(scene, doc, 0, wide_map), landmark_in_panorama(scene, doc, 1, wide_map)
    assert np.linalg.norm(b - a) * doc["mm_per_pixel"] == pytest.approx(scene["true_length_mm"], rel=0.005)
    for key, value in doc.items():
        assert value == expected[key], key
    png = fluoro.read_image(str(tmp_path / "pano.png"))
    assert np.array_equal(np.clip(np.floor(image + 0.5), 0, 65535), png)
    assert overlay.dtype == np.uint8 and overlay.shape == image.shape + (3,)
    assert np.array_equal(overlay, read_rgb_png(str(tmp_path / "overlay.png")))
    red = (overlay[..., 0] > 200) & (overlay[..., 1] < 80) & (overlay[..., 2] < 80)  # the ruler threads
    green = (overlay[..., 1] > 200) & (overlay[..., 0] < 80) & (overlay[..., 2] < 80)  # the graduations
    assert red.sum() > 100 and green.sum() > 100

    # The map as fit_dewarp's dict is the same map; only the picture is optional.
    from_dict = fluoro.panorama(scene["images"], contours=scene["contours"], dewarp=json.loads(open(wide_map).read()))
    assert len(from_dict) == 2 and from_dict[0]["dewarp"] == "dewarp"
    assert [f["H_panorama_frame"] for f in from_dict[0]["frames"]] == [f["H_panorama_frame"] for f in doc["frames"]]
    with pytest.raises(ValueError, match=r'^dewarp: expected "kind": "dewarp_map"'):
        fluoro.panorama(scene["images"], dewarp={"kind": "other"})
    with pytest.raises(ValueError, match=r"the map is for 256 x 256 images, the frames are 128 x 128$"):
        fluoro.panorama([f[:128, :128] for f in scene["images"]], dewarp=wide_map)
