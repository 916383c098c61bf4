#!/usr/bin/env python3
"""Regenerates tiny_surgsim.ply (ASCII) and tiny_surgsim_be.ply (binary big-endian)
for tests/integration/mesh_io.rs: the 5-node, 2-tet "tiny" mesh (tags [1, 2]) in
OpenSurgSim's deformable PLY layout (vertex with texture coordinates, face,
3d_element, boundary_condition, material), with mixed property types."""
import struct

NODES = [(0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, 1), (1, 1, 1)]
TEXTURE = [(0, 0), (1, 0), (0, 1), (0, 0), (1, 1)]
FACES = [(0, 1, 2), (0, 1, 3)]
TETS = [((0, 1, 2, 3), 1), ((1, 2, 3, 4), 2)]
BOUNDARY = [2, 0, 1, 1]  # node 1 twice: the reader keeps a set
MATERIAL = (1000.0, 0.45, 75000.0)  # mass_density, poisson_ratio, young_modulus


def header(fmt):
    return f"""ply
format {fmt} 1.0
comment The tiny mesh (two tets sharing a face) in OpenSurgSim's deformable layout:
comment texture coordinates on the vertices, a surface face list, a 3d_element
comment list (with a tag property, which OpenSurgSim ignores), boundary conditions
comment and one material, as its Fem3DPlyReaderDelegate reads them.
element vertex 5
property double x
property double y
property double z
property float s
property float t
element face 2
property list uchar uint vertex_indices
element 3d_element 2
property list uchar uint vertex_indices
property int tag
element boundary_condition 4
property uint vertex_index
element material 1
property double mass_density
property double poisson_ratio
property double young_modulus
end_header
"""


text = header("ascii")
for p, t in zip(NODES, TEXTURE):
    text += "%g %g %g %g %g\n" % (p + t)
for f in FACES:
    text += "3 %d %d %d\n" % f
for t, tag in TETS:
    text += "4 %d %d %d %d %d\n" % (t + (tag,))
for b in BOUNDARY:
    text += "%d\n" % b
text += "%g %g %g\n" % MATERIAL
open("tiny_surgsim.ply", "w").write(text)

data = header("binary_big_endian").encode()
for p, t in zip(NODES, TEXTURE):
    data += struct.pack(">dddff", *p, *t)
for f in FACES:
    data += struct.pack(">BIII", 3, *f)
for t, tag in TETS:
    data += struct.pack(">BIIIIi", 4, *t, tag)
for b in BOUNDARY:
    data += struct.pack(">I", b)
data += struct.pack(">ddd", *MATERIAL)
open("tiny_surgsim_be.ply", "wb").write(data)
