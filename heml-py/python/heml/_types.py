"""The dicts some functions of `heml` return, as TypedDicts (shared by the package
and its stubs, so that the two cannot disagree)."""

from typing import Literal, TypedDict


class MaterialInfo(TypedDict):
    """One law of ``heml.materials()``."""

    name: str
    parameters: list[str]
    parameter_docs: list[str]
    energy: str
    kind: Literal["invariant", "link", "stretch", "fibre"]
    young_poisson: bool
    doc: str


class Energies(TypedDict):
    """Energies (J) of ``System.energies()`` and of ``StepStats["energies"]``."""

    kinetic: float
    elastic: float
    gravity: float
    loads: float
    total: float


class StepStats(TypedDict):
    """Statistics of the last step of ``System.step``."""

    step: int
    time: float
    dt: float
    max_speed: float
    reaction: list[float]
    energies: Energies | None
    newton_iterations: int
    cg_iterations: int
    factorizations: int


class StaticReport(TypedDict):
    """What ``System.solve_static`` reached."""

    converged: bool
    iterations: int
    residual: float
    load_scale: float
    tol: float
    roundoff: float
    criterion: str
