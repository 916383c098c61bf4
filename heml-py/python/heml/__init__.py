"""HEML — Hyper-Elastic Mass Links, from Python.

Exact hyperelastic forces on linear tetrahedral meshes (P1 finite elements
evaluated as forces along the mesh links), simulation systems and scene files.
NumPy arrays go in and out; no per-node Python objects are created.

>>> import numpy as np, heml
>>> mesh = heml.box_mesh([0.1, 0.02, 0.02], [10, 2, 2])
>>> law = heml.material("neo_hookean", E=3e3, nu=0.45)
>>> energy, forces = law.force_field(mesh).forces(mesh.nodes * [1.1, 1.0, 1.0])
>>> bool(energy > 0 and forces.shape == (mesh.n_nodes, 3))
True

Where data is copied: (n, 3) float64 inputs (positions, displacements) that are
C-contiguous are read in place; other layouts are copied once; ndarrays of another
dtype raise TypeError, wrong shapes ValueError. Index inputs (tets, node ids) are
converted (copied) once. Outputs are fresh arrays; ``ForceField.forces`` and
``Tangent.dot`` have the library write straight into the array they return.
Library errors raise :class:`HemlError` with the library's message.
"""

from ._heml import (
    ForceField,
    HemlError,
    Material,
    Mesh,
    Ramp,
    Scene,
    System,
    Tangent,
    __version__,
    box_mesh,
    integrators,
    material,
    material_from_energy,
    materials,
    read_mesh,
    write_mesh,
)

__all__ = [
    "ForceField",
    "HemlError",
    "Material",
    "Mesh",
    "Ramp",
    "Scene",
    "System",
    "Tangent",
    "__version__",
    "box_mesh",
    "integrators",
    "material",
    "material_from_energy",
    "materials",
    "read_mesh",
    "write_mesh",
]
