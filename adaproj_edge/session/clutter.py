"""Cluttered rooms for the session simulator: objects in front of walls.

A user's first real room is a wall with a chair in front of it. These scenes put what
real depth sensors see in front of the device: silhouettes (depth jumps), the bands
beside them one stereo camera cannot see, and surfaces of several depths at once.
Metres, in the frame of a level device at the origin (x right, y down, z forward).

- ``wall-boxes``: a wall 2.4 m ahead standing on a floor, two boxes in front of it;
- ``wall-chair``: the same wall with a chair (seat, back, four legs) 0.9 m before it;
- ``wall-shelf``: a shelf (two sides, three boards, a back) against the wall;
- ``desk-partition``: a desk top 0.35 m below the device reaching to a partition
  1.3 m ahead, a wall behind and the floor under it all.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from adaproj_edge.arrays import FloatArray
from adaproj_edge.geometry.mesh_surface import MeshSurface

FLOOR_Y = 0.75  # the floor, this far below the device

_BOX_FACES = np.array(
    [
        [0, 1, 2], [0, 2, 3], [4, 6, 5], [4, 7, 6],  # front (z0), back (z1)
        [0, 4, 5], [0, 5, 1], [3, 2, 6], [3, 6, 7],  # top (y0), bottom (y1)
        [0, 3, 7], [0, 7, 4], [1, 5, 6], [1, 6, 2],  # left (x0), right (x1)
    ]
)  # fmt: skip


def box(
    x0: float, x1: float, y0: float, y1: float, z0: float, z1: float
) -> tuple[FloatArray, FloatArray]:
    """Vertices (8, 3) and faces (12, 3) of an axis-aligned box."""
    v = np.array(
        [
            [x0, y0, z0], [x1, y0, z0], [x1, y1, z0], [x0, y1, z0],
            [x0, y0, z1], [x1, y0, z1], [x1, y1, z1], [x0, y1, z1],
        ]
    )  # fmt: skip
    return v, _BOX_FACES.astype(np.float64)


def _quad(
    x0: float, x1: float, y0: float, y1: float, z0: float, z1: float
) -> tuple[FloatArray, FloatArray]:
    """A rectangle: a wall (z0 = z1) or a floor/top (y0 = y1), as two triangles."""
    if y0 == y1:
        v = np.array([[x0, y0, z0], [x1, y0, z0], [x1, y0, z1], [x0, y0, z1]])
    else:
        v = np.array([[x0, y0, z0], [x1, y0, z0], [x1, y1, z0], [x0, y1, z0]])
    return v, np.array([[0.0, 1, 2], [0, 2, 3]])


def _mesh(name: str, parts: list[tuple[FloatArray, FloatArray]]) -> MeshSurface:
    vs, fs, n = [], [], 0
    for v, f in parts:
        vs.append(v)
        fs.append(f.astype(np.int64) + n)
        n += len(v)
    return MeshSurface(name, np.concatenate(vs), np.concatenate(fs))


def _room(wall_z: float) -> list[tuple[FloatArray, FloatArray]]:
    """A wall ``wall_z`` ahead standing on the floor."""
    return [
        _quad(-3.0, 3.0, -2.0, FLOOR_Y, wall_z, wall_z),
        _quad(-3.0, 3.0, FLOOR_Y, FLOOR_Y, 0.2, wall_z),
    ]


def wall_boxes() -> MeshSurface:
    """Two boxes in front of a wall 2.4 m ahead."""
    return _mesh(
        "wall-boxes",
        [
            *_room(2.4),
            box(-0.65, -0.15, -0.05, FLOOR_Y, 1.5, 1.9),
            box(0.25, 0.6, -0.3, FLOOR_Y, 1.8, 2.1),
        ],
    )


def wall_chair() -> MeshSurface:
    """A chair 0.9 m before a wall 2.4 m ahead, its back to the device."""
    legs = [box(x, x + 0.04, 0.3, FLOOR_Y, z, z + 0.04) for x in (-0.25, 0.17) for z in (1.4, 1.8)]
    return _mesh(
        "wall-chair",
        [
            *_room(2.4),
            box(-0.25, 0.21, 0.27, 0.3, 1.4, 1.84),  # seat
            box(-0.25, 0.21, -0.2, 0.27, 1.4, 1.44),  # back
            *legs,
        ],
    )


def wall_shelf() -> MeshSurface:
    """A shelf against a wall 2.4 m ahead: sides, three boards and a back."""
    x0, x1, z0, z1 = -0.4, 0.4, 2.05, 2.38
    parts = [
        *_room(2.4),
        box(x0, x0 + 0.02, -0.9, FLOOR_Y, z0, z1),
        box(x1 - 0.02, x1, -0.9, FLOOR_Y, z0, z1),
        _quad(x0, x1, -0.9, FLOOR_Y, z1, z1),
    ]
    parts += [box(x0, x1, y, y + 0.025, z0, z1) for y in (-0.9, -0.35, 0.2)]
    return _mesh("wall-shelf", parts)


def desk_partition() -> MeshSurface:
    """A desk top 0.35 m below the device up to a partition 1.3 m ahead; a wall behind."""
    return _mesh(
        "desk-partition",
        [
            *_room(2.6),
            box(-0.8, 0.8, 0.35, 0.38, 0.35, 1.3),  # the desk top
            _quad(-0.8, 0.8, -0.45, 0.35, 1.3, 1.3),  # the partition
        ],
    )


CLUTTER: dict[str, Callable[[], MeshSurface]] = {
    "wall-boxes": wall_boxes,
    "wall-chair": wall_chair,
    "wall-shelf": wall_shelf,
    "desk-partition": desk_partition,
}
"""The cluttered scenes by name (each a function building its mesh)."""
