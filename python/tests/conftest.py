"""Shared fixtures: the fluoro program (FLUORO_CLI, set by ctest; else the build tree's bin/)."""
import os
import pathlib
import subprocess

import pytest

import fluoro


@pytest.fixture(scope="session")
def cli():
    path = os.environ.get("FLUORO_CLI") or str(pathlib.Path(fluoro.__file__).resolve().parent.parent / "bin" / "fluoro")
    assert os.access(path, os.X_OK), f"the fluoro program is not at {path} (set FLUORO_CLI)"

    def run(*args, check=True):
        r = subprocess.run([path, *map(str, args)], capture_output=True, text=True)
        if check:
            assert r.returncode == 0, r.stderr
        return r

    return run
