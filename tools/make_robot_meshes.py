"""Write the meshes of the test robots under scenarios/robots/ (binary STL and OBJ, made
here so that nothing in them comes from elsewhere): ``python tools/make_robot_meshes.py``."""

from __future__ import annotations

import math
import struct
from pathlib import Path

import numpy as np

ROBOTS = Path(__file__).resolve().parent.parent / "scenarios" / "robots"


def cylinder(radius: float, length: float, segments: int = 24) -> np.ndarray:
    """Triangles (n, 3, 3) of a closed cylinder along z, centred at the origin."""
    a = np.linspace(0, 2 * math.pi, segments, endpoint=False)
    ring = np.stack([radius * np.cos(a), radius * np.sin(a)], axis=1)
    top, bottom = length / 2, -length / 2
    tris = []
    for i in range(segments):
        (x0, y0), (x1, y1) = ring[i], ring[(i + 1) % segments]
        tris += [[(0, 0, top), (x0, y0, top), (x1, y1, top)],
                 [(0, 0, bottom), (x1, y1, bottom), (x0, y0, bottom)],
                 [(x0, y0, bottom), (x1, y1, bottom), (x1, y1, top)],
                 [(x0, y0, bottom), (x1, y1, top), (x0, y0, top)]]
    return np.array(tris, dtype=float)


def box(sx: float, sy: float, sz: float) -> np.ndarray:
    """Triangles of an axis-aligned box of full sizes (sx, sy, sz) centred at the origin."""
    c = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float)
    c *= np.array([sx, sy, sz]) / 2
    faces = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    return np.array([[c[a], c[b], c[d]] for a, b, _, d in faces]
                    + [[c[b], c[cc], c[d]] for _, b, cc, d in faces])


def write_stl(path: Path, tris: np.ndarray) -> None:
    """A binary STL of the triangles."""
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("wb") as f:
        f.write(b"cosim test mesh".ljust(80, b" "))
        f.write(struct.pack("<I", len(tris)))
        for t in tris:
            n = np.cross(t[1] - t[0], t[2] - t[0])
            n = n / (np.linalg.norm(n) or 1)
            f.write(struct.pack("<12fH", *n, *t.reshape(-1), 0))


def write_obj(path: Path, tris: np.ndarray) -> None:
    """A Wavefront OBJ of the triangles (one vertex per corner)."""
    lines = [f"v {x:.6f} {y:.6f} {z:.6f}" for x, y, z in tris.reshape(-1, 3)]
    lines += [f"f {3 * i + 1} {3 * i + 2} {3 * i + 3}" for i in range(len(tris))]
    path.write_text("# cosim test mesh\n" + "\n".join(lines) + "\n")


def main() -> None:
    """Write every mesh of mybot_description and myarm_description."""
    bot = ROBOTS / "mybot_description" / "meshes"
    write_stl(bot / "chassis.stl", cylinder(0.18, 0.10, 32))
    write_stl(bot / "wheel.stl", cylinder(0.06, 0.04))
    write_stl(bot / "lds.stl", cylinder(0.04, 0.03))
    arm = ROBOTS / "myarm_description" / "meshes"
    write_stl(arm / "base.stl", cylinder(0.08, 0.10))
    write_stl(arm / "link.stl", cylinder(1.0, 1.0, 16))  # scaled per link in the xacro
    write_obj(arm / "wrist.obj", box(0.06, 0.06, 0.08))


if __name__ == "__main__":
    main()
