#!/usr/bin/env python3
"""Writes grid3x3.3ds, the 3DS twin of grid3x3.obj (tests/test_io_mesh.cpp reads both).

A 3 x 3 grid of vertices 0.5 m apart in the z = 0 plane, 2 x 2 quads split into
8 triangles, with the same vertex order, corners and winding as grid3x3.obj. The 3DS
file is written chunk by chunk (little-endian; every chunk is u16 id, u32 length
including its 6-byte header, payload): MAIN 0x4D4D { VERSION 0x0002, EDIT 0x3D3D {
MESH_VERSION 0x3D3E, OBJECT 0x4000 { name, TRIMESH 0x4100 { VERTEX_LIST 0x4110,
FACE_LIST 0x4120 } } } }. No material, no mesh matrix, no keyframer: assimp's 3DS
reader then gives the vertices as written.

Run from anywhere: python3 tests/data/make_mesh_3ds.py (writes next to this script).
"""
import os
import struct

SPACING = 0.5
VERTICES = [(SPACING * c, SPACING * r, 0.0) for r in range(3) for c in range(3)]
TRIANGLES = []
for r in range(2):
    for c in range(2):
        a, b, d, e = 3 * r + c, 3 * r + c + 1, 3 * (r + 1) + c, 3 * (r + 1) + c + 1
        TRIANGLES += [(a, b, e), (a, e, d)]


def chunk(chunk_id, payload):
    return struct.pack("<HI", chunk_id, 6 + len(payload)) + payload


def main():
    vertex_list = struct.pack("<H", len(VERTICES)) + b"".join(struct.pack("<3f", *v) for v in VERTICES)
    face_list = struct.pack("<H", len(TRIANGLES)) + b"".join(struct.pack("<4H", *t, 0x7) for t in TRIANGLES)
    trimesh = chunk(0x4100, chunk(0x4110, vertex_list) + chunk(0x4120, face_list))
    obj = chunk(0x4000, b"grid\0" + trimesh)
    edit = chunk(0x3D3D, chunk(0x3D3E, struct.pack("<I", 3)) + obj)
    data = chunk(0x4D4D, chunk(0x0002, struct.pack("<I", 3)) + edit)
    path = os.path.join(os.path.dirname(os.path.abspath(__file__)), "grid3x3.3ds")
    with open(path, "wb") as out:
        out.write(data)


if __name__ == "__main__":
    main()
