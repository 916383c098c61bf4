"""Runtime control from Python: a grasp lifts and is felt, a tool is pushed back by
the tissue, a cut splits the body, and bad calls raise without changing anything."""

import numpy as np
import pytest

import heml


def block():
    """A 4 × 4 × 4 cm neo-Hookean block clamped at its base (z = 0)."""
    mesh = heml.box_mesh([0.04, 0.04, 0.04], [3, 3, 3], "six")
    z = mesh.nodes[:, 2]
    return heml.System(mesh, "neo_hookean", {"E": 5e3, "nu": 0.45}, density=1000.0, fixed=z < 1e-9, rayleigh=(20.0, 0.0))


def top_nodes(sys):
    return np.flatnonzero(sys.rest_positions[:, 2] > 0.04 - 1e-9)


def test_a_grasp_lifts_the_top_and_the_hand_feels_the_tissue_pull_back():
    sys = block()
    top = top_nodes(sys)
    g = sys.grasp(top, stiffness=500.0, damping=0.5)
    for s in range(1, 41):
        sys.move_grasp(g, [0.0, 0.0, 0.01 * s / 40])
        sys.step("backward_euler", dt=5e-3)
    for _ in range(40):
        sys.step("backward_euler", dt=5e-3)
    lift = sys.displacements[top, 2].mean()
    # the springs hold the top near +1 cm; the stretched block pulls it back by
    # F/(n·k), a few percent of the lift at these stiffnesses
    assert 0.008 < lift < 0.0101, lift
    felt = np.array(sys.grasp_force(g))
    assert felt[2] < 0.0  # the tissue pulls the hand down
    # what the hand feels is what the clamp holds (static balance, no gravity; 1e-6
    # relative: the run is 0.4 s of a damped 20 Hz block, settled well below that)
    assert np.allclose(felt, sys.total_reaction, rtol=1e-6, atol=1e-6 * np.abs(felt).max())
    sys.release_grasp(g)
    with pytest.raises(KeyError):
        sys.grasp_force(g)


def test_a_tool_is_pushed_back_and_a_cut_splits_the_block():
    sys = block()
    # a 1 cm sphere centred 5 mm above the top-face node at (2.67, 2.67, 4) cm
    t = sys.add_tool("sphere", stiffness=2e3, radius=0.01, translation=[0.08 / 3, 0.08 / 3, 0.045])
    sys.compute_forces()
    force, torque = sys.tool_wrench(t)
    assert force[2] > 0.0  # the top face pushes the sphere up
    # a sphere's contact forces point through its centre: no torque about it (lever
    # arms ≤ the radius, 1 cm; what remains is round-off, ≪ 1e-12 of |f|·r)
    assert np.linalg.norm(torque) <= 1e-12 * 0.01 * np.linalg.norm(force)
    sys.remove_tool(t)
    n, mass = sys.n_tets, sys.masses.sum()
    # a vertical blade through x = 2.1 cm, sweeping across the whole block
    r = sys.cut([[0.021, -0.01, -0.01], [0.021, -0.01, 0.05], [0.021, 0.05, -0.01], [0.021, 0.05, 0.05]])
    assert len(r["removed_tets"]) > 0 and r["remaining_tets"] == sys.n_tets < n
    # the removed tets' mass is reported and gone, to round-off of a sum of ~300 terms
    assert sys.masses.sum() + r["removed_mass"] == pytest.approx(mass, rel=1e-12)


def test_bad_control_calls_raise_and_change_nothing():
    sys = block()
    before = (sys.positions.copy(), sys.masses.copy(), sys.n_tets)
    with pytest.raises(heml.HemlError, match="empty"):
        sys.grasp(np.array([], dtype=np.int64), stiffness=10.0)
    with pytest.raises(heml.HemlError):
        sys.prescribe_pose(top_nodes(sys), [np.nan, 0.0, 0.0])
    with pytest.raises(ValueError, match="unknown tool shape"):
        sys.add_tool("cube", stiffness=1.0, radius=0.01)
    with pytest.raises(heml.HemlError, match="radius"):
        sys.add_tool("sphere", stiffness=1.0, radius=-0.01)
    with pytest.raises(KeyError):
        sys.set_tool_pose(7, [0.0, 0.0, 0.0])
    with pytest.raises(heml.HemlError, match="meets no tet"):
        sys.cut([[1.0, 1.0, 1.0], [2.0, 1.0, 1.0], [1.0, 2.0, 1.0]])
    with pytest.raises(ValueError, match="3 points"):
        sys.cut([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]])
    after = (sys.positions, sys.masses, sys.n_tets)
    assert np.array_equal(before[0], after[0]) and np.array_equal(before[1], after[1]) and before[2] == after[2]


def test_a_law_replaced_after_a_cut_keeps_the_cut_and_stiffens_the_block():
    sys = block()
    # a notch through the top layer, then a sag under sideways gravity
    sys.cut([[-0.01, 0.02, 0.05], [0.05, 0.02, 0.05], [-0.01, 0.02, 0.028]])
    tets, masses = sys.n_tets, sys.masses.copy()
    sys.set_gravity([9.81, 0.0, 0.0])
    sys.solve_static()
    soft = sys.displacements[:, 0].max()
    # the same law again: the stable step estimated anew on the cut block
    sys.set_material("neo_hookean", {"E": 5e3, "nu": 0.45})
    dt = sys.stable_dt
    sys.set_material("neo_hookean", {"E": 2e4, "nu": 0.45})
    # the cut stays (same tets, same masses) and the state too
    assert sys.n_tets == tets and np.array_equal(sys.masses, masses)
    assert sys.displacements[:, 0].max() == soft
    # four times E: twice the highest frequency ω, so half the undamped step; the
    # mass damping α = 20/s shortens a step by √(1 + ζ²) − ζ, ζ = α/(2ω), less at the
    # higher ω: a little over half
    assert 0.5 < sys.stable_dt / dt < 0.6, sys.stable_dt / dt
    # a quarter of the sag (a neo-Hookean block at a few percent strain is linear to
    # within its strain: 5 %)
    sys.solve_static()
    stiff = sys.displacements[:, 0].max()
    assert abs(stiff / soft - 0.25) < 0.05 * 0.25, (soft, stiff)
    # a heml.Material works too (back to the first law: the same estimate, to the
    # bit); bad regions and parameters raise, nothing changes
    sys.set_material(heml.material("neo_hookean", E=5e3, nu=0.45))
    assert sys.stable_dt == dt
    with pytest.raises(KeyError, match="no region 3"):
        sys.set_material("neo_hookean", {"E": 2e4, "nu": 0.45}, region=3)
    with pytest.raises(heml.HemlError):
        sys.set_material("neo_hookean", {"E": -1.0, "nu": 0.45})
    assert sys.stable_dt == dt
