"""The panorama on a generated long-bone set (datasets/panorama_scene.hpp, 256 px): the bone's
length measured on it against the truth, and the document and image against `fluoro panorama`'s."""
import json

import numpy as np
import pytest

import fluoro


@pytest.fixture(scope="module")
def scene():
    return fluoro.make_panorama_scene(pixels=256, frames=6, seed=2)


def landmark_in_panorama(scene, doc, k):
    # From the frame where the landmark lies nearest the image centre, as a user would pick it.
    px = scene["landmark_px"][:, k]
    centre = (np.array(scene["images"][0].shape[::-1]) - 1) / 2
    f = int(np.argmin(np.linalg.norm(px - centre, axis=1)))
    H = np.array(doc["frames"][f]["H_panorama_frame"])
    q = H @ np.r_[px[f], 1.0]
    return q[:2]


def test_length_in_the_bone_plane_matches_the_truth(scene):
    doc, image = fluoro.panorama(scene["images"], contours=scene["contours"])
    assert doc["status"] == "ok" and doc["plane"] == "contours" and not doc["partial"]
    assert image.dtype == np.float32 and image.shape == (doc["size"][1], doc["size"][0])
    # The contours move the scale from the ruler's plane to the bone's (seed eqs. 8-10).
    assert doc["plane_scale"] == pytest.approx(scene["ruler_plane_mm"] / scene["bone_plane_mm"], abs=0.003)
    a, b = landmark_in_panorama(scene, doc, 0), landmark_in_panorama(scene, doc, 1)
    length = np.linalg.norm(b - a) * doc["mm_per_pixel"]
    assert length == pytest.approx(scene["true_length_mm"], rel=0.005)

    ruler_only, _ = fluoro.panorama(scene["images"])  # ruler 50 mm nearer the source: parallax
    assert ruler_only["plane"] == "ruler" and ruler_only["plane_scale"] == 1


def test_document_and_image_are_the_programs(cli, scene, tmp_path):
    paths = []
    for i, im in enumerate(scene["images"]):
        paths.append(str(tmp_path / f"f{i}.tif"))  # float TIFF: the 16-bit values exactly
        fluoro.write_image(im, paths[-1])
    (tmp_path / "C.json").write_text(json.dumps(scene["contours"]))
    cli("panorama", "--images", *paths, "--plane-contours", tmp_path / "C.json", "--blend", "median",
        "--out", tmp_path / "pano.png", "--report", tmp_path / "pano.json")
    expected = json.loads((tmp_path / "pano.json").read_text())

    doc, image = fluoro.panorama([fluoro.read_image(p) for p in paths], contours=str(tmp_path / "C.json"),
                                 blend="median", names=paths)
    for key, value in doc.items():
        assert value == expected[key], key
    # The program writes the same pixels rounded to 16 bits (its values are non-negative).
    png = fluoro.read_image(str(tmp_path / "pano.png"))
    assert np.array_equal(np.clip(np.floor(image + 0.5), 0, 65535), png)  # lround: halves away from 0


def test_bad_input_raises_the_programs_message(scene):
    with pytest.raises(ValueError, match=r"^frames: a panorama needs at least 2 frames$"):
        fluoro.panorama(scene["images"][:1])
    with pytest.raises(ValueError, match=r"^blend: must be max, mean, median or min, not sum$"):
        fluoro.panorama(scene["images"], blend="sum")
    bad = dict(scene["contours"], frames=[5, 6])
    with pytest.raises(ValueError, match=r"^contours: \"frames\" \[5, 6\] must be two consecutive frames among the 6 given$"):
        fluoro.panorama(scene["images"], contours=bad)


def test_measure_is_the_programs(cli, scene, tmp_path):
    doc, _ = fluoro.panorama(scene["images"], contours=scene["contours"])
    (tmp_path / "pano.json").write_text(json.dumps(doc))
    a, b = landmark_in_panorama(scene, doc, 0), landmark_in_panorama(scene, doc, 1)
    cli("measure", "--report", tmp_path / "pano.json", "--points", ",".join(repr(float(x)) for x in (*a, *b)),
        "--out", tmp_path / "m.json")
    expected = json.loads((tmp_path / "m.json").read_text())
    for report in (doc, str(tmp_path / "pano.json")):
        m = fluoro.measure(report, [a, b])
        assert m["distance_mm"] == expected["distance_mm"] == np.linalg.norm(b - a) * doc["mm_per_pixel"]
        assert m["uncertainty_mm"] == expected["uncertainty_mm"] > 0
    with pytest.raises(ValueError, match=r"^points: a point lies outside the \d+ x \d+ panorama$"):
        fluoro.measure(doc, [a, [-5.0, 0.0]])
    with pytest.raises(ValueError, match=r"^report: the panorama failed"):
        fluoro.measure(dict(doc, status="failed"), [a, b])
    # Without the uncertainty section (a report from another program) it is unknown, not 0.
    bare = {k: v for k, v in doc.items() if k != "uncertainty"}
    assert fluoro.measure(bare, [a, b])["uncertainty_mm"] is None
