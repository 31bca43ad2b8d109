"""Fixtures of the streamcvd module tests: the bundled meshes, the CLI of the same build, and
procedural meshes made with numpy (no file of ../shared is used)."""
import os
import pathlib
import subprocess

import numpy as np
import pytest

import streamcvd

DATA = pathlib.Path(__file__).resolve().parents[2] / "tests" / "data"


@pytest.fixture(scope="session")
def data():
    """The folder of the bundled test meshes (tests/data)."""
    assert (DATA / "fertility.off.zst").exists(), DATA
    return DATA


@pytest.fixture(scope="session")
def cli():
    """Runs the streamcvd CLI of this build (STREAMCVD_CLI, set by ctest) and returns its stdout."""
    path = os.environ.get("STREAMCVD_CLI")
    if not path:
        pytest.skip("STREAMCVD_CLI is not set (run through ctest, or set it to build/streamcvd)")

    def run(*args):
        done = subprocess.run([path, *map(str, args)], capture_output=True, text=True)
        assert done.returncode == 0, done.stderr
        return done.stdout

    return run


@pytest.fixture(scope="session")
def fertility():
    """The bundled fertility mesh (genus 4, closed), read by the module."""
    return streamcvd.read(DATA / "fertility.off.zst")


def torus(rings, segments, major=1.0, minor=0.35):
    """A closed torus of rings x segments vertices: (points float64, faces int64)."""
    u = np.linspace(0, 2 * np.pi, rings, endpoint=False)
    v = np.linspace(0, 2 * np.pi, segments, endpoint=False)
    uu, vv = np.meshgrid(u, v, indexing="ij")
    points = np.stack([(major + minor * np.cos(vv)) * np.cos(uu),
                       (major + minor * np.cos(vv)) * np.sin(uu),
                       minor * np.sin(vv)], axis=-1).reshape(-1, 3)
    i, j = np.meshgrid(np.arange(rings), np.arange(segments), indexing="ij")
    a = i * segments + j
    b = ((i + 1) % rings) * segments + j
    c = ((i + 1) % rings) * segments + (j + 1) % segments
    d = i * segments + (j + 1) % segments
    faces = np.concatenate([np.stack([a, b, c], -1).reshape(-1, 3), np.stack([a, c, d], -1).reshape(-1, 3)])
    return points, faces
