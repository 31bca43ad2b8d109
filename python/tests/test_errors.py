"""Bad arguments raise TypeError / ValueError naming the problem; the library's input errors
raise streamcvd.InputError (a ValueError), unwritable outputs streamcvd.OutputError (an OSError)."""
import numpy as np
import pytest

import streamcvd

TETRA_POINTS = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], dtype=np.float32)
TETRA_FACES = np.array([[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2]], dtype=np.int32)


@pytest.mark.parametrize("points, faces, error, words", [
    (TETRA_POINTS[:, :2], TETRA_FACES, ValueError, "points: expected shape (V, 3), got (4, 2)"),
    (TETRA_POINTS.ravel(), TETRA_FACES, ValueError, "points: expected shape (V, 3), got (12,)"),
    (TETRA_POINTS[:0], TETRA_FACES[:0], ValueError, "points: the mesh has no vertex"),
    (TETRA_POINTS.astype(str), TETRA_FACES, TypeError, "points: expected a float array"),
    (None, TETRA_FACES, TypeError, "points: expected a float array of shape (V, 3), got None"),
    (TETRA_POINTS, TETRA_FACES.astype(np.float32), TypeError, "faces: expected an integer array"),
    (TETRA_POINTS, TETRA_FACES[:, :2], ValueError, "faces: expected shape (F, 3), got (4, 2)"),
    (TETRA_POINTS, TETRA_FACES[:0], ValueError, "faces: the mesh has no face"),
    (TETRA_POINTS, TETRA_FACES + 1, ValueError, "faces: face 1 uses vertex 4, there are 4 vertices"),
    (TETRA_POINTS, TETRA_FACES - 1, ValueError, "faces: face 0 uses vertex -1 (negative)"),
    (TETRA_POINTS, (TETRA_FACES + 1).astype(np.uint32), ValueError, "uses vertex 4, there are 4 vertices"),
    (np.where(np.eye(4, 3) > 0, np.nan, TETRA_POINTS), TETRA_FACES, ValueError,
     "points: vertex 0 has a non-finite coordinate"),
    (TETRA_POINTS * np.float64(1e300), TETRA_FACES, ValueError, "non-finite coordinate (inf as float32)"),
])
@pytest.mark.filterwarnings("ignore:overflow encountered in cast:RuntimeWarning")
def test_bad_arrays(points, faces, error, words):
    with pytest.raises(error) as e:
        streamcvd.remesh(points, faces, 4)
    assert words in str(e.value)


@pytest.mark.parametrize("kwargs, error, words", [
    ({"n": 3}, ValueError, "n: at least 4 output vertices (a tetrahedron), got 3"),
    ({"n": 3_000_000_000}, ValueError, "n: expected 4 to 2000000000"),
    ({"n": "100"}, TypeError, "n: expected an int"),
    ({"n": 100.0}, TypeError, "n: expected an int"),
    ({"metric": "Q"}, ValueError, "metric: expected 'I', 'IQ', 'A' or 'AQ', got 'Q'"),
    ({"algorithm": "lloyd", "metric": "A"}, ValueError, "only the metrics I and IQ"),
    ({"small_components": "some"}, ValueError, "small_components: expected 'keep' or 'drop'"),
    ({"subdivide": 9}, ValueError, "subdivide: expected 'auto', 'none' or a level 0-6, got 9"),
    ({"gradation": 9.0}, ValueError, "gradation: expected"),
    ({"threads": -1}, ValueError, "threads: expected 0 to 4096"),
    ({"memory": "lots"}, streamcvd.InputError, "lots"),
    ({"memory": -5}, ValueError, "memory: expected a positive byte count"),
    ({"attributes": ["red"]}, TypeError, "remesh() takes a dict"),
    ({"attributes": {"red": np.zeros(3)}}, ValueError, "attributes['red']: expected shape (4,), got (3,)"),
    ({"attributes": {"red": np.full(4, np.inf)}}, ValueError, "attributes['red']: vertex 0 has a non-finite value"),
])
def test_bad_options(kwargs, error, words):
    kwargs = {"n": 4, **kwargs}
    with pytest.raises(error) as e:
        streamcvd.remesh(TETRA_POINTS, TETRA_FACES, **kwargs)
    assert words in str(e.value)


def test_keywords_only():
    with pytest.raises(TypeError):
        streamcvd.remesh(TETRA_POINTS, TETRA_FACES, 4, "IQ")


def test_input_errors_are_value_errors(data, tmp_path):
    assert issubclass(streamcvd.InputError, ValueError) and issubclass(streamcvd.OutputError, OSError)
    with pytest.raises(streamcvd.InputError, match="missing.ply"):
        streamcvd.read(tmp_path / "missing.ply")
    bad = tmp_path / "bad.off"
    bad.write_text("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 7\n")
    with pytest.raises(streamcvd.InputError, match="bad.off: line 6"):
        streamcvd.remesh_file(bad, tmp_path / "out.ply", 10)
    with pytest.raises(streamcvd.InputError, match="no vertex attribute 'red' in the input"):
        streamcvd.remesh_file(data / "fertility.off.zst", tmp_path / "out.ply", 100, attributes=["red"])
    with pytest.raises(streamcvd.InputError, match="out.xyz"):
        streamcvd.remesh_file(data / "fertility.off.zst", tmp_path / "out.xyz", 100)
    with pytest.raises(streamcvd.OutputError, match="no_such_folder"):
        streamcvd.remesh_file(data / "fertility.off.zst", tmp_path / "no_such_folder" / "out.ply", 100)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.off"]  # nothing left behind


def test_a_library_refusal_is_an_input_error():
    # Two far-apart tetrahedra, the small one dropped, and a budget the big one cannot take.
    points = np.concatenate([TETRA_POINTS, TETRA_POINTS * 1e-3 + 10])
    faces = np.concatenate([TETRA_FACES, TETRA_FACES + 4])
    with pytest.raises(streamcvd.InputError, match="<arrays>"):
        streamcvd.remesh(points, faces, 4, small_components="drop", subdivide="none")
