"""ICP to a CT's bone surface (`fluoro icp --ct`): a known pose recovered from points on the
surface, the same result as the program's, bit for bit, and its bad input messages."""
import json

import numpy as np
import pytest

import fluoro

TRUTH = fluoro.pose([0.04, -0.03, 0.05], [3.0, -2.0, 4.0])


def transform(T, points):
    return points @ T[:3, :3].T + T[:3, 3]


@pytest.fixture(scope="module")
def ct(tmp_path_factory):
    path = str(tmp_path_factory.mktemp("icp") / "ct.nii.gz")
    fluoro.write_volume(fluoro.make_phantom("femur", size=48, fov_mm=144).hu, path)
    return path


def test_icp_to_a_ct_recovers_a_known_pose_as_the_program(cli, ct, tmp_path):
    hu = fluoro.read_volume(ct)
    vertices, triangles = fluoro.ct_surface(hu, iso_hu=250, ct_voxel_mm=3.0)
    assert vertices.shape[1] == 3 and triangles.shape[1] == 3 and triangles.dtype == np.int32
    assert len(triangles) > 1000 and triangles.max() < len(vertices)
    # Every vertex of the surface lies on it: points digitised on the bone, moved by the truth.
    model_points = vertices[:: max(1, len(vertices) // 400)]
    world = transform(TRUTH, model_points)
    start = fluoro.pose([0.02, -0.01, 0.02], [1.5, -1.0, 1.0]) @ TRUTH

    r = fluoro.icp(world, ct=hu, initial=start, iso_hu=250, ct_voxel_mm=3.0, keep_fraction=1.0)
    assert r.ok, r.failure_reason
    np.testing.assert_allclose(r.T_world_model[:3, 3], TRUTH[:3, 3], atol=1e-3)
    assert fluoro.rotation_angle_deg(r.T_world_model @ np.linalg.inv(TRUTH)) < 1e-3
    assert r.rms_mm < 1e-3
    # The same surface given as arrays is the same problem.
    as_mesh = fluoro.icp(world, (vertices, triangles), start, keep_fraction=1.0)
    assert np.array_equal(as_mesh.T_world_model, r.T_world_model)

    (tmp_path / "pts.json").write_text(json.dumps({"points": world.tolist()}))
    fluoro.write_pose(start, str(tmp_path / "init.json"))
    cli("icp", "--points", tmp_path / "pts.json", "--ct", ct, "--iso", 250, "--ct-voxel-mm", 3.0,
        "--keep-fraction", 1.0, "--init", tmp_path / "init.json", "--out", tmp_path / "out.json")
    expected = json.loads((tmp_path / "out.json").read_text())
    from_path = fluoro.icp(world, ct=ct, initial=fluoro.read_pose(str(tmp_path / "init.json")), ct_voxel_mm=3.0,
                           keep_fraction=1.0)
    assert np.array_equal(from_path.T_world_model, np.array(expected["T_world_ct"]))
    assert from_path.rms_mm == expected["rms_mm"] and from_path.iterations == expected["iterations"]
    assert expected["surface"]["triangles"] == len(triangles)


def test_icp_to_a_ct_bad_input_raises_the_programs_message(cli, ct, tmp_path):
    (tmp_path / "pts.json").write_text(json.dumps({"points": [[0, 0, 0], [1, 0, 0], [0, 1, 0]]}))
    fluoro.write_pose(np.eye(4), str(tmp_path / "init.json"))
    r = cli("icp", "--points", tmp_path / "pts.json", "--ct", ct, "--iso", 5000, "--init", tmp_path / "init.json",
            "--out", tmp_path / "out.json", check=False)
    assert r.returncode == 2 and r.stderr.startswith("fluoro: ") and r.stderr.count("\n") == 1
    message = r.stderr[len("fluoro: "):].strip()
    with pytest.raises(ValueError) as e:
        fluoro.icp(np.zeros((3, 3)), ct=ct, iso_hu=5000)
    assert str(e.value) == message
    with pytest.raises(ValueError, match=r"^icp: give mesh \(a file or \(vertices, triangles\)\) or ct$"):
        fluoro.icp(np.zeros((3, 3)))
    with pytest.raises(ValueError, match=r"^ct: expected a Volume \(HU\) or a volume file's path$"):
        fluoro.icp(np.zeros((3, 3)), ct=5)
