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
C-contiguous and aligned are read in place; other layouts are copied once; ndarrays
of another dtype raise TypeError, wrong shapes ValueError, NaN or infinite
coordinates HemlError naming the node. Index inputs (tets, node ids) are
converted (copied) once. Outputs are fresh arrays; ``ForceField.forces`` and
``Tangent.dot`` have the library write straight into the array they return.
Library errors raise :class:`HemlError` with the library's message.

The dicts some functions return are described by the TypedDicts :class:`MaterialInfo`
(``materials()``), :class:`StepStats` (``System.step``), :class:`Energies`
(``System.energies``) and :class:`StaticReport` (``System.solve_static``), importable
for annotations (``from heml import StepStats``).
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
from ._types import Energies, MaterialInfo, StaticReport, StepStats

__all__ = [
    "Energies",
    "ForceField",
    "HemlError",
    "Material",
    "MaterialInfo",
    "Mesh",
    "Ramp",
    "Scene",
    "StaticReport",
    "StepStats",
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
