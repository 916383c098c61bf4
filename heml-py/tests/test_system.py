"""A System stepped from Python: the Rust run's bits, the GIL released while it
steps, static solves, and the state arrays."""

import threading

import numpy as np
import pytest

import heml
from conftest import STRETCH_DT, STRETCH_SCENE, STRETCH_STEPS


def stretch_system(mesh):
    """The System of conftest.STRETCH_SCENE, described through the Python API."""
    x = mesh.nodes[:, 0]
    return heml.System(
        mesh,
        "neo_hookean",
        {"E": 5e3, "nu": 0.45},
        density=1000.0,
        fixed=x == 0.0,
        prescribed=[(np.isclose(x, 0.04, rtol=0, atol=1e-9), [0.008, 0.002, 0.0], heml.Ramp.smooth(0.005))],
    )


def test_system_stepped_from_python_matches_the_rust_run(stretch_run):
    """`heml run` on the stretch scene and the same system stepped from Python
    (velocity Verlet, same dt, same number of steps) end at the same positions,
    bit for bit: the last frame stores positions in double precision."""
    meshio = pytest.importorskip("meshio")
    out = stretch_run
    mesh = heml.read_mesh(out / "frame_00000.vtu")
    sys = stretch_system(mesh)
    stats = sys.step("velocity_verlet", dt=STRETCH_DT, n=STRETCH_STEPS)
    assert stats["step"] == STRETCH_STEPS and sys.step_count == STRETCH_STEPS
    assert sys.time == pytest.approx(STRETCH_STEPS * STRETCH_DT, rel=1e-12)
    last = meshio.read(out / "frame_00001.vtu")
    assert np.array_equal(sys.positions, last.points)
    assert np.array_equal(sys.velocities, last.point_data["velocity"])
    assert np.array_equal(sys.reactions, last.point_data["reaction"])


def test_scene_run_from_python_matches_the_rust_run(stretch_run, tmp_path):
    """Scene.from_file(...).run() reaches the positions of the Rust run, and calls
    the progress callback after each step with increasing step numbers."""
    meshio = pytest.importorskip("meshio")
    out = stretch_run
    seen = []
    scene = heml.Scene.from_file(STRETCH_SCENE)
    summary = scene.run(progress=lambda p: seen.append((p["step"], p["steps"], p["time"])), out_dir=tmp_path)
    assert (tmp_path / "frame_00001.vtu").is_file()
    assert summary["steps"] == STRETCH_STEPS
    assert [s for s, _, _ in seen] == list(range(1, STRETCH_STEPS + 1))
    assert all(total == STRETCH_STEPS for _, total, _ in seen)
    assert seen[-1][2] == pytest.approx(scene.time, rel=0, abs=0)
    last = meshio.read(out / "frame_00001.vtu")
    assert np.array_equal(scene.positions, last.points)


def test_progress_callback_error_is_raised():
    """An exception in the progress callback reaches the caller (after the run),
    and the callback is not called again after it."""
    calls = []

    def cb(p):
        calls.append(p["step"])
        raise KeyError("stop")

    text = """
[mesh]
generate = { kind = "box", size = [0.02, 0.01, 0.01], cells = [2, 1, 1] }
[[material]]
law = "neo_hookean"
params = { E = 5e3, nu = 0.3 }
[[fix]]
plane = { point = [0, 0, 0], normal = [1, 0, 0] }
[loads]
gravity = [0, 0, -9.81]
[solver]
duration = 0.05
[output]
vtu = false
csv = false
"""
    with pytest.raises(KeyError):
        heml.Scene.from_toml(text).run(progress=cb, every=2)
    assert calls == [2]


def test_gil_is_released_while_stepping():
    """A Python thread keeps counting while `step` runs. If `step` held the GIL the
    whole time the counter could not move at all (the thread runs Python code and
    `step` runs none); it must advance by well over a few increments."""
    mesh = heml.box_mesh([0.1, 0.05, 0.05], [16, 8, 8])
    sys = heml.System(mesh, heml.material("neo_hookean", E=3e3, nu=0.45), fixed=mesh.nodes[:, 0] == 0)
    count = [0]
    stop = threading.Event()
    started = threading.Event()

    def counter():
        started.set()
        while not stop.is_set():
            count[0] += 1

    t = threading.Thread(target=counter)
    t.start()
    started.wait()
    before = count[0]
    sys.step("symplectic_euler", n=400)
    during = count[0] - before
    stop.set()
    t.join()
    assert sys.step_count == 400
    assert during > 1000, during


def test_static_solve_under_gravity_balances_the_weight():
    """After solve_static the supports carry the whole weight: the total reaction is
    −m g to the solver's tolerance (1e-6 of the load scale, the weight here)."""
    mesh = heml.box_mesh([0.1, 0.02, 0.02], [10, 2, 2])
    sys = heml.System(
        mesh, heml.material("neo_hookean", E=30e3, nu=0.45), density=1000.0, gravity=[0, 0, -9.81],
        fixed=mesh.nodes[:, 0] == 0,
    )
    report = sys.solve_static(tol=1e-8)
    assert report["converged"]
    weight = sys.masses.sum() * 9.81
    assert sys.total_reaction[2] == pytest.approx(weight, rel=1e-6)
    assert sys.displacements[:, 2].min() < 0
    assert np.array_equal(sys.positions - sys.rest_positions, sys.displacements)


def test_fixed_by_ids_equals_fixed_by_mask():
    """A boolean mask and the equivalent id list fix the same nodes: same motion."""
    mesh = heml.box_mesh([0.04, 0.02, 0.02], [4, 2, 2])
    mask = mesh.nodes[:, 0] == 0
    law = heml.material("neo_hookean", E=3e3, nu=0.45)
    a = heml.System(mesh, law, gravity=[0, 0, -9.81], fixed=mask)
    b = heml.System(mesh, law, gravity=[0, 0, -9.81], fixed=np.flatnonzero(mask).tolist())
    a.step("symplectic_euler", n=20)
    b.step("symplectic_euler", n=20)
    assert np.array_equal(a.positions, b.positions)
    assert np.all(a.displacements[mask] == 0)
    assert np.all(a.reactions[~mask] == 0)


def test_initial_velocity_is_applied_per_node():
    """initial_velocity's rows go to their nodes (checked on a free body)."""
    mesh = heml.box_mesh([0.02, 0.02, 0.02], [2, 2, 2])
    v = np.zeros((mesh.n_nodes, 3))
    v[:, 1] = mesh.nodes[:, 0]
    sys = heml.System(mesh, heml.material("neo_hookean", E=3e3, nu=0.45), initial_velocity=v)
    assert np.array_equal(sys.velocities, v)


def test_scene_state_is_refused_not_waited_for_while_it_runs():
    """Reading a scene's state from another thread while it runs raises (the run
    holds the simulation and needs the GIL for its callback: waiting would
    deadlock). The callback pauses the run at step 1 until the check is done."""
    scene = heml.Scene.from_toml("""
[mesh]
generate = { kind = "box", size = [0.02, 0.01, 0.01], cells = [2, 1, 1] }
[[material]]
law = "neo_hookean"
params = { E = 5e3, nu = 0.3 }
[loads]
gravity = [0, 0, -9.81]
[solver]
duration = 0.001
[output]
vtu = false
csv = false
""")
    started, checked = threading.Event(), threading.Event()

    def cb(p):
        if p["step"] == 1:
            started.set()
            assert checked.wait(30)

    t = threading.Thread(target=scene.run, kwargs=dict(progress=cb))
    t.start()
    assert started.wait(30)
    try:
        with pytest.raises(RuntimeError, match="running in another thread"):
            scene.time
    finally:
        checked.set()
        t.join()
    assert scene.time > 0


def sagging_block():
    """An 8 × 6 × 5 cm soft block (E = 5 kPa, ν = 0.45) clamped at x = 0, under gravity."""
    mesh = heml.box_mesh([0.08, 0.06, 0.05], [8, 6, 5])
    return heml.System(
        mesh, "neo_hookean", {"E": 5e3, "nu": 0.45}, density=1000.0, gravity=[0, 0, -9.81],
        fixed=mesh.nodes[:, 0] < 1e-9, rayleigh=(15.0, 0.0), energy_every=0,
    )


def test_cholesky_linear_solver_reaches_the_cg_steps_and_reuses_its_factor():
    """backward_euler with linear_solver="cholesky" ends on the CG run's state when
    both converge each step (Newton to 1e-9, CG to 1e-12), factoring fewer times than
    it steps; CG reports no factorisation.

    Bound: each step meets |r| ≤ 1e-9·max(|r0|, |loads|) with both solvers, so the
    states differ by ~1e-8 of the sag after 20 steps (the Rust test's argument,
    tests/tests/suite/implicit_cholesky.rs); 1e-6 leaves margin, while a wrong or stale
    matrix taken as converged leaves O(1e-2)."""
    converged = dict(newton_iterations=30, newton_tolerance=1e-9, cg_tolerance=1e-12)
    runs = {}
    for solver in ("cg", "cholesky"):
        sys = sagging_block()
        stats = [sys.step("backward_euler", dt=0.01, linear_solver=solver, **converged)]
        # the settings stay for the following calls with the same integrator
        stats += [sys.step("backward_euler", dt=0.01) for _ in range(19)]
        assert all(s["newton_iterations"] < 30 for s in stats)
        runs[solver] = (sys.displacements, [s["factorizations"] for s in stats])
    u_cg, f_cg = runs["cg"]
    u_chol, f_chol = runs["cholesky"]
    sag = np.abs(u_cg).max()
    assert sag > 1e-3, sag
    assert np.abs(u_chol - u_cg).max() < 1e-6 * sag
    assert f_cg == [0] * 20
    assert f_chol[0] >= 1 and 1 <= sum(f_chol) < 20, f_chol


@pytest.mark.parametrize(
    "keyword, values",
    [("cholesky_ordering", ("amd", "nested_dissection")), ("factor_precision", ("f64", "f32"))],
)
def test_cholesky_options_reach_the_same_steps(keyword, values):
    """Nested dissection against AMD, and an f32 factor against an f64 one (both
    forced: the block is below the 3000 unknowns where `auto` takes them), factor
    the same matrix in other orders or precisions, so with both runs converged each
    step (Newton to 1e-9 on exact f64 residuals) they end on the same state.

    Bound: as in the CG/Cholesky test above, each step meets |r| ≤ 1e-9 of its scale,
    so the states agree to ~1e-8 of the sag; 1e-6 leaves margin, while an option
    that scrambled the unknowns (a wrong permutation) would leave O(1) of the sag."""
    converged = dict(newton_iterations=30, newton_tolerance=1e-9)
    runs = {}
    for value in values:
        sys = sagging_block()
        sys.step("backward_euler", dt=0.01, n=10, linear_solver="cholesky", **{keyword: value}, **converged)
        runs[value] = sys.displacements
    base, other = (runs[v] for v in values)
    sag = np.abs(base).max()
    assert sag > 1e-3, sag
    assert np.abs(other - base).max() < 1e-6 * sag
    # the keyword reached the factor: other elimination orders (or an f32 factor)
    # round differently, so the two (each deterministic) runs cannot be the same bits
    assert not np.array_equal(other, base)


def test_implicit_settings_are_refused_for_explicit_integrators_and_bad_values():
    sys = sagging_block()
    with pytest.raises(ValueError, match="explicit"):
        sys.step("velocity_verlet", linear_solver="cholesky")
    with pytest.raises(ValueError, match="'cg' or 'cholesky'"):
        sys.step("backward_euler", dt=0.01, linear_solver="lu")
    with pytest.raises(ValueError, match="'nested_dissection', got \"metis\""):
        sys.step("backward_euler", dt=0.01, linear_solver="cholesky", cholesky_ordering="metis")
    with pytest.raises(ValueError, match="'f32', got \"double\""):
        sys.step("backward_euler", dt=0.01, linear_solver="cholesky", factor_precision="double")
    with pytest.raises(heml.HemlError, match="newton_tolerance"):
        sys.step("backward_euler", dt=0.01, newton_tolerance=2.0)
    assert sys.step_count == 0


def test_lazy_energy_steps_and_reports_as_the_eager_system():
    """`lazy_energy=True` (explicit steps skip the energy where a field can) steps
    exactly as the default system, and `energies()` evaluated on request equals the
    energies the eager system kept from its last force evaluation."""
    mesh = heml.box_mesh([0.04, 0.01, 0.01], [8, 2, 2])
    runs = []
    for lazy in (False, True):
        x = mesh.nodes[:, 0]
        sys = heml.System(
            mesh, "neo_hookean", {"E": 5e3, "nu": 0.45}, gravity=[0.0, 0.0, -9.81],
            fixed=x == 0.0, energy_every=0, lazy_energy=lazy,
        )
        sys.step("symplectic_euler", n=40)
        runs.append((sys.positions.copy(), sys.energies()))
    (x0, e0), (x1, e1) = runs
    assert np.array_equal(x0, x1)
    assert e0["elastic"] > 0.0 and e1 == e0


def test_setting_positions_puts_constrained_nodes_back_at_once():
    """A fixed node moved by the positions setter is back at rest right away (the
    next force evaluation used to see it moved, and the step diverged); a prescribed
    node goes to X + r(t)·u; free nodes keep the positions given."""
    mesh = heml.box_mesh([0.1, 0.02, 0.02], [4, 2, 2])
    X = mesh.nodes
    fixed = X[:, 0] == 0
    pushed = np.isclose(X[:, 0], 0.1)
    u = np.array([0.001, 0.0, 0.0])
    sys = heml.System(mesh, heml.material("neo_hookean", E=3e3, nu=0.45), fixed=fixed,
                      prescribed=[(pushed, u, heml.Ramp.step())])
    y = X.copy()
    y[:, 2] += 0.01  # every node, the constrained ones too, 1 cm up
    sys.positions = y
    x = sys.positions
    assert np.array_equal(x[fixed], X[fixed])
    assert np.array_equal(x[pushed], X[pushed] + u)
    free = ~(fixed | pushed)
    assert np.array_equal(x[free], y[free])
    v = np.ones_like(X)
    sys.velocities = v
    assert not sys.velocities[fixed | pushed].any() and np.array_equal(sys.velocities[free], v[free])
    sys.velocities = np.zeros_like(X)
    sys.step("velocity_verlet", n=20)
    assert np.abs(sys.displacements).max() < 0.02
