# Type hints of the streamcvd package (the extension streamcvd._core); docstrings: help(streamcvd.remesh).
import os
from typing import Any, Callable, Literal, Sequence, Union

import numpy as np
import numpy.typing as npt

__version__: str
__all__: list[str]

PathLike = Union[str, os.PathLike[str]]
Memory = Union[None, int, str]  # None (default limit), bytes, or "512M"
Metric = Literal["I", "IQ", "A", "AQ"]
MeshLike = Union["Mesh", tuple[npt.ArrayLike, npt.ArrayLike]]
Progress = Callable[[dict[str, Any]], object] | None  # called with {"stage", "done", "total", "unit", "round", "fraction", "finished"}

class InputError(ValueError): ...
class OutputError(OSError): ...

class Mesh:
    @property
    def points(self) -> npt.NDArray[np.float32]: ...  # (V, 3)
    @property
    def faces(self) -> npt.NDArray[np.uint32]: ...  # (F, 3)
    @property
    def attributes(self) -> dict[str, npt.NDArray[np.float32]]: ...  # {name: (V,)}
    @property
    def attribute_types(self) -> dict[str, str]: ...  # {name: "uchar" | "float" | ...}
    def write(self, path: PathLike, *, ascii: bool = False) -> None: ...

class Result(Mesh):
    @property
    def report(self) -> dict[str, Any]: ...  # the JSON report of `streamcvd remesh --report`

def remesh(
    points: npt.ArrayLike,
    faces: npt.ArrayLike,
    n: int,
    *,
    metric: Metric = "IQ",
    gradation: float = 0.0,
    seed: int = 20080401,
    threads: int = 0,
    deterministic: bool = False,
    small_components: Literal["keep", "drop"] = "keep",
    boundary_strips: bool = True,
    memory: Memory = None,
    attributes: dict[str, npt.ArrayLike] | None = None,
    algorithm: Literal["cvd", "lloyd"] = "cvd",
    curvature_rings: int = 3,
    qem_threshold: float = 0.01,
    subdivide: Union[Literal["auto", "none"], int] = "auto",
    project: bool = True,
    optimize: bool = True,
    work_dir: PathLike | None = None,
    progress: Progress = None,
) -> Result: ...

def remesh_file(
    input: PathLike,
    output: PathLike,
    n: int,
    *,
    metric: Metric = "IQ",
    gradation: float = 0.0,
    seed: int = 20080401,
    threads: int = 0,
    deterministic: bool = False,
    small_components: Literal["keep", "drop"] = "keep",
    boundary_strips: bool = True,
    memory: Memory = None,
    attributes: Union[None, Literal["all", "none"], Sequence[str]] = None,
    algorithm: Literal["cvd", "lloyd"] = "cvd",
    curvature_rings: int = 3,
    qem_threshold: float = 0.01,
    subdivide: Union[Literal["auto", "none"], int] = "auto",
    project: bool = True,
    optimize: bool = True,
    work_dir: PathLike | None = None,
    progress: Progress = None,
    report: PathLike | None = None,
    keep_work: bool = False,
    ascii: bool = False,
) -> Result: ...

def read(path: PathLike, *, attributes: Union[Literal["all", "none"], Sequence[str]] = "all") -> Mesh: ...
def write(
    path: PathLike,
    points: npt.ArrayLike,
    faces: npt.ArrayLike,
    attributes: dict[str, npt.ArrayLike] | None = None,
    *,
    attribute_types: dict[str, str] | None = None,
    ascii: bool = False,
    comment: str = "",
) -> None: ...
def ingest(
    input: PathLike, store: PathLike, *, memory: Memory = None, work_dir: PathLike | None = None,
    threads: int = 0, faces_per_chunk: int = 1048576, progress: Progress = None,
) -> dict[str, Any]: ...
def quality(points: Union[npt.ArrayLike, Mesh], faces: npt.ArrayLike | None = None) -> dict[str, Any]: ...
def info(
    mesh: Union[PathLike, MeshLike, npt.ArrayLike], faces: npt.ArrayLike | None = None, *,
    memory: Memory = None, work_dir: PathLike | None = None, threads: int = 0,
) -> dict[str, Any]: ...
def distance(
    a: Union[MeshLike, PathLike], b: Union[MeshLike, PathLike], *, samples: int = 1000000, seed: int = 1,
    threads: int = 0,
) -> dict[str, Any]: ...
