"""Meshes MuJoCo cannot read, converted into binary STL files it can, as RViz shows them.

MuJoCo reads binary STL, OBJ and MSH. Robot descriptions also ship ASCII STL files (RViz and
Gazebo read them) and COLLADA (``.dae``) files. ``mujoco_meshes(path)`` says what MuJoCo
should load for a mesh file: None when it reads the file as it is, else one or more
:class:`MeshPart` (a binary STL and the colour its material gives, if any). The conversion
is trimesh's (and pycollada's, for COLLADA), done as RViz and MoveIt's geometric_shapes read
the file: the scene's node transforms are applied, ``<unit meter>`` scales the vertices and
``<up_axis>`` is ignored (RViz ignores it). A COLLADA file's triangles are grouped by
material colour, one part per colour, so a visual keeps its colours; ``whole=True`` gives
one part (a collision mesh).

Converted files are cached by content in ``$XDG_CACHE_HOME/cosim/meshes`` (``~/.cache``
without it) as ``STEM-HASH[-N].stl``, HASH the source file's bytes and the converter's
version, written atomically, so every process of a run and every later run reads the same
file and converts nothing twice. Vertices are transformed with elementwise arithmetic only
(no BLAS product, whose last bits depend on the CPU), so a file converts to the same bytes
everywhere.
"""

from __future__ import annotations

import functools
import hashlib
import importlib.metadata
import os
import struct
import tempfile
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

import numpy as np

CONVERTER = "cosim-mesh-1"  # part of every cache key: change it when the conversion changes
CONVERTED = (".dae",)  # formats converted (besides ASCII STL)


class MeshError(ValueError):
    """A mesh file that cannot be read or converted; the message says why."""


@dataclass(frozen=True)
class MeshPart:
    """One mesh MuJoCo loads: a binary STL file and its material's colour (None: none)."""

    path: str
    rgba: tuple[float, float, float, float] | None = None


def cache_dir(kind: str = "meshes") -> Path:
    """This user's folder of derived files of one ``kind`` (converted meshes; USD robots as
    URDF), created when missing; one under the system's temporary folder, named by the user,
    where the cache folder cannot be written."""
    folder = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "cosim" / kind
    try:
        folder.mkdir(parents=True, exist_ok=True)
        if os.access(folder, os.W_OK):
            return folder
    except OSError:
        pass
    folder = Path(tempfile.gettempdir()) / f"cosim-{kind}-{os.getuid()}"
    folder.mkdir(parents=True, exist_ok=True)
    return folder


@functools.lru_cache(maxsize=1)
def converter_id() -> bytes:
    """What a conversion's result depends on besides the file: cosim's conversion and the
    versions of the libraries that read the meshes (an upgrade converts again)."""
    versions = []
    for name in ("trimesh", "pycollada"):
        try:
            versions.append(f"{name}-{importlib.metadata.version(name)}")
        except importlib.metadata.PackageNotFoundError:
            versions.append(f"{name}-none")
    return " ".join([CONVERTER, *versions]).encode()


def is_ascii_stl(path: Path) -> bool:
    """True for an STL file that is not binary STL (MuJoCo's test: 84 + 50 bytes a facet)."""
    size = path.stat().st_size
    if size < 84:
        return True
    with path.open("rb") as f:
        f.seek(80)
        (count,) = struct.unpack("<I", f.read(4))
    return size != 84 + 50 * count


def mujoco_meshes(path: Path, whole: bool = False) -> list[MeshPart] | None:
    """What MuJoCo loads for the mesh file ``path``: None for a file it reads as it is (OBJ,
    MSH, binary STL), the converted parts for an ASCII STL or a COLLADA file. MeshError for
    a file that does not convert or holds no triangles."""
    suffix = path.suffix.lower()
    if suffix == ".stl" and not is_ascii_stl(path):
        return None
    if suffix != ".stl" and suffix not in CONVERTED:
        return None
    stat = path.stat()
    whole = whole and suffix != ".stl"  # an STL file is one part anyway
    return list(_converted(str(path.resolve()), stat.st_mtime_ns, stat.st_size, whole))


@functools.lru_cache(maxsize=256)
def _converted(path: str, mtime_ns: int, size: int, whole: bool) -> tuple[MeshPart, ...]:
    source = Path(path)
    data = source.read_bytes()
    digest = hashlib.sha256(converter_id() + b"\0" + data).hexdigest()[:16]
    stem = f"{source.stem}-{digest}" + ("-whole" if whole else "")
    folder = cache_dir()
    index = folder / f"{stem}.parts"
    if index.is_file():  # converted before, by this process or another
        parts = _read_index(folder, index)
        if all(Path(p.path).is_file() for p in parts):
            return tuple(parts)
    groups = _triangles(source, data)
    if whole:
        groups = [(np.concatenate([t for t, _ in groups]), None)]
    parts = []
    for i, (triangles, rgba) in enumerate(groups):
        name = f"{stem}.stl" if len(groups) == 1 else f"{stem}-{i}.stl"
        write_atomic(folder / name, _binary_stl(triangles))
        parts.append(MeshPart(str(folder / name), rgba))
    lines = [f"{Path(p.path).name} {' '.join(f'{c:.6g}' for c in p.rgba) if p.rgba else '-'}"
             for p in parts]
    write_atomic(index, ("\n".join(lines) + "\n").encode())
    return tuple(parts)


def _read_index(folder: Path, index: Path) -> list[MeshPart]:
    parts = []
    for line in index.read_text().splitlines():
        name, *rgba = line.split()
        colour = None if rgba == ["-"] else tuple(float(c) for c in rgba)
        parts.append(MeshPart(str(folder / name), colour))
    return parts


def _triangles(source: Path, data: bytes) -> list[tuple[np.ndarray, tuple | None]]:
    """(triangles (n, 3, 3) in metres, rgba or None) per colour of the file."""
    import trimesh

    kind = source.suffix.lower().lstrip(".")
    try:
        loaded = trimesh.load(trimesh.util.wrap_as_stream(data), file_type=kind,
                              force="scene")
    except Exception as exc:  # trimesh raises many kinds; all mean "does not read"
        raise MeshError(f"{source.suffix} file does not read ({type(exc).__name__}: "
                        f"{exc})") from None
    scale = _collada_unit(data) if kind == "dae" else 1.0
    groups: dict[tuple | None, list[np.ndarray]] = {}
    for node in loaded.graph.nodes_geometry:
        transform, name = loaded.graph[node]
        mesh = loaded.geometry[name]
        if not hasattr(mesh, "faces") or len(mesh.faces) == 0:
            continue
        vertices = _transformed(np.asarray(mesh.vertices, dtype=float), transform) * scale
        groups.setdefault(_colour(mesh) if kind == "dae" else None, []).append(
            vertices[np.asarray(mesh.faces)])
    if not groups:
        raise MeshError(f"{source.suffix} file holds no triangles")
    return [(np.concatenate(t), c) for c, t in groups.items()]


def _transformed(vertices: np.ndarray, transform: np.ndarray) -> np.ndarray:
    """``vertices`` (n, 3) moved by the 4x4 ``transform``, elementwise (no BLAS)."""
    t = np.asarray(transform, dtype=float)
    return (vertices[:, 0:1] * t[:3, 0] + vertices[:, 1:2] * t[:3, 1]
            + vertices[:, 2:3] * t[:3, 2] + t[:3, 3])


def _collada_unit(data: bytes) -> float:
    """The document's ``<asset><unit meter>`` (1 when absent), as RViz reads it."""
    try:
        root = ET.fromstring(data)
    except ET.ParseError:
        return 1.0
    for el in root.iter():
        if el.tag.rsplit("}", 1)[-1] == "unit" and el.get("meter"):
            try:
                return float(el.get("meter"))
            except ValueError:
                return 1.0
    return 1.0


def _colour(mesh) -> tuple[float, float, float, float] | None:
    """The diffuse colour of a COLLADA mesh's material, None without one."""
    material = getattr(mesh.visual, "material", None)
    for attr in ("baseColorFactor", "diffuse"):
        value = getattr(material, attr, None)
        if value is not None:
            rgba = np.asarray(value, dtype=float).ravel()
            if rgba.size >= 3:
                rgba = rgba / 255.0 if rgba.max() > 1.0 else rgba
                alpha = float(rgba[3]) if rgba.size > 3 else 1.0
                return (round(float(rgba[0]), 4), round(float(rgba[1]), 4),
                        round(float(rgba[2]), 4), round(alpha, 4))
    return None


def _binary_stl(triangles: np.ndarray) -> bytes:
    """Binary STL bytes of triangles (n, 3, 3): header, count, per facet normal and corners."""
    tri = np.asarray(triangles, dtype=np.float32).reshape(-1, 3, 3)
    normals = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    length = np.sqrt((normals * normals).sum(axis=1, keepdims=True))
    normals = np.divide(normals, length, out=np.zeros_like(normals), where=length > 0)
    record = np.zeros(len(tri), dtype=[("n", "<f4", 3), ("v", "<f4", (3, 3)), ("a", "<u2")])
    record["n"], record["v"] = normals, tri
    header = CONVERTER.encode().ljust(80, b"\0")
    return header + struct.pack("<I", len(tri)) + record.tobytes()


def write_atomic(path: Path, data: bytes) -> None:
    """Write ``path`` whole or not at all (processes converting the same file at once each
    write their own temporary file and rename it in place)."""
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.")
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
