"""Ctrl-C during a job: KeyboardInterrupt soon after, no output file and no temporary file left,
and the module works on afterwards."""
import os
import signal
import threading
import time

import numpy as np
import pytest

import streamcvd
from conftest import torus


@pytest.fixture(scope="module")
def big(tmp_path_factory):
    """A 1.2M-face torus as arrays and as a binary PLY: a few seconds of remeshing on 2 cores."""
    points, faces = torus(1000, 600)
    path = tmp_path_factory.mktemp("big") / "torus.ply"
    streamcvd.write(path, points, faces)
    return points, faces, path


def interrupt_after(seconds):
    """Sends this process SIGINT after `seconds` (from another thread, as a terminal's Ctrl-C)."""
    sent = []
    timer = threading.Timer(seconds, lambda: (sent.append(time.monotonic()), os.kill(os.getpid(), signal.SIGINT)))
    timer.start()
    return timer, sent


@pytest.mark.parametrize("delay", [0.2, 1.0])
def test_interrupting_remesh_file_leaves_nothing(big, tmp_path, delay):
    out_dir = tmp_path / "out"
    out_dir.mkdir()
    timer, sent = interrupt_after(delay)
    try:
        with pytest.raises(KeyboardInterrupt):
            streamcvd.remesh_file(big[2], out_dir / "torus_50k.ply", 50_000, threads=2, work_dir=out_dir,
                                  report=out_dir / "report.json")
    finally:
        timer.cancel()  # a job that ended first must not leave a signal for pytest
        timer.join()
    assert sent, "the job ended before the interrupt: make the mesh larger"
    assert time.monotonic() - sent[0] < 5.0  # stopped at the next stage or clustering loop
    assert list(out_dir.iterdir()) == []  # no output, no report, no work file


def test_interrupting_remesh_of_arrays(big):
    timer, sent = interrupt_after(0.8)
    try:
        with pytest.raises(KeyboardInterrupt):
            streamcvd.remesh(big[0], big[1], 50_000, threads=2)
    finally:
        timer.cancel()
        timer.join()
    assert sent and time.monotonic() - sent[0] < 5.0
    small = streamcvd.remesh(*torus(40, 20), 100, threads=1)
    assert small.points.shape == (100, 3)  # the module works on after an interrupt


def test_the_uninterrupted_job_takes_longer_than_the_delays(big, tmp_path):
    start = time.monotonic()
    r = streamcvd.remesh_file(big[2], tmp_path / "torus_50k.ply", 50_000, threads=2)
    assert time.monotonic() - start > 1.0  # else the tests above interrupt nothing but a finished job
    assert r.report["checks"]["all_ok"] and (tmp_path / "torus_50k.ply").exists()
