"""Type stubs of the `heml` package (the extension module `heml._heml`)."""

from os import PathLike
from typing import Any, Callable, Literal, Sequence, final

import numpy as np
import numpy.typing as npt

from ._types import Energies as Energies
from ._types import MaterialInfo as MaterialInfo
from ._types import StaticReport as StaticReport
from ._types import StepStats as StepStats

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

__version__: str

_F64 = npt.NDArray[np.float64]
_ArrayLike = npt.ArrayLike
_Path = str | PathLike[str]
_Selection = _ArrayLike  # node or tet ids, or a boolean mask

class HemlError(Exception):
    """An error reported by the library (bad mesh, unknown law, malformed file, NaN step…)."""

def materials() -> list[MaterialInfo]:
    """Every registered law, sorted by name."""

def integrators() -> list[tuple[str, str]]:
    """Every registered integrator as (name, doc), sorted by name."""

def material(name: str, **params: float) -> Material:
    """The law `name` with keyword parameters (E/nu accepted where the law maps them)."""

def material_from_energy(
    energy: str, *, volumetric_energy: str | None = None, inversion_fix: bool = True, **params: float
) -> Material:
    """A law declared at run time by its strain energy over the keyword parameters;
    a mistake in the text raises HemlError with the column. `volumetric_energy`
    declares its volumetric energy U(J) for the anti-locking formulations."""

def read_mesh(path: _Path) -> Mesh:
    """Reads a .msh/.vtk/.vtu/.node/.ele/.mesh/.ply file and validates it."""

def write_mesh(path: _Path, mesh: Mesh) -> None:
    """Writes `mesh` in the format of the extension, atomically."""

def box_mesh(
    size: Sequence[float], cells: Sequence[int], split: Literal["five", "six", "ten", "twentyfour"] = "six"
) -> Mesh:
    """A box of `size` (m) cut into `cells` (>= 0) hexahedra, each split into tets."""

@final
class Material:
    """A law with its parameter values."""

    @property
    def name(self) -> str:
        """Registry name ("energy" for a law from material_from_energy)."""
    @property
    def energy(self) -> str | None:
        """The energy text of a law from material_from_energy, else None."""
    @property
    def kind(self) -> Literal["invariant", "link", "stretch", "fibre"]:
        """Invariant, link, stretch or fibre law."""
    @property
    def params(self) -> dict[str, float]:
        """Resolved parameter values by name."""
    @property
    def volumetric(self) -> str:
        """How the volumetric energy is discretised: "element", "nodal (...)" or "patch (...)"."""
    def with_volumetric(
        self, formulation: Literal["element", "nodal", "patch"], stabilization: float | None = None
    ) -> Material:
        """This law with the anti-locking "nodal" or "patch" volumetric term (or "element")."""
    def force_field(
        self, mesh: Mesh, tets: _Selection | None = None, *, j0: float = 0.4, inversion_fix: bool = True
    ) -> ForceField:
        """The HEML force field of this law over `mesh` (or over the tets `tets`: ids, each once, or a mask)."""

@final
class Mesh:
    """A validated, immutable linear tetrahedral mesh."""

    def __new__(cls, nodes: _ArrayLike, tets: _ArrayLike, tags: _ArrayLike | None = None) -> Mesh:
        """nodes (n, 3) float64, tets (m, 4) integers, tags (m,) int32 values, optional."""
    @property
    def nodes(self) -> _F64:
        """Rest positions (n, 3), a copy."""
    @property
    def tets(self) -> npt.NDArray[np.int64]:
        """Tets (m, 4), positively oriented, a copy."""
    @property
    def tags(self) -> npt.NDArray[np.int32]:
        """Region tag per tet (m,), a copy."""
    @property
    def node_sets(self) -> dict[str, npt.NDArray[np.int64]]:
        """The file's named node sets (Gmsh physical groups, an OpenSurgSim .ply's "boundary_condition")."""
    @property
    def n_nodes(self) -> int:
        """Number of nodes."""
    @property
    def n_tets(self) -> int:
        """Number of tets."""
    @property
    def reoriented_count(self) -> int:
        """Tets reoriented at construction."""
    @property
    def volume(self) -> float:
        """Total rest volume (m³)."""
    def lumped_masses(self, density: float) -> _F64:
        """Lumped nodal masses (n,) for `density` (finite, > 0)."""
    def surface(self, padded: bool = False) -> tuple[_F64, npt.NDArray[np.int64]]:
        """(points, faces) of the outward boundary; padded=True gives PyVista's flat faces."""
    def to_meshio(self) -> Any:
        """A meshio.Mesh (needs meshio)."""
    @staticmethod
    def from_meshio(m: Any) -> Mesh:
        """A mesh from a meshio.Mesh's points and tetra cells."""

@final
class ForceField:
    """Energy and internal forces of one law over a mesh."""

    @property
    def n_nodes(self) -> int:
        """Number of nodes positions must have."""
    @property
    def n_tets(self) -> int:
        """Number of tets summed over."""
    def energy(self, x: _ArrayLike) -> float:
        """Total elastic energy (J) at positions x (n, 3); non-finite input or result raises HemlError."""
    def forces(self, x: _ArrayLike) -> tuple[float, _F64]:
        """(energy, internal forces (n, 3)) at positions x; non-finite input or result raises HemlError."""
    def tet_states(self, x: _ArrayLike) -> tuple[_F64, _F64]:
        """(J, w) per tet at positions x."""
    def tangent(self, x: _ArrayLike, project_psd: bool = False) -> Tangent:
        """The stiffness K = d²W/dx² at x."""
    def hessian_product(self, x: _ArrayLike, dx: _ArrayLike, project_psd: bool = False) -> _F64:
        """K(x)·dx, (n, 3)."""
    def stiffness(self, x: _ArrayLike, project_psd: bool = False, format: str = "csr") -> Any:
        """K(x) as a scipy.sparse matrix (3n, 3n) (needs scipy)."""

@final
class Tangent:
    """The stiffness of a force field at one configuration."""

    @property
    def shape(self) -> tuple[int, int]:
        """(3n, 3n)."""
    @property
    def projected(self) -> bool:
        """Whether tet matrices were projected to positive semi-definite."""
    @property
    def tet_ids(self) -> npt.NDArray[np.uintp]:
        """Global tet ids in the order of tet_matrices()."""
    __array_ufunc__: None
    def dot(self, dx: _ArrayLike) -> _F64:
        """K·dx, (n, 3)."""
    def __matmul__(self, dx: _ArrayLike, /) -> _F64:
        """K @ dx."""
    def __rmatmul__(self, dx: _ArrayLike, /) -> _F64:
        """dx @ K = K·dx (K is symmetric)."""
    def tet_matrices(self) -> _F64:
        """(m, 12, 12) tet stiffness matrices."""
    def to_scipy(self, format: str = "csr") -> Any:
        """K as a scipy.sparse matrix (needs scipy)."""

@final
class Ramp:
    """Time profile r(t) of a prescribed displacement (checked: HemlError on bad values)."""

    @staticmethod
    def step() -> Ramp:
        """r = 1 from t = 0."""
    @staticmethod
    def linear(duration: float) -> Ramp:
        """r = t / duration (duration finite, > 0), then 1."""
    @staticmethod
    def smooth(duration: float) -> Ramp:
        """Smoothstep over duration (finite, > 0)."""
    @staticmethod
    def keyframes(points: Sequence[Sequence[float]]) -> Ramp:
        """Piecewise linear through [[t, r], …] (at least one; finite; times >= 0, increasing)."""
    def value(self, t: float) -> float:
        """r(t)."""

@final
class System:
    """A simulated body (the Rust SystemBuilder's options as keywords)."""

    def __new__(
        cls,
        mesh: Mesh,
        material: Material | str,
        params: dict[str, float] | None = None,
        *,
        regions: dict[int, Material] | None = None,
        density: float = 1000.0,
        gravity: Sequence[float] | None = None,
        fixed: _ArrayLike | None = None,
        prescribed: list[tuple[_ArrayLike, Sequence[float]] | tuple[_ArrayLike, Sequence[float], Ramp]] | None = None,
        nodal_forces: list[tuple[int, Sequence[float]]] | None = None,
        rayleigh: tuple[float, float] | None = None,
        prony: list[tuple[float, float]] | None = None,
        initial_velocity: _ArrayLike | None = None,
        j0: float = 0.4,
        inversion_fix: bool = True,
        dt_policy: Literal["warn", "refuse", "ignore"] = "warn",
        safety: float | None = None,
        energy_every: int = 1,
        lazy_energy: bool = False,
        pin_unreferenced: bool = False,
    ) -> System:
        """Builds and checks the system."""
    def step(
        self,
        integrator: str = "velocity_verlet",
        dt: float | None = None,
        n: int = 1,
        *,
        linear_solver: Literal["cg", "cholesky"] | None = None,
        cholesky_ordering: Literal["auto", "amd", "node_amd", "nested_dissection"] | None = None,
        factor_precision: Literal["auto", "f64", "f32"] | None = None,
        newton_iterations: int | None = None,
        newton_tolerance: float | None = None,
        cg_tolerance: float | None = None,
        cg_max_iterations: int | None = None,
    ) -> StepStats:
        """n (>= 1) steps of dt with the named integrator, GIL released; the keywords set the
        implicit integrators' settings (kept for later calls)."""
    def solve_static(self, tol: float = 1e-6, abs_tol: float = 0.0, max_iterations: int = 500_000) -> StaticReport:
        """Static equilibrium, GIL released, Ctrl-C checked every ~0.1 s; max_iterations >= 1."""
    def compute_forces(self) -> None:
        """Evaluates forces and reactions at the current state."""
    positions: _F64
    """Current positions (n, 3) (copy; assignable: constrained nodes are put back at once)."""
    velocities: _F64
    """Current velocities (n, 3) (copy; assignable: constrained nodes get their constraint's velocity)."""
    @property
    def displacements(self) -> _F64:
        """x − X (n, 3)."""
    @property
    def rest_positions(self) -> _F64:
        """X (n, 3)."""
    @property
    def forces(self) -> _F64:
        """Total nodal forces of the last evaluation (n, 3)."""
    @property
    def reactions(self) -> _F64:
        """Support reactions (n, 3)."""
    @property
    def total_reaction(self) -> list[float]:
        """Sum of the reactions."""
    @property
    def masses(self) -> _F64:
        """Lumped masses (n,)."""
    @property
    def time(self) -> float:
        """Simulated time (s)."""
    @property
    def step_count(self) -> int:
        """Completed steps."""
    @property
    def stable_dt(self) -> float:
        """Stable explicit step at rest (s)."""
    @property
    def n_nodes(self) -> int:
        """Number of nodes."""
    @property
    def mesh(self) -> Mesh:
        """The rest mesh."""
    @property
    def warnings(self) -> list[str]:
        """Warnings collected so far."""
    def energies(self) -> Energies:
        """kinetic, elastic, gravity, loads, total (J)."""
    def surface(self, padded: bool = False) -> tuple[_F64, npt.NDArray[np.int64]]:
        """(current points, boundary faces)."""
    # runtime control between steps (errors raise HemlError, the system unchanged)
    def set_gravity(self, g: Sequence[float]) -> None:
        """Sets gravity (m/s²) from the next step on."""
    def fix_nodes(self, nodes: _Selection) -> None:
        """Holds nodes at their rest positions (moved there at once)."""
    def release_nodes(self, nodes: _Selection) -> None:
        """Frees fixed or prescribed nodes."""
    def prescribe_pose(
        self, nodes: _Selection, translation: Sequence[float], rotation: Sequence[float] | None = None
    ) -> None:
        """Moves a node group rigidly from rest to the pose and holds it."""
    def grasp(
        self,
        nodes: _Selection,
        stiffness: float,
        damping: float = 0.0,
        translation: Sequence[float] | None = None,
        rotation: Sequence[float] | None = None,
    ) -> int:
        """Ties nodes by springs to where they are; the pose is the frame of later targets. Returns the grasp id."""
    def move_grasp(self, grasp: int, translation: Sequence[float], rotation: Sequence[float] | None = None) -> None:
        """Moves a grasp's target to T: the nodes follow by T·T0⁻¹ (T0 the grasp's pose)."""
    def release_grasp(self, grasp: int) -> None:
        """Lets go of a grasp."""
    def grasp_force(self, grasp: int) -> list[float]:
        """Force (N) the tissue applies to the grasp."""
    def add_tool(
        self,
        shape: Literal["sphere", "capsule", "half_space"],
        stiffness: float,
        radius: float | None = None,
        half_length: float | None = None,
        damping: float = 0.0,
        translation: Sequence[float] | None = None,
        rotation: Sequence[float] | None = None,
    ) -> int:
        """Adds a sphere, capsule or half_space tool; returns its id."""
    def set_tool_pose(self, tool: int, translation: Sequence[float], rotation: Sequence[float] | None = None) -> None:
        """Places a tool for the next step."""
    def tool_wrench(self, tool: int) -> tuple[list[float], list[float]]:
        """(force N, torque N·m) the tissue applied to the tool."""
    def remove_tool(self, tool: int) -> None:
        """Removes a tool."""
    def cut(self, blade: npt.ArrayLike) -> dict[str, Any]:
        """Removes the tets a blade ((3, 3) triangle or (4, 3) swept edge) meets."""
    def remove_tets(self, tets: _Selection) -> dict[str, Any]:
        """Removes the given tets."""
    def set_material(
        self, material: Material | str, params: dict[str, float] | None = None, *, region: int | None = None
    ) -> None:
        """Replaces a region's law (region: its tag; None: the main material), keeping state and cuts."""
    @property
    def n_tets(self) -> int:
        """Tets left by cuts."""

@final
class Scene:
    """A scene file, run to its duration."""

    @staticmethod
    def from_file(path: _Path) -> Scene:
        """Parses a scene file."""
    @staticmethod
    def from_toml(text: str, base_dir: _Path = ".") -> Scene:
        """Parses scene text."""
    def run(
        self,
        progress: Callable[[dict[str, Any]], object] | None = None,
        every: int = 1,
        out_dir: _Path | None = None,
    ) -> dict[str, Any]:
        """Runs the scene, GIL released; progress(info) every `every` (>= 1) steps; an
        exception of the callback or a Ctrl-C stops the run and is raised."""
    @property
    def positions(self) -> _F64:
        """Positions after run(), file node order."""
    @property
    def displacements(self) -> _F64:
        """Displacements after run(), file node order."""
    @property
    def time(self) -> float:
        """Simulated time reached."""
