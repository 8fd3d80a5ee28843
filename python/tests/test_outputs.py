"""Files a user takes to other tools: DRRs as .mha/.nrrd carry the detector's pixel spacing (and a
window's place on the detector) exactly as `fluoro drr --out x.mha` writes them."""
import re

import numpy as np
import pytest

import fluoro

TRUTH = fluoro.pose([0.05, -0.03, 0.10], [4.0, -3.0, 6.0])


def header_numbers(path, key):
    # The header is text up to the data: the key's numbers, as a reader of the format sees them.
    text = open(path, "rb").read(2048).decode("latin-1")
    m = re.search(rf"^{key}\s*[=:]\s*(.*)$", text, re.M)
    assert m, f"{key} not in {path}"
    return [float(x) for x in re.findall(r"[-+0-9.eE]+", m.group(1))]


@pytest.mark.parametrize("ext", ["mha", "nrrd"])
def test_write_drr_carries_the_pixel_spacing_as_the_program(cli, tmp_path, ext):
    ct, cam, pose = (str(tmp_path / n) for n in ("ct.nii.gz", "cam.json", "pose.json"))
    fluoro.write_volume(fluoro.make_phantom("femur", size=32).hu, ct)
    g = fluoro.c_arm_view(30, pixels=64, pixel_mm=4.8)
    camera = fluoro.Camera(g.K, g.R, g.t, g.width, g.height, pixel_spacing_mm=(0.3, 0.4))  # non-square pixels
    fluoro.write_camera(camera, cam)
    fluoro.write_pose(TRUTH, pose)
    window = (8, 4, 40, 30)
    expected = str(tmp_path / f"cli.{ext}")
    cli("drr", "--ct", ct, "--camera", cam, "--pose", pose, "--out", expected, "--window", ",".join(map(str, window)))

    b = fluoro.make_backend("cpu")
    drr = b.drr(b.upload(fluoro.hu_to_attenuation(fluoro.read_volume(ct))), TRUTH, camera, window=window)
    mine = str(tmp_path / f"py.{ext}")
    fluoro.write_drr(drr, mine, camera=camera, window_origin=window[:2])
    assert open(mine, "rb").read() == open(expected, "rb").read()  # the same file, byte for byte
    if ext == "mha":
        assert header_numbers(mine, "ElementSpacing") == pytest.approx([0.3, 0.4])
        assert header_numbers(mine, "Offset")[:2] == pytest.approx([8 * 0.3, 4 * 0.4])
    else:
        assert header_numbers(mine, "space directions") == pytest.approx([0.3, 0, 0, 0.4])
        assert header_numbers(mine, "space origin") == pytest.approx([8 * 0.3, 4 * 0.4])

    # A spacing given outright wins over the camera's; without either the file is in pixel units.
    fluoro.write_drr(drr, str(tmp_path / "given.mha"), camera=camera, pixel_spacing_mm=(0.15, 0.15))
    assert header_numbers(str(tmp_path / "given.mha"), "ElementSpacing") == pytest.approx([0.15, 0.15])
    fluoro.write_drr(drr, str(tmp_path / "none.mha"))
    assert header_numbers(str(tmp_path / "none.mha"), "ElementSpacing") == pytest.approx([1, 1])
    with pytest.raises(ValueError, match=r"^pixel_spacing_mm: must be two positive numbers$"):
        fluoro.write_drr(drr, str(tmp_path / "bad.mha"), pixel_spacing_mm=(0.0, 0.3))
