#!/usr/bin/env python3
"""Writes spikes.obj beside this script: the bed of nails of the spikes scene.

Nine thin, closed square pyramids ("spikes") standing on y = -0.3, their apexes at y = 0, in
metres: each 0.3 m tall on a 2 cm base, 5 vertices and 6 triangles, wound counter-clockwise
seen from outside. The apexes sit at the centroids of cloth triangles of the scene's 24^2
cloth (3 cm cells, particle columns at x, z = -0.345 + 0.03 i), a third of a cell along x
and two thirds along z into the cells i = 5, 11, 17: 7 mm from the nearest cloth edge and
farther from every particle, so that only the corner pass (an apex against a cloth face)
can hold the cloth up. Deterministic: running it again gives the same file byte for byte.

    python3 tools/scenes/meshes/make_spikes_obj.py
"""
import os

CELL = 0.03
ORIGIN = -0.345
CELLS = (5, 11, 17)
HEIGHT = 0.3
HALF_BASE = 0.01


def main():
    vertices = []
    triangles = []
    for i in CELLS:
        for k in CELLS:
            x = ORIGIN + CELL * (i + 1.0 / 3.0)
            z = ORIGIN + CELL * (k + 2.0 / 3.0)
            first = len(vertices) + 1  # OBJ indices start at 1
            vertices.append((x, 0.0, z))
            for dx, dz in ((-1, -1), (1, -1), (1, 1), (-1, 1)):
                vertices.append((x + dx * HALF_BASE, -HEIGHT, z + dz * HALF_BASE))
            apex, b0, b1, b2, b3 = range(first, first + 5)
            triangles += [(apex, b1, b0), (apex, b2, b1), (apex, b3, b2), (apex, b0, b3), (b0, b1, b2), (b0, b2, b3)]
    path = os.path.join(os.path.dirname(os.path.abspath(__file__)), "spikes.obj")
    with open(path, "w", newline="\n") as out:
        out.write("# spikes.obj: written by make_spikes_obj.py (nine spikes, metres)\n")
        for v in vertices:
            out.write("v %.6f %.6f %.6f\n" % v)
        for t in triangles:
            out.write("f %d %d %d\n" % t)


if __name__ == "__main__":
    main()
