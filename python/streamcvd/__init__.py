"""streamcvd: discrete centroidal Voronoi remeshing of large triangle meshes.

Arrays in, arrays out: ``remesh(points, faces, n)`` returns a ``Result`` whose ``points`` and
``faces`` are numpy arrays and whose ``report`` is the dict of ``streamcvd remesh --report``.
``remesh_file`` runs the same job file to file, out of core. See help(streamcvd.remesh).
"""
from ._core import (
    InputError,
    Mesh,
    OutputError,
    Result,
    __version__,
    distance,
    info,
    ingest,
    quality,
    read,
    remesh,
    remesh_file,
    write,
)

__all__ = [
    "InputError", "Mesh", "OutputError", "Result", "__version__", "distance", "info", "ingest",
    "quality", "read", "remesh", "remesh_file", "write",
]

for _type in (InputError, Mesh, OutputError, Result):
    _type.__module__ = __name__  # streamcvd.Result, not streamcvd._core.Result, in reprs and errors
del _type
