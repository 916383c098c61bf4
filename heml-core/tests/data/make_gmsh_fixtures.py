#!/usr/bin/env python3
"""Regenerates the gmsh_groups_* fixtures of tests/integration/mesh_io.rs with Gmsh
itself (pip install gmsh; written with 4.15.2): a unit cube of a few dozen tets with
physical groups of every dimension, saved as 4.1 and 2.2, ASCII and binary.

Groups: volume "body" (1); surface "clamp" (the face z = 0, tag 2); an unnamed
surface, tag 7 (the face z = 1); curve "edge" (the edge x = 0, y = 0, tag 3);
an unnamed point, tag 9 (the corner (1, 1, 1))."""
import gmsh

gmsh.initialize()
gmsh.option.setNumber("General.Terminal", 0)
gmsh.model.add("groups")
gmsh.model.occ.addBox(0, 0, 0, 1, 1, 1)
gmsh.model.occ.synchronize()


def at(dim, test):
    out = []
    for d, t in gmsh.model.getEntities(dim):
        x0, y0, z0, x1, y1, z1 = gmsh.model.getBoundingBox(d, t)
        if test(x0, y0, z0, x1, y1, z1):
            out.append(t)
    assert len(out) == 1, (dim, out)
    return out


eps = 1e-6  # OCC bounding boxes carry a tolerance of ~1e-7
gmsh.model.addPhysicalGroup(3, [1], 1, "body")
gmsh.model.addPhysicalGroup(2, at(2, lambda x0, y0, z0, x1, y1, z1: z1 < eps), 2, "clamp")
gmsh.model.addPhysicalGroup(2, at(2, lambda x0, y0, z0, x1, y1, z1: z0 > 1 - eps), 7)
gmsh.model.addPhysicalGroup(
    1, at(1, lambda x0, y0, z0, x1, y1, z1: x1 < eps and y1 < eps), 3, "edge"
)
gmsh.model.addPhysicalGroup(0, at(0, lambda x0, y0, z0, x1, y1, z1: x0 > 1 - eps and y0 > 1 - eps and z0 > 1 - eps), 9)
gmsh.option.setNumber("Mesh.MeshSizeMin", 0.6)
gmsh.option.setNumber("Mesh.MeshSizeMax", 0.6)
gmsh.model.mesh.generate(3)
for version, binary, name in [
    (4.1, 0, "gmsh_groups_v41.msh"),
    (4.1, 1, "gmsh_groups_b41.msh"),
    (2.2, 0, "gmsh_groups_v22.msh"),
    (2.2, 1, "gmsh_groups_b22.msh"),
]:
    gmsh.option.setNumber("Mesh.MshFileVersion", version)
    gmsh.option.setNumber("Mesh.Binary", binary)
    gmsh.write(name)
gmsh.finalize()
