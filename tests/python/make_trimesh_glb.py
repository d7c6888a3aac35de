"""Writes a GLB with Python `trimesh` (a tool other than tensorscout), for tests/formats.rs.

Usage: make_trimesh_glb.py OUT.glb
The scene is the 8 x 5 m two-room box, 2.5 m high, in glTF's y-up frame: x along the 8 m, y up,
z along the 5 m. Walls are trimesh boxes placed by node transforms (trimesh writes one node per
geometry with its transform); the divider has a 1 m door.
"""

import sys

import numpy as np
import trimesh


def box(scene, name, lo, hi):
    lo, hi = np.array(lo, float), np.array(hi, float)
    mesh = trimesh.creation.box(extents=hi - lo)
    transform = trimesh.transformations.translation_matrix((lo + hi) / 2)
    scene.add_geometry(mesh, node_name=name, geom_name=name, transform=transform)


def main() -> None:
    s = trimesh.Scene()
    h = 2.5
    # (x, y-up, z): z spans -5..0 so that z-up y = -z spans 0..5.
    box(s, "south", (0, 0, -0.1), (8, h, 0))
    box(s, "north", (0, 0, -5), (8, h, -4.9))
    box(s, "west", (0, 0, -5), (0.1, h, 0))
    box(s, "east", (7.9, 0, -5), (8, h, 0))
    box(s, "divider_a", (3.95, 0, -2.0), (4.05, h, -0.1))
    box(s, "divider_b", (3.95, 0, -4.9), (4.05, h, -3.0))
    s.export(sys.argv[1])


if __name__ == "__main__":
    main()
