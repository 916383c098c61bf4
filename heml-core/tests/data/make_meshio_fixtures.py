#!/usr/bin/env python3
"""Regenerates the meshio-written fixtures of tests/integration/mesh_io.rs: the 5-node,
2-tet "tiny" mesh (tags [1, 2], plus one triangle that readers must skip) as
meshio (5.3.5) writes it by default: binary Gmsh 2.2 (`gmsh22`), binary Gmsh 4.1
(`gmsh`), and VTU with lzma compression. Run from this directory with a Python
that has meshio (`python3 -m venv /tmp/mv && /tmp/mv/bin/pip install meshio`)."""
import meshio
import numpy as np

P = np.array([(0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, 1), (1, 1, 1)], dtype=float)
cells = [("tetra", np.array([(0, 1, 2, 3), (1, 2, 3, 4)])), ("triangle", np.array([(0, 1, 2)]))]
tags = [np.array([1, 2], dtype=np.int32), np.array([0], dtype=np.int32)]
gmsh = meshio.Mesh(P, cells, cell_data={"gmsh:physical": tags, "gmsh:geometrical": tags})
meshio.write("tiny_meshio_b22.msh", gmsh, file_format="gmsh22", binary=True)
# meshio's 4.1 writer needs each node's entity to write two cell types, and then
# writes entities its own reader refuses: the 4.1 fixture holds the tets only
tets = meshio.Mesh(P, cells[:1], cell_data={"gmsh:physical": tags[:1], "gmsh:geometrical": tags[:1]})
meshio.write("tiny_meshio_b41.msh", tets, file_format="gmsh", binary=True)
vtu = meshio.Mesh(P, cells, cell_data={"tag": tags})
meshio.write("tiny_meshio_lzma.vtu", vtu, compression="lzma")

# A generated box of 3 x 2 x 2 hexahedra (VTK corner order), graded spacing and
# shuffled node ids (no split may lean on a structured numbering), tags 1..12:
# as VTU (hexahedron cells) and as binary Gmsh 4.1 (type 5).
xs, ys, zs = [0.0, 0.5, 1.25, 3.0], [0.0, 0.75, 2.0], [0.0, 1.0, 1.5]
ids = np.arange(4 * 3 * 3)
np.random.default_rng(7).shuffle(ids)
pts = np.zeros((len(ids), 3))
idx = lambda i, j, k: ids[i + 4 * (j + 3 * k)]
for k in range(3):
    for j in range(3):
        for i in range(4):
            pts[idx(i, j, k)] = (xs[i], ys[j], zs[k])
hexes = []
for k in range(2):
    for j in range(2):
        for i in range(3):
            hexes.append([idx(i, j, k), idx(i + 1, j, k), idx(i + 1, j + 1, k), idx(i, j + 1, k),
                          idx(i, j, k + 1), idx(i + 1, j, k + 1), idx(i + 1, j + 1, k + 1), idx(i, j + 1, k + 1)])
hex_tags = np.arange(1, 13, dtype=np.int32)
box = meshio.Mesh(pts, [("hexahedron", np.array(hexes))], cell_data={"tag": [hex_tags]})
meshio.write("hex_box_meshio.vtu", box)
box = meshio.Mesh(pts, [("hexahedron", np.array(hexes))],
                  cell_data={"gmsh:physical": [hex_tags], "gmsh:geometrical": [hex_tags]})
meshio.write("hex_box_meshio_b22.msh", box, file_format="gmsh22", binary=True)
meshio.write("hex_box_meshio_b41.msh", box, file_format="gmsh", binary=True)
meshio.write("hex_box_meshio_v22.msh", box, file_format="gmsh22", binary=False)
