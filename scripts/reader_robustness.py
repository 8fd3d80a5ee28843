#!/usr/bin/env python3
"""Feeds mutated input files to the fluoro program and classifies what it does with them.

The error contract (shared/docs/CONVENTIONS.md, docs/cli.md): bad input ends with exit code 2 and
exactly one line on stderr that names the file; no signal, no "internal error", no library chatter.
A mutation that leaves the file valid may of course succeed (exit 0, nothing on stderr).

Seeds are made by the program itself (a small phantom CT as .nii, .nii.gz, .mha, .mhd and .nrrd; a DRR as
.png and .tif) and written by hand (camera, pose and the model files of FORMATS.md); each is then
mutated deterministically from --seed: header fields set to extreme integers, NaN and infinities,
zero and negative sizes and spacings, unknown component types, random byte flips, truncation.

Usage: scripts/reader_robustness.py [--fluoro build/bin/fluoro] [--per-format 60] [--seed 1]
                                    [--keep DIR]   (copies every input that breaks the contract)
Prints one line per broken case and a table of outcomes per format; exit code 1 if any broke it.
"""
import argparse
import collections
import gzip
import json
import math
import os
import random
import resource
import shutil
import signal
import struct
import subprocess
import sys
import tempfile

MEMORY_LIMIT = 4 << 30  # a header promising terabytes must be refused, not attempted
TIMEOUT_S = 60


def limit_memory():
    resource.setrlimit(resource.RLIMIT_AS, (MEMORY_LIMIT, MEMORY_LIMIT))


def run(fluoro, args):
    """(class, exit code, stderr) of one run of the program."""
    try:
        p = subprocess.run([fluoro] + args, capture_output=True, timeout=TIMEOUT_S,
                           preexec_fn=limit_memory)
    except subprocess.TimeoutExpired:
        return "timeout", None, ""
    err = p.stderr.decode(errors="replace")
    return None, p.returncode, err


def classify(code, err, name):
    """The outcome class of a run whose input file is called `name`."""
    lines = err.count("\n")
    if code == 2 and lines == 1 and "absent.png: file not found" in err:
        return "ok"  # a model file's reader accepted it; the command then missed its image
    if code < 0:
        return "signal " + signal.Signals(-code).name
    if code == 0:
        return "ok" if lines == 0 else "ok but printed"
    if code == 1:
        return "internal error (exit 1)"
    if code == 2:
        if lines != 1:
            return "exit 2, %d lines" % lines
        return "exit 2, one line" if name in err else "exit 2, file not named"
    if code == 3:
        return "exit 3, one line" if lines == 1 else "exit 3, %d lines" % lines
    return "exit %d" % code


GOOD = {"ok", "exit 2, one line"}


# ---- seeds -------------------------------------------------------------------------------------

CAMERA = {"width": 48, "height": 48, "K": [[400, 0, 23.5], [0, 400, 23.5], [0, 0, 1]],
          "R": [[1, 0, 0], [0, 1, 0], [0, 0, 1]], "t": [0, 0, 400], "pixel_spacing_mm": [0.5, 0.5]}
POSE = {"T_world_ct": [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]}
GRID = {"kind": "hole_grid", "pitch_mm": 10.0, "hole_diameter_mm": 3.0, "rows": 25, "cols": 25,
        "thickness_mm": 7.0}
PHANTOM = {"kind": "fiducial_phantom", "fiducial_diameter_mm": 3.0,
           "fiducials": [{"id": "f%d" % i, "position_mm": [20.0 * (i % 3), 15.0 * (i // 3), 7.0 * i]}
                         for i in range(8)]}
GUIDE = {"kind": "drill_guide", "sphere_diameter_mm": 3.0,
         "spheres_mm": [[10.0 * (i % 3), 12.0 * (i // 3), 5.0 * i * i % 17] for i in range(7)],
         "axes": [{"name": "distal", "point_mm": [0, 0, 0], "direction": [0, 0, 1]},
                  {"name": "proximal", "point_mm": [30, 0, 0], "direction": [0, 0, 1]}]}
NAIL = {"kind": "nail", "diameter_mm": 10.0,
        "holes": [{"center_mm": [-15, 0, 0], "diameter_mm": 5.0},
                  {"center_mm": [15, 0, 0], "diameter_mm": 5.0}]}
ROBOT = {"T_base_tip": [[1, 0, 0, 100], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]],
         "T_tip_guide": [[0, -1, 0, 0], [1, 0, 0, 0], [0, 0, 1, 50], [0, 0, 0, 1]]}


def make_seeds(fluoro, d):
    def must(args):
        p = subprocess.run([fluoro] + args, capture_output=True)
        if p.returncode != 0:
            sys.exit("seed command failed: fluoro %s\n%s" % (" ".join(args), p.stderr.decode()))

    for ext in ("nii", "nii.gz", "mha", "mhd", "nrrd"):
        must(["phantom", "--size", "16", "--out", os.path.join(d, "seed." + ext)])
    with open(os.path.join(d, "cam.json"), "w") as f:
        json.dump(CAMERA, f)
    for ext in ("png", "tif"):
        must(["drr", "--ct", os.path.join(d, "seed.nii"), "--camera", os.path.join(d, "cam.json"),
              "--out", os.path.join(d, "seed." + ext), "--quiet"])


# ---- binary mutations ---------------------------------------------------------------------------

EXTREME_INTS = [0, -1, 1, 2, 3, 7, 8, 127, 255, 32767, -32768, 65535, 2**31 - 1, -2**31]
EXTREME_FLOATS = [0.0, -0.0, -1.0, 1e-30, 1e30, 3.4e38, float("nan"), float("inf"), float("-inf")]


def nifti_field_mutation(hdr, rng):
    """Sets one NIfTI-1 header field (offsets of nifti1.h) to an extreme value."""
    h = bytearray(hdr)
    int16_fields = {"dim0": 40, "dim1": 42, "dim2": 44, "dim3": 46, "dim4": 48, "datatype": 70,
                    "bitpix": 72, "qform_code": 252, "sform_code": 254, "slice_end": 120}
    float_fields = {"pixdim0": 76, "pixdim1": 80, "pixdim2": 84, "pixdim3": 88, "vox_offset": 108,
                    "scl_slope": 112, "scl_inter": 116, "quatern_b": 256, "quatern_c": 260,
                    "quatern_d": 264, "qoffset_x": 268, "srow_x0": 280, "srow_y1": 300,
                    "srow_z2": 320, "srow_z3": 324}
    if rng.random() < 0.45:
        name, off = rng.choice(sorted(int16_fields.items()))
        v = rng.choice(EXTREME_INTS)
        v = max(-32768, min(32767, v)) if name != "datatype" else rng.choice(
            [0, 1, 3, 5, 6, 99, 128, 255, 511, 1536, 1792, 2048, 2304, -1, 32767])
        struct.pack_into("<h", h, off, v)
    else:
        name, off = rng.choice(sorted(float_fields.items()))
        v = rng.choice(EXTREME_FLOATS)
        struct.pack_into("<f", h, off, v)
        if name.startswith(("quatern", "qoffset")):
            struct.pack_into("<h", h, 252, 1)  # make the qform count
        if name.startswith("srow"):
            struct.pack_into("<h", h, 254, 1)
    return bytes(h), "%s=%r" % (name, v)


def flip_bytes(data, rng, lo, hi, n):
    b = bytearray(data)
    for _ in range(n):
        i = rng.randrange(lo, min(hi, len(b)))
        b[i] = rng.choice([0, 0xff, 0x7f, 0x80, rng.randrange(256)])
    return bytes(b)


def mutate_nifti(raw, rng):
    r = rng.random()
    if r < 0.6:
        return nifti_field_mutation(raw, rng)
    if r < 0.8:
        return flip_bytes(raw, rng, 0, 352, rng.randint(1, 8)), "header bytes flipped"
    n = rng.randrange(0, len(raw))
    return raw[:n], "truncated to %d bytes" % n


# ---- MetaImage ------------------------------------------------------------------------------------

META_VALUES = {
    "NDims": ["0", "1", "2", "4", "-3", "99999999999", "3.5", "x"],
    "DimSize": ["0 12 12", "-1 12 12", "12 12", "4294967295 12 12", "99999999999 1 1",
                "65536 65536 65536", "12 12 12 12", "nan 12 12", "12 0 0"],
    "ElementSpacing": ["0 1 1", "-1 1 1", "nan 1 1", "inf 1 1", "1e308 1e308 1e308", "1e-320 1 1",
                       "1 1", ""],
    "ElementSize": ["0 0 0", "nan nan nan", "-1 1 1"],
    "Offset": ["nan 0 0", "inf 0 0", "1e308 0 0", "0"],
    "TransformMatrix": ["nan 0 0 0 1 0 0 0 1", "0 0 0 0 0 0 0 0 0", "1 0 0 1 0 0 0 0 1",
                        "inf 0 0 0 1 0 0 0 1", "1 0 0 0 1 0", "1e308 0 0 0 1e308 0 0 0 1e308"],
    "ElementType": ["MET_NONE", "MET_FOO", "MET_OTHER", "MET_STRING", "MET_UCHAR_ARRAY",
                    "MET_FLOAT_MATRIX", "MET_DOUBLE", "MET_CHAR", "MET_ULONG_LONG", "MET_FLOAT_ARRAY"],
    "ElementNumberOfChannels": ["0", "-1", "3", "2147483647", "99999999999"],
    "HeaderSize": ["-1", "-2", "99999999", "1", "-99999999999"],
    "CompressedData": ["True", "False", "x"],
    "CompressedDataSize": ["0", "1", "99999999999", "-5"],
    "BinaryDataByteOrderMSB": ["True", "x"],
    "ElementDataFile": ["LOCAL", "missing.raw", "LIST", "seed%03d.raw 1 3 1", ""],
    "ElementMin": ["nan"],
    "AnatomicalOrientation": ["XXX", "RAI", ""],
}


def split_metaimage(data):
    end = data.find(b"ElementDataFile")
    end = data.find(b"\n", end) + 1
    return data[:end].decode("latin-1").splitlines(), data[end:]


def mutate_metaimage(data, rng, detached):
    r = rng.random()
    lines, body = split_metaimage(data)
    if r < 0.7:
        key = rng.choice(sorted(META_VALUES))
        value = rng.choice(META_VALUES[key])
        if detached and key == "ElementDataFile" and value == "LOCAL":
            value = "missing.raw"
        new = "%s = %s" % (key, value)
        for i, line in enumerate(lines):
            if line.split("=")[0].strip() == key:
                lines[i] = new
                break
        else:
            lines.insert(rng.randrange(1, len(lines)), new)  # ElementDataFile stays last
        return ("\n".join(lines) + "\n").encode("latin-1") + body, new
    if r < 0.85:
        text = "\n".join(lines).encode("latin-1")
        return flip_bytes(text, rng, 0, len(text), rng.randint(1, 4)) + b"\n" + body, "header bytes flipped"
    n = rng.randrange(0, len(data))
    return data[:n], "truncated to %d bytes" % n


NRRD_VALUES = {
    "type": ["block", "int128", "float", "double", "uchar", "x", ""],
    "dimension": ["0", "-1", "2", "4", "17", "99999999999", "3.5", "x"],
    "sizes": ["0 16 16", "-1 16 16", "16 16", "4294967295 16 16", "99999999999 1 1", "65536 65536 65536",
              "16 16 16 16", "nan 16 16", "0x10 16 16"],
    "encoding": ["raw", "bzip2", "hex", "text", "zrl", "gzip", ""],
    "byte skip": ["-1", "-2", "99999999999", "x"],
    "line skip": ["-1", "99999999999"],
    "data file": ["missing.raw", "LIST", "m%03d.raw 1 0 0", "."],
    "spacings": ["0 1 1", "nan nan nan", "-1 1 1"],
    "space directions": ["(nan,0,0) (0,1,0) (0,0,1)", "(0,0,0) (0,0,0) (0,0,0)", "(1,0,0) (1,0,0) (0,0,1)",
                         "(1e308,0,0) (0,1,0) (0,0,1)"],
    "space origin": ["(nan,0,0)", "(1e308,0,0)", "(0,0)"],
}


def mutate_nrrd(data, rng):
    r = rng.random()
    end = data.find(b"\n\n") + 2
    lines, body = data[:end - 1].decode("latin-1").splitlines(), data[end:]
    if r < 0.7:
        key = rng.choice(sorted(NRRD_VALUES))
        new = "%s: %s" % (key, rng.choice(NRRD_VALUES[key]))
        for i, line in enumerate(lines):
            if line.split(":")[0].strip() == key:
                lines[i] = new
                break
        else:
            lines.insert(rng.randrange(1, len(lines) + 1), new)
        return ("\n".join(lines) + "\n\n").encode("latin-1") + body, new
    if r < 0.85:
        text = ("\n".join(lines) + "\n").encode("latin-1")
        return flip_bytes(text, rng, 0, len(text), rng.randint(1, 4)) + b"\n" + body, "header bytes flipped"
    n = rng.randrange(0, len(data))
    return data[:n], "truncated to %d bytes" % n


# ---- images ----------------------------------------------------------------------------------------

def mutate_raster(data, rng):
    r = rng.random()
    if r < 0.5:
        n = rng.randrange(0, len(data))
        return data[:n], "truncated to %d bytes" % n
    if r < 0.8:
        return flip_bytes(data, rng, 0, min(len(data), 200), rng.randint(1, 6)), "header bytes flipped"
    return flip_bytes(data, rng, 0, len(data), rng.randint(1, 30)), "bytes flipped anywhere"


# ---- JSON ---------------------------------------------------------------------------------------------

JSON_VALUES = [None, 0, -1, 1e308, -1e308, 2**63, 0.5, "nan", "x", [], {}, [1, 2], [[1]], True,
               [[float("nan")] * 3] * 3, 1e-320]


def json_paths(doc, prefix=()):
    yield prefix
    if isinstance(doc, dict):
        for k, v in doc.items():
            yield from json_paths(v, prefix + (k,))
    elif isinstance(doc, list):
        for i, v in enumerate(doc):
            yield from json_paths(v, prefix + (i,))


def mutate_json(doc, rng):
    r = rng.random()
    text = json.dumps(doc)
    if r < 0.15:
        n = rng.randrange(0, len(text))
        return text[:n].encode(), "truncated to %d bytes" % n
    if r < 0.25:
        return flip_bytes(text.encode(), rng, 0, len(text), rng.randint(1, 3)), "bytes flipped"
    doc = json.loads(text)
    paths = [p for p in json_paths(doc) if p]
    path = rng.choice(paths)
    parent = doc
    for k in path[:-1]:
        parent = parent[k]
    if rng.random() < 0.15 and isinstance(parent, dict):
        del parent[path[-1]]
        what = "deleted %s" % "/".join(map(str, path))
    elif rng.random() < 0.15 and isinstance(parent[path[-1]], list) and parent[path[-1]]:
        parent[path[-1]] = parent[path[-1]][:rng.randrange(len(parent[path[-1]]))]
        what = "shortened %s" % "/".join(map(str, path))
    else:
        v = rng.choice(JSON_VALUES)
        parent[path[-1]] = v
        what = "%s=%s" % ("/".join(map(str, path)), json.dumps(v)[:40])
    # NaN/Infinity are not JSON, but writers (Python's json) emit them: they must be refused too.
    return json.dumps(doc).encode(), what


# ---- the cases ----------------------------------------------------------------------------------------

def cases(d, per_format, rng):
    """(format, input file name, bytes, extra files {name: bytes}, description, commands)."""
    seeds = {ext: open(os.path.join(d, "seed." + ext), "rb").read()
             for ext in ("nii", "mha", "mhd", "png", "tif")}
    raw = open(os.path.join(d, "seed.raw"), "rb").read() if os.path.exists(
        os.path.join(d, "seed.raw")) else b""
    cam = os.path.join(d, "cam.json")

    def volume_cmds(f):
        return [["info", f], ["drr", "--ct", f, "--camera", cam, "--out", f + ".out.tif", "--quiet"]]

    for i in range(per_format):
        data, what = mutate_nifti(seeds["nii"], rng)
        yield "nii", "m%03d.nii" % i, data, {}, what, volume_cmds
    for i in range(per_format):
        data, what = mutate_nifti(seeds["nii"], rng)
        yield "nii.gz", "m%03d.nii.gz" % i, gzip.compress(data, 1), {}, what, volume_cmds
    for i in range(per_format):
        data, what = mutate_metaimage(seeds["mha"], rng, False)
        yield "mha", "m%03d.mha" % i, data, {}, what, volume_cmds
    for i in range(per_format):
        data, what = mutate_metaimage(seeds["mhd"], rng, True)
        extra = {}
        if b"seed.raw" in data:
            data = data.replace(b"seed.raw", b"m%03d.raw" % i)
            extra["m%03d.raw" % i] = raw if rng.random() < 0.6 else raw[:rng.randrange(len(raw) + 1)]
        yield "mhd", "m%03d.mhd" % i, data, extra, what, volume_cmds
    for ext in ("png", "tif"):
        for i in range(per_format // 2):
            data, what = mutate_raster(seeds[ext], rng)
            yield ext, "m%03d.%s" % (i, ext), data, {}, what, lambda f: [["info", f]]
    models = [("camera", CAMERA, lambda f: [["info", f], ["drr", "--ct", os.path.join(d, "seed.nii"),
                                                           "--camera", f, "--out", f + ".tif", "--quiet"]]),
              ("pose", POSE, lambda f: [["info", f]]),
              ("grid", GRID, lambda f: [["dewarp", "fit", "--image", "absent.png", "--grid", f,
                                         "--out", f + ".out.json"]]),
              ("phantom", PHANTOM, lambda f: [["calibrate", "--image", "absent.png", "--phantom", f,
                                               "--out", f + ".out.json"]]),
              ("guide", GUIDE, lambda f: [["distal-lock", "--image", "absent.png", "--camera", cam,
                                           "--guide", f, "--nail", os.path.join(d, "nail.json"),
                                           "--out", f + ".out.json"]]),
              ("nail", NAIL, lambda f: [["distal-lock", "--image", "absent.png", "--camera", cam,
                                         "--guide", os.path.join(d, "guide.json"), "--nail", f,
                                         "--out", f + ".out.json"]]),
              ("robot", ROBOT, lambda f: [["distal-lock", "--image", "absent.png", "--camera", cam,
                                           "--guide", os.path.join(d, "guide.json"), "--nail",
                                           os.path.join(d, "nail.json"), "--robot", f,
                                           "--out", f + ".out.json"]])]
    for name, doc, cmds in models:
        with open(os.path.join(d, name + ".json"), "w") as f:
            json.dump(doc, f)
    for name, doc, cmds in models:
        for i in range(per_format // 4):
            data, what = mutate_json(doc, rng)
            yield name, "%s%03d.json" % (name, i), data, {}, what, cmds
    # NRRD last, so that the other formats' mutations stay those of the documented runs.
    nrrd = open(os.path.join(d, "seed.nrrd"), "rb").read()
    for i in range(per_format):
        data, what = mutate_nrrd(nrrd, rng)
        yield "nrrd", "m%03d.nrrd" % i, data, {}, what, volume_cmds


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--fluoro", default=os.path.join(os.path.dirname(__file__), "..", "build", "bin", "fluoro"))
    ap.add_argument("--per-format", type=int, default=60)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--keep", help="directory to copy every contract-breaking input into")
    args = ap.parse_args()
    fluoro = os.path.abspath(args.fluoro)
    rng = random.Random(args.seed)
    table = collections.defaultdict(collections.Counter)
    broken = 0
    with tempfile.TemporaryDirectory(prefix="fluoro_robustness_") as d:
        make_seeds(fluoro, d)
        for fmt, name, data, extra, what, cmds in cases(d, args.per_format, rng):
            path = os.path.join(d, name)
            with open(path, "wb") as f:
                f.write(data)
            for extra_name, extra_data in extra.items():
                with open(os.path.join(d, extra_name), "wb") as f:
                    f.write(extra_data)
            for cmd in cmds(path):
                timeout, code, err = run(fluoro, cmd)
                outcome = timeout or classify(code, err, name)
                table["%-7s %s" % (fmt, cmd[0])][outcome] += 1
                if outcome not in GOOD:
                    broken += 1
                    first = err.strip().splitlines()[:3]
                    print("BROKEN %-24s %-8s %-22s %-36s | %s" % (
                        outcome, cmd[0], name, what[:36], " / ".join(first)[:300]), flush=True)
                    if args.keep:
                        os.makedirs(args.keep, exist_ok=True)
                        shutil.copy(path, os.path.join(args.keep, name))
            os.remove(path)
    total = sum(sum(c.values()) for c in table.values())
    print("\n%-20s %s" % ("format command", "outcomes"))
    for key in sorted(table):
        print("%-20s %s" % (key, ", ".join("%s: %d" % kv for kv in sorted(table[key].items()))))
    overall = collections.Counter()
    for c in table.values():
        overall.update(c)
    print("\nall %d runs: %s" % (total, ", ".join("%s: %d" % kv for kv in sorted(overall.items()))))
    print("broke the contract: %d of %d runs" % (broken, total))
    return 1 if broken else 0


if __name__ == "__main__":
    sys.exit(main())
