"""Ctrl-C during a job: KeyboardInterrupt, no output file and no temporary file left, and the
module works on afterwards; an exception of the progress callable does the same.

The interrupts are sent from inside the job (its progress callable, at a chosen stage) and the
callable then waits until the calling thread has seen the signal, so every test interrupts a job
that is running, whatever the machine's speed: nothing here depends on timing."""
import os
import signal
import threading

import pytest

import streamcvd
from conftest import torus


@pytest.fixture(scope="module")
def big(tmp_path_factory):
    """A 200k-face torus as arrays and as a binary PLY."""
    points, faces = torus(400, 250)
    path = tmp_path_factory.mktemp("big") / "torus.ply"
    streamcvd.write(path, points, faces)
    return points, faces, path


class CtrlCAt:
    """A progress callable that sends this process SIGINT (a terminal's Ctrl-C) at the first
    report of `stage`, then waits until the calling thread's SIGINT handler has run."""

    def __init__(self, stage):
        self.stage, self.stages, self.sent = stage, [], False
        self.handled = threading.Event()

    def __call__(self, report):
        self.stages.append(report["stage"])
        if report["stage"] == self.stage and not self.sent:
            self.sent = True
            os.kill(os.getpid(), signal.SIGINT)
            assert self.handled.wait(30), "the SIGINT handler did not run while the job ran"

    def __enter__(self):
        def handler(signum, frame):
            self.handled.set()
            raise KeyboardInterrupt

        self.previous = signal.signal(signal.SIGINT, handler)
        return self

    def __exit__(self, *exc):
        signal.signal(signal.SIGINT, self.previous)


@pytest.mark.parametrize("stage", ["read", "faces", "clustering", "placement"])
def test_interrupting_remesh_file_leaves_nothing(big, tmp_path, stage):
    out_dir = tmp_path / "out"
    out_dir.mkdir()
    with CtrlCAt(stage) as ctrl_c, pytest.raises(KeyboardInterrupt):
        streamcvd.remesh_file(big[2], out_dir / "torus.ply", 20_000, threads=2, work_dir=out_dir,
                              report=out_dir / "report.json", progress=ctrl_c)
    assert ctrl_c.sent and ctrl_c.handled.is_set()
    assert ctrl_c.stages[-1] == stage  # stopped at the stage's next report: no later stage ran
    assert list(out_dir.iterdir()) == []  # no output, no report, no work file


def test_interrupting_remesh_of_arrays(big):
    with CtrlCAt("clustering") as ctrl_c, pytest.raises(KeyboardInterrupt):
        streamcvd.remesh(big[0], big[1], 20_000, threads=2, progress=ctrl_c)
    assert ctrl_c.sent and ctrl_c.stages[-1] == "clustering"
    small = streamcvd.remesh(*torus(40, 20), 100, threads=1)
    assert small.points.shape == (100, 3)  # the module works on after an interrupt


def test_interrupting_ingest_leaves_no_store(big, tmp_path):
    with CtrlCAt("faces") as ctrl_c, pytest.raises(KeyboardInterrupt):
        streamcvd.ingest(big[2], tmp_path / "torus.store", work_dir=tmp_path, progress=ctrl_c)
    assert ctrl_c.sent
    assert list(tmp_path.iterdir()) == []


def test_an_exception_of_the_progress_callable_stops_the_job(big, tmp_path):
    class Stop(Exception):
        pass

    seen = []

    def progress(report):
        seen.append(report["stage"])
        if report["stage"] == "dual":
            raise Stop("enough")

    with pytest.raises(Stop, match="enough"):
        streamcvd.remesh_file(big[2], tmp_path / "torus.ply", 20_000, threads=2, work_dir=tmp_path, progress=progress)
    assert seen[-1] == "dual" and "clustering" in seen
    assert list(tmp_path.iterdir()) == []


def test_progress_reports_every_stage_in_order(big, tmp_path):
    reports = []
    r = streamcvd.remesh_file(big[2], tmp_path / "torus.ply", 20_000, threads=2, progress=reports.append)
    assert r.report["checks"]["all_ok"]
    stages = list(dict.fromkeys(p["stage"] for p in reports))
    assert stages[:2] == ["ingest", "read"]
    for later in ["items", "sampling", "clustering", "repair", "dual", "placement", "checks"]:
        assert later in stages
    assert stages.index("clustering") < stages.index("dual") < stages.index("placement")
    for p in reports:
        assert set(p) == {"stage", "done", "total", "unit", "round", "fraction", "finished"}
        assert p["fraction"] is None or 0.0 <= p["fraction"] <= 1.0
    read = [p for p in reports if p["stage"] == "read"]
    assert read[-1]["total"] == os.path.getsize(big[2]) and read[-1]["unit"] == "bytes"
    assert any(p["finished"] for p in reports if p["stage"] == "clustering")


def test_progress_must_be_callable(big, tmp_path):
    with pytest.raises(TypeError, match="progress"):
        streamcvd.remesh(*torus(40, 20), 100, progress=3)
