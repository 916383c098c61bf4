"""Forces from Python: bit for bit those of the Rust run, minus the gradient of the
energy, and the tangent's products and sparse matrix."""

import numpy as np
import pytest

import heml
from conftest import LAW_PARAMS


def deformed(mesh, seed=0, amplitude=0.05):
    """A smooth stretch plus a random perturbation (no tet inverted)."""
    rng = np.random.default_rng(seed)
    x = mesh.nodes @ np.array([[1.1, 0.05, 0.0], [0.0, 0.95, 0.02], [0.0, 0.0, 1.03]])
    size = np.ptp(mesh.nodes, axis=0).max()
    return x + amplitude * size / 10 * rng.standard_normal(x.shape)


def test_forces_equal_the_rust_run_bit_for_bit(stretch_run):
    """The last frame of the Rust run holds the positions and the forces the Rust
    system computed there (total forces on free nodes, reactions = minus the forces
    on supported ones; no gravity, damping or loads): the elastic forces are
    force - reaction exactly (one of the two is zero on each node). Python's
    forces at those positions, on the mesh read back from frame 0, must have the
    same bits."""
    meshio = pytest.importorskip("meshio")
    out = stretch_run
    mesh = heml.read_mesh(out / "frame_00000.vtu")
    last = meshio.read(out / f"frame_{1:05d}.vtu")
    x = np.ascontiguousarray(last.points, dtype=np.float64)
    assert not np.array_equal(x, mesh.nodes)  # it did deform
    rust = last.point_data["force"] - last.point_data["reaction"]
    field = heml.material("neo_hookean", E=5e3, nu=0.45).force_field(mesh)
    energy, forces = field.forces(x)
    assert energy > 0
    assert np.array_equal(forces, rust), np.abs(forces - rust).max()


@pytest.mark.parametrize("name", sorted(LAW_PARAMS))
def test_forces_are_minus_the_energy_gradient(name):
    """Central differences of the energy along every coordinate of a deformed
    5-tet cube. With h = 1e-6 (the cube has unit size) the truncation error is
    O(h² |W'''|) ~ 1e-12 relative and the round-off ~ eps |W| / h ~ 1e-10
    relative; 1e-6 of the largest force leaves a wide margin and still catches
    any wrong term (which would be O(1) relative)."""
    mesh = heml.box_mesh([1.0, 1.0, 1.0], [1, 1, 1], split="five")
    field = heml.material(name, **LAW_PARAMS[name]).force_field(mesh)
    x = deformed(mesh)
    _, forces = field.forces(x)
    h = 1e-6
    grad = np.zeros_like(x)
    for i in range(mesh.n_nodes):
        for c in range(3):
            xp, xm = x.copy(), x.copy()
            xp[i, c] += h
            xm[i, c] -= h
            grad[i, c] = (field.energy(xp) - field.energy(xm)) / (2 * h)
    scale = np.abs(forces).max()
    assert scale > 0
    assert np.abs(forces + grad).max() <= 1e-6 * scale


def test_energy_and_forces_agree_with_system_forces():
    """A System without loads, supports or damping computes the same forces through
    its own entry point (System.compute_forces), bit for bit."""
    mesh = heml.box_mesh([0.03, 0.02, 0.01], [3, 2, 1])
    law = heml.material("mooney_rivlin", E=3e3, nu=0.45, c01=200.0)
    x = deformed(mesh, seed=3)
    _, forces = law.force_field(mesh).forces(x)
    sys = heml.System(mesh, law)
    sys.positions = x
    sys.compute_forces()
    assert np.array_equal(sys.forces, forces)


def test_strided_and_list_inputs_give_the_same_forces():
    """A Fortran-ordered array (copied) and a nested list (converted) give the same
    bits as the C-contiguous array (read in place)."""
    mesh = heml.box_mesh([1.0, 1.0, 1.0], [2, 1, 1])
    field = heml.material("neo_hookean", E=3e3, nu=0.45).force_field(mesh)
    x = deformed(mesh)
    e, f = field.forces(x)
    for other in (np.asfortranarray(x), x.tolist(), np.hstack([x, x])[:, :3]):
        e2, f2 = field.forces(other)
        assert e2 == e and np.array_equal(f2, f)


@pytest.mark.parametrize("name", ["neo_hookean", "mooney_rivlin", "mass_spring"])
def test_hessian_product_is_the_derivative_of_the_forces(name):
    """K·dx equals −(f(x + h dx) − f(x − h dx)) / 2h. Central differences of the
    forces: truncation O(h²) with h = 1e-5 on a unit mesh (~1e-10 relative),
    round-off ~ eps |f| / h ~ 1e-11; tolerance 1e-6 of |K dx|."""
    mesh = heml.box_mesh([1.0, 1.0, 1.0], [2, 1, 1])
    field = heml.material(name, **LAW_PARAMS[name]).force_field(mesh)
    x = deformed(mesh, seed=1)
    dx = np.random.default_rng(2).standard_normal(x.shape)
    kdx = field.hessian_product(x, dx)
    h = 1e-5
    fd = -(field.forces(x + h * dx)[1] - field.forces(x - h * dx)[1]) / (2 * h)
    assert np.abs(kdx - fd).max() <= 1e-6 * np.abs(kdx).max()


def test_stiffness_matrix_matches_the_operator():
    """The scipy.sparse stiffness is symmetric and its products are the operator's
    (same 12×12 blocks, summed per node pair: round-off of the sums only)."""
    sparse = pytest.importorskip("scipy.sparse")
    mesh = heml.box_mesh([1.0, 1.0, 1.0], [2, 2, 1])
    field = heml.material("neo_hookean", E=3e3, nu=0.45).force_field(mesh)
    x = deformed(mesh, seed=4)
    k = field.stiffness(x)
    assert sparse.issparse(k) and k.shape == (3 * mesh.n_nodes, 3 * mesh.n_nodes)
    assert abs(k - k.T).max() <= 1e-12 * abs(k).max()
    tangent = field.tangent(x)
    dx = np.random.default_rng(5).standard_normal(x.shape)
    assert np.allclose(k @ dx.ravel(), (tangent @ dx).ravel(), rtol=0, atol=1e-12 * abs(k).max() * 10)
    blocks = tangent.tet_matrices()
    assert blocks.shape == (mesh.n_tets, 12, 12)
    # the rigid translations are in the null space of every tet's matrix
    t = np.tile(np.eye(3), (4, 1))
    assert np.abs(blocks @ t).max() <= 1e-10 * np.abs(blocks).max()


def test_projected_tangent_is_positive_semidefinite():
    """project_psd=True gives tet matrices with no negative eigenvalue beyond
    round-off (1e-10 of the largest), even for a compressed, partly inverted state."""
    mesh = heml.box_mesh([1.0, 1.0, 1.0], [1, 1, 1], split="five")
    field = heml.material("neo_hookean", E=3e3, nu=0.45).force_field(mesh)
    x = mesh.nodes * [1.0, 1.0, 0.2]
    x[0, 2] += 0.5
    blocks = field.tangent(x, project_psd=True).tet_matrices()
    eig = np.linalg.eigvalsh(blocks)
    assert eig.min() >= -1e-10 * np.abs(eig).max()

