"""remesh() and remesh_file(): shapes and dtypes, the CLI's bytes and report, attributes, no copies."""
import json
import threading
import time

import numpy as np
import pytest

import streamcvd
from conftest import torus

# Report entries that measure the run (times, memory, disk traffic) or name its files.
VOLATILE = {"seconds", "seconds_per_loop", "peak_rss_bytes", "memory", "io", "file", "clustering_cpu"}


def comparable(report):
    """The report without its measurements: what two runs of the same job share."""
    if isinstance(report, dict):
        return {k: comparable(v) for k, v in report.items() if k not in VOLATILE}
    if isinstance(report, list):
        return [comparable(v) for v in report]
    return report


def test_version_is_the_library_version(cli):
    assert cli("--version").split() == ["streamcvd", streamcvd.__version__]


def test_result_shapes_and_dtypes(fertility):
    r = streamcvd.remesh(fertility.points, fertility.faces, 3000, threads=1)
    assert isinstance(r, streamcvd.Result) and isinstance(r, streamcvd.Mesh)
    assert r.points.shape == (3000, 3) and r.points.dtype == np.float32
    assert r.faces.ndim == 2 and r.faces.shape[1] == 3 and r.faces.dtype == np.uint32
    assert r.points.flags.c_contiguous and r.faces.flags.c_contiguous
    assert r.faces.max() == 2999 and len(np.unique(r.faces)) == 3000
    assert r.report["output"]["vertices"] == 3000
    assert r.report["checks"]["all_ok"] is True
    assert r.report["checks"]["genus_preserved"] is True
    assert r.attributes == {} and r.attribute_types == {}


def test_float64_and_int64_inputs_give_the_same_output(fertility):
    a = streamcvd.remesh(fertility.points, fertility.faces, 500, threads=1)
    b = streamcvd.remesh(fertility.points.astype(np.float64), fertility.faces.astype(np.int64), 500, threads=1)
    c = streamcvd.remesh(fertility.points.tolist(), fertility.faces.tolist(), 500, threads=1)
    assert np.array_equal(a.points, b.points) and np.array_equal(a.faces, b.faces)
    assert np.array_equal(a.points, c.points) and np.array_equal(a.faces, c.faces)


def test_same_bytes_and_report_as_the_cli(cli, data, fertility, tmp_path):
    src = data / "fertility.off.zst"
    cli("remesh", src, "-o", tmp_path / "cli.ply", "-n", 3000, "--threads", 1, "--report", tmp_path / "cli.json", "-q")
    r = streamcvd.remesh(fertility.points, fertility.faces, 3000, threads=1)
    r.write(tmp_path / "arrays.ply")
    f = streamcvd.remesh_file(src, tmp_path / "file.ply", 3000, threads=1, report=tmp_path / "file.json")
    expected = (tmp_path / "cli.ply").read_bytes()
    assert (tmp_path / "arrays.ply").read_bytes() == expected
    assert (tmp_path / "file.ply").read_bytes() == expected
    cli_report = json.loads((tmp_path / "cli.json").read_text())
    assert json.loads((tmp_path / "file.json").read_text())["output"]["file"] == str(tmp_path / "file.ply")
    assert comparable(f.report) == comparable(cli_report)
    assert comparable(r.report) == comparable(cli_report)
    assert f.report["input"]["file"] == str(src) and r.report["input"]["file"] == "<arrays>"
    # The arrays of remesh_file's result are the mesh it wrote.
    assert np.array_equal(f.points, r.points) and np.array_equal(f.faces, r.faces)


def test_options_reach_the_engine(fertility):
    r = streamcvd.remesh(fertility.points, fertility.faces, 800, metric="i", gradation=0.5, seed=7, threads=2,
                         deterministic=True, optimize=False, subdivide="none")
    opts = r.report["options"]
    assert (opts["metric"], opts["gradation"], opts["seed"], opts["deterministic"]) == ("I", 0.5, 7, True)
    assert (opts["threads"], opts["subdivide"]) == (2, "none")
    assert r.report["quality_pass"]["enabled"] is False
    again = streamcvd.remesh(fertility.points, fertility.faces, 800, metric="I", gradation=0.5, seed=7, threads=1,
                             deterministic=True, optimize=False, subdivide="none")
    assert np.array_equal(r.points, again.points) and np.array_equal(r.faces, again.faces)


def coloured_torus():
    points, faces = torus(120, 60)
    x = points[:, 0]
    red = np.round(255 * (x - x.min()) / np.ptp(x)).astype(np.uint8)
    return points, faces, {"red": red, "confidence": (points[:, 2] + 1).astype(np.float32)}


def test_attributes_are_carried_as_cluster_means(tmp_path):
    points, faces, attributes = coloured_torus()
    r = streamcvd.remesh(points, faces, 1000, threads=1, attributes=attributes)
    assert set(r.attributes) == {"red", "confidence"}
    assert r.attribute_types == {"red": "uchar", "confidence": "float"}
    red = r.attributes["red"]
    assert red.shape == (1000,) and red.dtype == np.float32
    x = r.points[:, 0]
    expected = 255 * (x - points[:, 0].min()) / np.ptp(points[:, 0])
    assert np.abs(red - expected).mean() < 0.02 * 255  # the colour follows the position
    assert np.abs(r.attributes["confidence"] - (r.points[:, 2] + 1)).max() < 0.05
    assert [a["name"] for a in r.report["attributes"]["carried"]] == ["red", "confidence"]
    r.write(tmp_path / "out.ply")
    back = streamcvd.read(tmp_path / "out.ply")
    assert back.attribute_types == {"red": "uchar", "confidence": "float"}
    assert np.array_equal(back.attributes["red"], np.clip(np.round(red), 0, 255))


def test_attributes_from_a_file_as_the_cli(cli, data, tmp_path):
    src = data / "bun_zipper_res2.ply"
    cli("remesh", src, "-o", tmp_path / "cli.ply", "-n", 1500, "--threads", 1, "--attributes", "confidence", "-q")
    f = streamcvd.remesh_file(src, tmp_path / "py.ply", 1500, threads=1, attributes=["confidence"])
    assert (tmp_path / "py.ply").read_bytes() == (tmp_path / "cli.ply").read_bytes()
    assert list(f.attributes) == ["confidence"]
    mesh = streamcvd.read(src)
    assert mesh.attribute_types == {"confidence": "float", "intensity": "float"}
    r = streamcvd.remesh(mesh.points, mesh.faces, 1500, threads=1, attributes={"confidence": mesh.attributes["confidence"]})
    assert np.array_equal(r.attributes["confidence"], f.attributes["confidence"])


def test_arrays_are_handed_over_without_a_copy(fertility):
    r = streamcvd.remesh(fertility.points, fertility.faces, 500, threads=1,
                         attributes={"a": fertility.points[:, 0], "b": fertility.points[:, 1]})
    for array in (r.points, r.faces, fertility.points):
        assert not array.flags.owndata  # the library's buffer, owned by a capsule
        assert type(array.base).__name__ == "PyCapsule"
    a, b = r.attributes["a"], r.attributes["b"]
    assert a.base is b.base and a.base.shape == (500, 2)  # columns of one (V, 2) buffer
    assert a.strides == (8,) and not a.flags.writeable and not a.base.flags.owndata
    points = r.points
    del r
    assert np.isfinite(points.sum())  # still alive: the capsule owns the buffer


def test_the_gil_is_released_during_the_job(fertility):
    done = threading.Event()
    worker = threading.Thread(
        target=lambda: (streamcvd.remesh(fertility.points, fertility.faces, 3000, threads=1), done.set()))
    ticks = 0
    worker.start()
    start = time.monotonic()
    while not done.is_set():
        ticks += 1
        time.sleep(0.001)
    worker.join()
    assert time.monotonic() - start > 0.05 and ticks > 20  # Python ran while the job did


def test_result_from_a_store(cli, data, tmp_path):
    store = tmp_path / "fertility.store"
    record = streamcvd.ingest(data / "fertility.off.zst", store)
    assert (record["vertices"], record["faces"]) == (4494, 9000) and record["store"] == str(store)
    cli("remesh", store, "-o", tmp_path / "cli.ply", "-n", 2000, "--threads", 1, "-q")
    streamcvd.remesh_file(store, tmp_path / "py.ply", 2000, threads=1, memory="64M")
    assert (tmp_path / "py.ply").read_bytes() == (tmp_path / "cli.ply").read_bytes()
