"""The calibration and distal-locking entry points give what the program writes for the same inputs
(the demos' scenes: `fluoro demo --calibration`, `fluoro demo --distal-locking`, its ROBOT.json)."""
import json

import numpy as np
import pytest

import fluoro


def same_values(py_doc, cli_doc):
    # Every key the binding returns, with the value the program wrote (it adds inputs and timings).
    for key, value in py_doc.items():
        assert key in cli_doc, key
        assert value == cli_doc[key], key


def test_dewarp_fit_and_calibration_are_the_programs(cli, tmp_path):
    d = tmp_path / "cal"
    cli("demo", "--calibration", "--out-dir", d, "--pixels", 512)
    cli("dewarp", "fit", "--image", d / "grid_xray.png", "--grid", d / "GRID.json", "--out", tmp_path / "map.json")
    cli("calibrate", "--image", d / "phantom_xray.png", "--phantom", d / "PHANTOM.json",
        "--dewarp", tmp_path / "map.json", "--out", tmp_path / "camera.json")

    fit = fluoro.fit_dewarp(fluoro.read_image(str(d / "grid_xray.png")), str(d / "GRID.json"))
    assert fit["status"] == "ok"
    same_values(fit, json.loads((tmp_path / "map.json").read_text()))

    cal = fluoro.calibrate_image(fluoro.read_image(str(d / "phantom_xray.png")), str(d / "PHANTOM.json"),
                                 str(tmp_path / "map.json"))
    assert cal["status"] == "ok"
    same_values(cal, json.loads((tmp_path / "camera.json").read_text()))
    camera = fluoro.Camera(cal["K"], cal["R"], cal["t"], cal["width"], cal["height"])
    truth = fluoro.read_camera(str(d / "truth_camera.json"))
    assert np.linalg.norm(camera.source - truth.source) < 5.0  # mm (the demo reports about 1 mm)

    with pytest.raises(ValueError, match="PHANTOM"):
        fluoro.calibrate_image(np.zeros((8, 8)), str(d / "missing_PHANTOM.json"))


def test_distal_locking_is_the_programs(cli, tmp_path):
    d = tmp_path / "dl"
    cli("demo", "--distal-locking", "--out-dir", d, "--pixels", 512)
    args = ["--image", d / "shot.png", "--camera", d / "shot_camera.json", "--guide", d / "shot_guide.json",
            "--nail", d / "shot_nail.json"]
    cli("distal-lock", *args, "--robot", d / "ROBOT.json", "--out", tmp_path / "result.json")
    expected = json.loads((tmp_path / "result.json").read_text())

    r = fluoro.locate_for_distal_locking(fluoro.read_image(str(d / "shot.png")),
                                         fluoro.read_camera(str(d / "shot_camera.json")),
                                         str(d / "shot_guide.json"), str(d / "shot_nail.json"))
    assert r.ok and expected["status"] == "ok"
    assert np.array_equal(r.T_world_guide, np.array(expected["T_world_guide"]))
    assert np.array_equal(r.T_world_nail, np.array(expected["T_world_nail"]))
    assert len(r.holes) == len(expected["holes_world"]) > 0
    for mine, theirs in zip(r.holes, expected["holes_world"]):
        assert np.array_equal(mine["entry_mm"], theirs["entry_mm"])
        assert np.array_equal(mine["exit_mm"], theirs["exit_mm"])

    goal = fluoro.robot_goal(r, str(d / "shot_guide.json"), str(d / "shot_nail.json"), str(d / "ROBOT.json"))
    assert np.array_equal(goal["T_base_goal"], np.array(expected["T_base_goal"]))
    for key in ("slide_mm", "turn_from_now_deg", "spacing_mismatch_mm"):
        assert goal[key] == expected["robot"][key], key
    with pytest.raises(ValueError, match="ROBOT"):
        fluoro.robot_goal(r, str(d / "shot_guide.json"), str(d / "shot_nail.json"), str(d / "missing_ROBOT.json"))

    # A guide whose axes are 6 mm further apart than the holes is refused, as by the program.
    guide = json.loads((d / "shot_guide.json").read_text())
    a, b = (np.array(axis["point_mm"], float) for axis in guide["axes"][:2])
    u = np.array(guide["axes"][0]["direction"], float)
    u /= np.linalg.norm(u)
    across = (b - a) - np.dot(b - a, u) * u
    guide["axes"][1]["point_mm"] = (b + 6.0 * across / np.linalg.norm(across)).tolist()
    (tmp_path / "wide_guide.json").write_text(json.dumps(guide))
    with pytest.raises(ValueError, match="no robot goal puts both axes on the holes"):
        fluoro.robot_goal(r, str(tmp_path / "wide_guide.json"), str(d / "shot_nail.json"), str(d / "ROBOT.json"))
