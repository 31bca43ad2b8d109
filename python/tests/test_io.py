"""read(), write(), quality(), info(), distance(), ingest(): the CLI's figures, round trips."""
import json

import numpy as np
import pytest

import streamcvd
from conftest import torus


def test_read_shapes_and_dtypes(fertility, data):
    assert fertility.points.shape == (4494, 3) and fertility.points.dtype == np.float32
    assert fertility.faces.shape == (9000, 3) and fertility.faces.dtype == np.uint32
    bunny = streamcvd.read(data / "bun_zipper_res2.ply", attributes=["intensity"])
    assert list(bunny.attributes) == ["intensity"] and bunny.attributes["intensity"].shape == (8171,)
    assert streamcvd.read(data / "bun_zipper_res2.ply", attributes="none").attributes == {}


@pytest.mark.parametrize("suffix", [".ply", ".obj", ".off", ".stl", ".ply.zst"])
def test_write_read_round_trip(fertility, tmp_path, suffix):
    path = tmp_path / ("m" + suffix)
    streamcvd.write(path, fertility.points, fertility.faces)
    back = streamcvd.read(path)
    if suffix == ".stl":  # corners by value: the vertices come back in order of first appearance
        assert np.array_equal(back.points[back.faces], fertility.points[fertility.faces])
        return
    assert np.array_equal(back.points, fertility.points) and np.array_equal(back.faces, fertility.faces)


def test_write_attributes_types_and_comment(tmp_path):
    points, faces = torus(20, 10)
    values = np.arange(len(points)) % 256
    streamcvd.write(tmp_path / "a.ply", points, faces, {"red": values.astype(np.uint8), "q": values / 7},
                    attribute_types={"q": "float"}, ascii=True, comment="made by a test")
    text = (tmp_path / "a.ply").read_text()
    assert "comment made by a test" in text
    assert "property uchar red" in text and "property float q" in text
    back = streamcvd.read(tmp_path / "a.ply")
    assert np.array_equal(back.attributes["red"], values)
    assert np.allclose(back.attributes["q"], values / 7, rtol=1e-6)
    with pytest.raises(ValueError, match="attribute_types\\['q'\\]: expected one of"):
        streamcvd.write(tmp_path / "b.ply", points, faces, {"q": values}, attribute_types={"q": "half"})


def strip_file(record):
    return {k: v for k, v in record.items() if k not in ("file", "a", "b")}


def test_quality_info_distance_are_the_cli_records(cli, data, fertility, tmp_path):
    src = data / "fertility.off.zst"
    assert streamcvd.quality(fertility) == strip_file(json.loads(cli("quality", "--json", src)))
    assert streamcvd.quality(fertility.points, fertility.faces)["q_avg"] > 0.3
    cli_info = json.loads(cli("info", "--json", src))
    assert streamcvd.info(src) == cli_info
    assert streamcvd.info(fertility) == {**cli_info, "file": "<arrays>"}
    assert cli_info["genus"] == 4
    r = streamcvd.remesh(fertility.points, fertility.faces, 1000, threads=1)
    r.write(tmp_path / "r.ply")
    d = streamcvd.distance(fertility, (r.points, r.faces), samples=20000, seed=3)
    expected = json.loads(cli("distance", "--json", "--samples", 20000, "--seed", 3, src, tmp_path / "r.ply"))
    assert d == {k: v for k, v in expected.items() if k in d}
    assert 0 < d["hausdorff_relative"] < 0.05
    assert streamcvd.distance(src, tmp_path / "r.ply", samples=20000, seed=3) == d


def test_info_of_a_defective_soup_reports_the_cleaning():
    points, faces = torus(30, 12)
    faces = np.concatenate([faces, faces[:5]])  # five duplicate faces
    record = streamcvd.info(points, faces)
    assert record["duplicate_faces"] == 5
    assert record["cleaning"]["rebuilt"] is True and record["cleaning"]["duplicate_faces_dropped"] == 5
