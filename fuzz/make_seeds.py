#!/usr/bin/env python3
"""Writes the seed corpus of the fuzz targets into fuzz/corpus/<target>/ (committed; rerun after a
format changes). The files are those the tests make: a small phantom CT written by `fluoro phantom`
in each volume format (and one written here as DICOM, which the program does not write), a DRR
written by `fluoro drr` in each image format (and as .nii, .mha and .nrrd, for the volume targets'
image reads), and the JSON documents of docs/cli.md and shared/docs/FORMATS.md.

Usage: fuzz/make_seeds.py [--fluoro build/bin/fluoro]   (the release build's program)
"""
import argparse
import json
import os
import shutil
import struct
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))

IDENTITY = [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]
CAMERA = {"width": 48, "height": 48, "K": [[400, 0, 23.5], [0, 400, 23.5], [0, 0, 1]],
          "R": [[1, 0, 0], [0, 1, 0], [0, 0, 1]], "t": [0, 0, 400], "pixel_spacing_mm": [0.5, 0.5]}
JSON_SEEDS = {
    "camera": {"cam_krt.json": CAMERA,
               "cam_p.json": {"width": 64, "height": 48,
                              "P": [[400, 0, 32, 100], [0, 400, 24, 50], [0, 0, 1, 400]]}},
    "pose": {"pose.json": {"T_world_ct": [[0, -1, 0, 10], [1, 0, 0, -5], [0, 0, 1, 300], [0, 0, 0, 1]]}},
    "pose_list": {"poses.json": {"poses": [IDENTITY, [[0, -1, 0, 1], [1, 0, 0, 2], [0, 0, 1, 3], [0, 0, 0, 1]]]}},
    "points": {"points2.json": {"points": [[10.5, 20], None, [30, 40.25]]},
               "points3.json": {"points": [[1, 2, 3], [4, 5, 6], None]}},
    "grid": {"grid.json": {"kind": "hole_grid", "pitch_mm": 10.0, "hole_diameter_mm": 3.0, "rows": 25,
                           "cols": 25, "thickness_mm": 7.0}},
    "phantom": {"phantom.json": {"kind": "fiducial_phantom", "fiducial_diameter_mm": 3.0,
                                 "fiducials": [{"id": "f%d" % i,
                                                "position_mm": [20.0 * (i % 3), 15.0 * (i // 3), 7.0 * i]}
                                               for i in range(8)]}},
    "guide": {"guide.json": {"kind": "drill_guide", "sphere_diameter_mm": 3.0,
                             "spheres_mm": [[10.0 * (i % 3), 12.0 * (i // 3), 5.0 * i * i % 17] for i in range(7)],
                             "axes": [{"name": "distal", "point_mm": [0, 0, 0], "direction": [0, 0, 1]},
                                      {"name": "proximal", "point_mm": [30, 0, 0], "direction": [0, 0, 1]}]}},
    "nail": {"nail.json": {"kind": "nail", "diameter_mm": 10.0,
                           "holes": [{"center_mm": [-15, 0, 0], "diameter_mm": 5.0},
                                     {"center_mm": [15, 0, 0], "diameter_mm": 5.0}]}},
    "robot": {"robot.json": {"T_base_tip": [[1, 0, 0, 100], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]],
                             "T_tip_guide": [[0, -1, 0, 0], [1, 0, 0, 0], [0, 0, 1, 50], [0, 0, 0, 1]]}},
    "landmarks": {"landmarks.json": {"landmarks": [
        {"name": "p%d" % i, "ct": [10.0 * i, -5.0 * i, 3.0], "pixels": [[20 + i, 30 - i], None if i == 2 else [25, 26]],
         "weight": 1.0} for i in range(4)]}},
    "contours": {"contours.json": {"views": [{"polylines": [[[10, 10], [50, 10], [50, 40]]]}, {}]}},
    "sweep_config": {
        "sweep.json": {"phantom": {"kind": "femur", "size": 64}, "c_arm": {"pixels": 192, "pixel_mm": 1.6},
                       "distances_mm": {"from": 3, "to": 8, "step": 5}, "runs_per_distance": 2,
                       "contours": "automatic"},
        "sweep_full.json": {"phantom": {"kind": "femur", "size": 128, "seed": 1, "fiducials": False},
                            "c_arm": {"source_to_isocentre_mm": 600, "source_to_detector_mm": 1000,
                                      "pixels": 384, "pixel_mm": 0.8},
                            "views": [{"orbit_deg": 0}, {"orbit_deg": 60}, {"orbit_deg": 100, "tilt_deg": 15}],
                            "truth": IDENTITY, "distances_mm": {"from": 1, "to": 85, "step": 1},
                            "runs_per_distance": 50, "contours": "traced", "noise": 0.0, "metal_tool": False,
                            "backend": "cpu", "seed": 1, "iso_hu": 250, "tissue_hu": 100}},
}

TET = [(0, 0, 0), (10, 0, 0), (0, 10, 0), (0, 0, 10)]
FACES = [(0, 2, 1), (0, 1, 3), (0, 3, 2), (1, 2, 3)]


def mesh_seeds():
    ascii_stl = "solid tet\n" + "".join(
        "facet normal 0 0 0\n outer loop\n" + "".join("  vertex %g %g %g\n" % TET[i] for i in f) +
        " endloop\nendfacet\n" for f in FACES) + "endsolid tet\n"
    binary_stl = b"\0" * 80 + struct.pack("<I", len(FACES)) + b"".join(
        struct.pack("<12fH", 0, 0, 0, *[c for i in f for c in TET[i]], 0) for f in FACES)
    ply = ("ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\n"
           "element face 4\nproperty list uchar int vertex_indices\nend_header\n" +
           "".join("%g %g %g\n" % v for v in TET) + "".join("3 %d %d %d\n" % f for f in FACES))
    ply_bin = ("ply\nformat binary_little_endian 1.0\nelement vertex 4\nproperty double x\nproperty double y\n"
               "property double z\nelement face 4\nproperty list uchar int vertex_indices\nend_header\n").encode()
    ply_bin += b"".join(struct.pack("<3d", *v) for v in TET) + b"".join(struct.pack("<B3i", 3, *f) for f in FACES)
    obj = "# tet\n" + "".join("v %g %g %g\n" % v for v in TET) + "".join(
        "f %d %d %d\n" % tuple(i + 1 for i in f) for f in FACES) + "f 1/1/1 2/2/2 3/3/3\n"
    return {"mesh_stl": {"ascii.stl": ascii_stl.encode(), "binary.stl": binary_stl},
            "mesh_ply": {"ascii.ply": ply.encode(), "binary.ply": ply_bin},
            "mesh_obj": {"tet.obj": obj.encode()}}


def dicom_seeds():
    """A CT of 8 x 8 x 4 16-bit voxels as one multi-frame DICOM Part 10 file, in explicit and in
    implicit VR little endian, written field by field (the program writes no DICOM)."""
    long_vrs = {"OB", "OW", "SQ", "UN", "UT"}

    def explicit(group, elem, vr, value):
        if len(value) % 2:
            value += b"\0" if vr in ("UI", "OB") else b" "
        if vr in long_vrs:
            return struct.pack("<HH2sHI", group, elem, vr.encode(), 0, len(value)) + value
        return struct.pack("<HH2sH", group, elem, vr.encode(), len(value)) + value

    def implicit(group, elem, vr, value):
        if len(value) % 2:
            value += b"\0" if vr in ("UI", "OB") else b" "
        return struct.pack("<HHI", group, elem, len(value)) + value

    us = lambda v: struct.pack("<H", v)
    ct_storage = b"1.2.840.10008.5.1.4.1.1.2"
    instance = b"1.2.826.0.1.3680043.9.7.4.1"
    data_set = [(0x0008, 0x0016, "UI", ct_storage), (0x0008, 0x0018, "UI", instance), (0x0008, 0x0060, "CS", b"CT"),
                (0x0018, 0x0050, "DS", b"1"), (0x0018, 0x0088, "DS", b"1"),
                (0x0020, 0x000D, "UI", b"1.2.826.0.1.3680043.9.7.4.2"),
                (0x0020, 0x000E, "UI", b"1.2.826.0.1.3680043.9.7.4.3"),
                (0x0020, 0x0032, "DS", b"0\\0\\0"), (0x0020, 0x0037, "DS", b"1\\0\\0\\0\\1\\0"),
                (0x0028, 0x0002, "US", us(1)), (0x0028, 0x0004, "CS", b"MONOCHROME2"), (0x0028, 0x0008, "IS", b"4"),
                (0x0028, 0x0010, "US", us(8)), (0x0028, 0x0011, "US", us(8)), (0x0028, 0x0030, "DS", b"0.5\\0.5"),
                (0x0028, 0x0100, "US", us(16)), (0x0028, 0x0101, "US", us(16)), (0x0028, 0x0102, "US", us(15)),
                (0x0028, 0x0103, "US", us(0)),
                (0x7FE0, 0x0010, "OW", b"".join(struct.pack("<H", (i * 37) % 1000) for i in range(8 * 8 * 4)))]
    files = {}
    for name, syntax, encode in (("ct_explicit.dcm", b"1.2.840.10008.1.2.1", explicit),
                                 ("ct_implicit.dcm", b"1.2.840.10008.1.2", implicit)):
        meta = b"".join(explicit(0x0002, e, vr, v) for e, vr, v in (
            (0x0001, "OB", b"\0\1"), (0x0002, "UI", ct_storage), (0x0003, "UI", instance), (0x0010, "UI", syntax),
            (0x0012, "UI", b"1.2.826.0.1.3680043.9.7.4")))
        meta = explicit(0x0002, 0x0000, "UL", struct.pack("<I", len(meta))) + meta
        files[name] = b"\0" * 128 + b"DICM" + meta + b"".join(encode(*e) for e in data_set)
    return {"volume_dcm": files}


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--fluoro", default=os.path.join(HERE, "..", "build", "bin", "fluoro"))
    args = ap.parse_args()
    corpus = os.path.join(HERE, "corpus")
    shutil.rmtree(corpus, ignore_errors=True)

    def put(target, name, data):
        os.makedirs(os.path.join(corpus, target), exist_ok=True)
        with open(os.path.join(corpus, target, name), "wb") as f:
            f.write(data)

    for target, files in JSON_SEEDS.items():
        for name, doc in files.items():
            put(target, name, json.dumps(doc).encode())
    for target, files in {**mesh_seeds(), **dicom_seeds()}.items():
        for name, data in files.items():
            put(target, name, data)

    def fluoro(*a):
        subprocess.run([args.fluoro, *a], check=True, capture_output=True)

    with tempfile.TemporaryDirectory() as d:
        for target, ext in (("volume_nii", "nii"), ("volume_mha", "mha"), ("volume_nrrd", "nrrd")):
            fluoro("phantom", "--size", "16", "--out", os.path.join(d, "ct." + ext))
            put(target, "phantom16." + ext, open(os.path.join(d, "ct." + ext), "rb").read())
        # An uncompressed int16 MetaImage: the project's MetaImage reader widens it (the phantom's is
        # compressed float).
        header = ("ObjectType = Image\nNDims = 3\nBinaryData = True\nBinaryDataByteOrderMSB = False\n"
                  "TransformMatrix = 1 0 0 0 1 0 0 0 1\nOffset = -3 -3 -3\nElementSpacing = 2 2 2\n"
                  "DimSize = 4 4 4\nElementType = MET_SHORT\nElementDataFile = LOCAL\n")
        voxels = b"".join(struct.pack("<h", (i * 37) % 300 - 1000) for i in range(64))
        put("volume_mha", "raw_short.mha", header.encode() + voxels)
        with open(os.path.join(d, "cam.json"), "w") as f:
            json.dump(CAMERA, f)
        # A DRR in each volume format too: those targets give every input to read_image as well.
        for target, ext in (("image_png", "png"), ("image_tif", "tif"), ("image_pfm", "pfm"),
                            ("volume_nii", "nii"), ("volume_mha", "mha"), ("volume_nrrd", "nrrd")):
            out = os.path.join(d, "drr." + ext)
            fluoro("drr", "--ct", os.path.join(d, "ct.nii"), "--camera", os.path.join(d, "cam.json"),
                   "--out", out, "--quiet")
            put(target, "drr48." + ext, open(out, "rb").read())
    total = sum(os.path.getsize(os.path.join(r, f)) for r, _, fs in os.walk(corpus) for f in fs)
    print("wrote %s (%d bytes)" % (corpus, total))


if __name__ == "__main__":
    sys.exit(main())
