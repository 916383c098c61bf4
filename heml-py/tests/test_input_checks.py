"""Bad input values are refused with an exception naming the argument, node, tet or
cell concerned: never a panic, a silent truncation, a NaN result or an abort."""

import os
import subprocess
import sys
import textwrap

import numpy as np
import pytest

import heml
from heml import _heml


def setup():
    mesh = heml.box_mesh([0.1, 0.02, 0.02], [4, 2, 2])
    return mesh, mesh.nodes, heml.material("neo_hookean", E=3e3, nu=0.45)


# ----- ramps ----------------------------------------------------------------------


@pytest.mark.parametrize(
    "make, message",
    [
        (lambda: heml.Ramp.keyframes([]), "at least one"),
        (lambda: heml.Ramp.linear(-1.0), "duration -1"),
        (lambda: heml.Ramp.linear(0.0), "duration 0"),
        (lambda: heml.Ramp.smooth(float("nan")), "duration NaN"),
        (lambda: heml.Ramp.keyframes([[0.0, 0.0], [float("nan"), 1.0]]), "keyframe #2"),
        (lambda: heml.Ramp.keyframes([[1.0, 0.0], [1.0, 1.0]]), "increase strictly"),
    ],
)
def test_ramps_are_checked_when_made(make, message):
    """An empty keyframe list used to panic in value(); bad durations were taken."""
    with pytest.raises(heml.HemlError, match=message):
        make()


def test_good_ramps_still_work():
    assert heml.Ramp.linear(2.0).value(1.0) == 0.5
    assert heml.Ramp.keyframes([[1.0, 1.0], [2.0, 0.0]]).value(1.5) == 0.5


# ----- memory ---------------------------------------------------------------------


def test_a_copy_that_cannot_be_allocated_is_a_memory_error():
    """Under a 4 GB address-space limit, copying 2.4 GB of nodes (on top of NumPy's
    2.4 GB array) fails: MemoryError, where the allocator used to abort the process.
    Run in a child process, so that the limit stays there."""
    code = textwrap.dedent("""
        import resource
        resource.setrlimit(resource.RLIMIT_AS, (4_000_000_000, 4_000_000_000))
        import numpy as np, heml
        nodes = np.zeros((10**8, 3))
        try:
            heml.Mesh(nodes, [[0, 1, 2, 3]])
        except MemoryError as e:
            print("MemoryError:", e)
    """)
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120,
                       env=dict(os.environ, OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1"))
    assert r.returncode == 0, r.stderr[-2000:]
    assert "MemoryError: nodes: cannot allocate 2400000000 bytes" in r.stdout, (r.stdout, r.stderr[-2000:])


# ----- non-finite positions -------------------------------------------------------


def test_non_finite_positions_name_the_node():
    mesh, X, law = setup()
    field = law.force_field(mesh)
    y = X.copy()
    y[3, 1] = np.nan
    for call in (field.forces, field.energy, field.tet_states, field.tangent):
        with pytest.raises(heml.HemlError, match=r"x: node 3 has a non-finite coordinate"):
            call(y)
    dx = np.zeros_like(X)
    dx[5, 2] = np.inf
    with pytest.raises(heml.HemlError, match=r"dx: node 5 has a non-finite coordinate"):
        field.hessian_product(X, dx)
    with pytest.raises(heml.HemlError, match=r"x: node 3"):
        field.hessian_product(y, np.zeros_like(X))


def test_a_non_finite_result_from_finite_positions_is_an_error():
    """X·1e150 overflows the invariants: the result is named as not finite, with the
    first tet concerned, instead of NaN forces and energy returned."""
    mesh, X, law = setup()
    field = law.force_field(mesh)
    with pytest.raises(heml.HemlError, match=r"forces: the result is not finite .*at node \d+.*tet \d+"):
        field.forces(X * 1e150)
    with pytest.raises(heml.HemlError, match=r"energy: the result is not finite.*tet \d+"):
        field.energy(X * 1e150)
    with pytest.raises(heml.HemlError, match=r"tet_states: .* of tet \d+ is not finite"):
        field.tet_states(X * 1e150)


def test_system_state_setters_refuse_nan_and_keep_the_state():
    mesh, X, law = setup()
    s = heml.System(mesh, law)
    y = X.copy()
    y[7, 0] = np.nan
    with pytest.raises(heml.HemlError, match="positions: node 7 has a non-finite coordinate"):
        s.positions = y
    with pytest.raises(heml.HemlError, match="velocities: node 7 has a non-finite coordinate"):
        s.velocities = y
    with pytest.raises(heml.HemlError, match="initial_velocity: node 7"):
        heml.System(mesh, law, initial_velocity=y)
    assert np.array_equal(s.positions, X) and not s.velocities.any()
    s.positions = X * 1e150  # finite, but no energy can be computed there
    with pytest.raises(heml.HemlError, match="energies: the elastic energy is NaN"):
        s.energies()


# ----- ids listed twice, tags ------------------------------------------------------


def test_an_integer_mask_is_refused_as_repeated_ids():
    """(x == 0).astype(int) used to fix nodes {0, 1}: ids listed twice are an error
    that says a mask must be boolean."""
    mesh, X, law = setup()
    with pytest.raises(heml.HemlError, match=r"fixed: node 0 is listed twice.*dtype bool"):
        heml.System(mesh, law, fixed=(X[:, 0] == 0).astype(int))
    with pytest.raises(heml.HemlError, match=r"prescribed nodes: node 4 is listed twice"):
        heml.System(mesh, law, prescribed=[([4, 5, 4], [0.0, 0.0, 0.001])])
    s = heml.System(mesh, law, fixed=X[:, 0] == 0)
    with pytest.raises(heml.HemlError, match=r"grasp: node 9 is listed twice"):
        s.grasp([9, 9], 1.0)


def test_repeated_tet_ids_are_refused():
    mesh, X, law = setup()
    with pytest.raises(heml.HemlError, match=r"tets: tet 0 is listed twice"):
        law.force_field(mesh, [0, 0, 0])
    # a boolean mask selects tets too
    assert law.force_field(mesh, np.arange(mesh.n_tets) < 5).n_tets == 5


@pytest.mark.parametrize("tag, shown", [(2**40, "1099511627776"), (2.7, "2.7"), (-(2**31) - 1, "-2147483649")])
def test_meshio_tags_out_of_int32_or_fractional_are_refused(tag, shown):
    meshio = pytest.importorskip("meshio")
    mesh, X, _ = setup()
    tags = np.zeros(mesh.n_tets, dtype=np.asarray(tag).dtype)
    tags[5] = tag
    m = meshio.Mesh(X, [("tetra", mesh.tets)], cell_data={"tag": [tags]})
    with pytest.raises(ValueError, match=rf"block 0: cell 5 has tag {shown}; tags must be integers in the int32"):
        heml.Mesh.from_meshio(m)
    # integral floats are taken as they are
    m = meshio.Mesh(X, [("tetra", mesh.tets)], cell_data={"tag": [np.full(mesh.n_tets, 3.0)]})
    assert np.all(heml.Mesh.from_meshio(m).tags == 3)


def test_mesh_tags_are_not_truncated():
    mesh, X, _ = setup()
    with pytest.raises(ValueError, match=r"tags: tet 1 has tag 2.5"):
        heml.Mesh(X, mesh.tets, [0, 2.5] + [0] * (mesh.n_tets - 2))
    assert list(heml.Mesh(X, mesh.tets, np.arange(mesh.n_tets)).tags[:3]) == [0, 1, 2]


# ----- poses and tools -----------------------------------------------------------


def test_a_rotation_alone_is_applied():
    """A rotation given without a translation used to be dropped (identity pose)."""
    mesh, X, law = setup()
    s = heml.System(mesh, law, fixed=X[:, 0] == 0)
    n = mesh.n_nodes
    turn = [0.0, 0.0, 1.0]
    # a grasp made with pose R0 holds its node where it is; moving the target to R0
    # is then no motion at all, while for a grasp made at the identity it is a turn
    # of 1 rad about z
    g = s.grasp([n - 1], 1.0, rotation=turn)
    h = s.grasp([n - 2], 1.0)
    s.move_grasp(g, [0.0, 0.0, 0.0], rotation=turn)
    s.move_grasp(h, [0.0, 0.0, 0.0], rotation=turn)
    s.compute_forces()
    assert np.linalg.norm(s.grasp_force(g)) < 1e-12
    assert np.linalg.norm(s.grasp_force(h)) > 0.01
    # a half space turned upside down (solid z >= 0) holds the whole box
    t = s.add_tool("half_space", 1e3, rotation=[np.pi, 0.0, 0.0])
    s.compute_forces()
    assert np.linalg.norm(s.tool_wrench(t)[0]) > 1.0


def test_bad_poses_and_unused_tool_dimensions_are_refused():
    mesh, X, law = setup()
    s = heml.System(mesh, law, fixed=X[:, 0] == 0)
    with pytest.raises(heml.HemlError, match=r"rotation \[NaN, 0.0, 0.0\] .* is not finite"):
        s.add_tool("sphere", 1e3, radius=0.01, rotation=[np.nan, 0.0, 0.0])
    with pytest.raises(heml.HemlError, match=r"rotation \[0.0, 0.0, 1e300\]"):
        s.add_tool("sphere", 1e3, radius=0.01, rotation=[0.0, 0.0, 1e300])
    with pytest.raises(heml.HemlError, match=r"translation \[inf, 0.0, 0.0\] is not finite"):
        s.grasp([3], 1.0, translation=[np.inf, 0.0, 0.0])
    with pytest.raises(ValueError, match="a half_space has no radius"):
        s.add_tool("half_space", 1e3, radius=0.01)
    with pytest.raises(ValueError, match="a sphere has no half_length"):
        s.add_tool("sphere", 1e3, radius=0.01, half_length=0.02)
    with pytest.raises(ValueError, match="a capsule needs half_length"):
        s.add_tool("capsule", 1e3, radius=0.01)
    with pytest.raises(ValueError, match="a sphere needs radius"):
        s.add_tool("sphere", 1e3)
    assert s.add_tool("capsule", 1e3, radius=0.01, half_length=0.02, translation=[0.0, 0.0, 0.5]) == 0


# ----- scalar values ---------------------------------------------------------------


@pytest.mark.parametrize("density", [-1.0, 0.0, float("nan"), float("inf")])
def test_lumped_masses_need_a_positive_density(density):
    mesh, _, _ = setup()
    with pytest.raises(heml.HemlError, match="density .* must be a finite number > 0"):
        mesh.lumped_masses(density)


def test_negative_integers_name_the_argument():
    mesh, X, law = setup()
    s = heml.System(mesh, law, fixed=X[:, 0] == 0)
    g = s.grasp([10], 1.0)
    t = s.add_tool("sphere", 1e3, radius=0.01, translation=[0.0, 0.0, 1.0])
    cases = [
        (lambda: heml.box_mesh([1.0, 1.0, 1.0], [2, -1, 1]), r"cells must be 3 integers >= 0, got \[2, -1, 1\]"),
        (lambda: law.force_field(mesh, [3, -1]), r"tets: entry 1 \(flat index\) is -1"),
        (lambda: s.step(n=-1), "n must be >= 1 .*got -1"),
        (lambda: heml.System(mesh, law, energy_every=-1), "energy_every must be >= 0, got -1"),
        (lambda: s.move_grasp(-1, [0.0, 0.0, 0.0]), "grasp must be >= 0, got -1"),
        (lambda: s.grasp_force(-2), "grasp must be >= 0, got -2"),
        (lambda: s.set_tool_pose(-1, [0.0, 0.0, 0.0]), "tool must be >= 0, got -1"),
        (lambda: s.tool_wrench(-1), "tool must be >= 0, got -1"),
        (lambda: heml.System(mesh, law, nodal_forces=[(-1, [0, 0, 1])]), "nodal_forces entry 0: node id -1"),
        (lambda: s.solve_static(max_iterations=0), "max_iterations must be >= 1, got 0"),
    ]
    for call, message in cases:
        with pytest.raises(ValueError, match=message):
            call()
    scene = heml.Scene.from_toml(
        '[mesh]\ngenerate = { kind = "box", size = [0.02, 0.01, 0.01], cells = [2, 1, 1] }\n'
        '[[material]]\nlaw = "neo_hookean"\nparams = { E = 5e3, nu = 0.3 }\n'
        '[solver]\nduration = 0.001\n[output]\nvtu = false\ncsv = false\n')
    for every in (-1, 0):
        with pytest.raises(ValueError, match=f"every must be >= 1 \\(steps\\), got {every}"):
            scene.run(every=every)
    with pytest.raises(TypeError, match=r"regions: keys must be integer region tags .*got 'a'"):
        heml.System(mesh, law, regions={"a": law})
    s.move_grasp(g, [0.0, 0.0, 0.001])  # the good ids still work
    s.set_tool_pose(t, [0.0, 0.0, 0.9])


def test_unsigned_indices_keep_their_value():
    """uint64 2**64 - 1 used to be reported as -1."""
    _, X, _ = setup()
    with pytest.raises(heml.HemlError, match="refers to node 18446744073709551615"):
        heml.Mesh(X, np.array([[0, 1, 2, 2**64 - 1]], np.uint64))


def test_messages_say_what_is_expected():
    mesh, X, law = setup()
    s = heml.System(mesh, law)
    with pytest.raises(ValueError, match=r"one entry per tet\), got \[3\]"):
        s.remove_tets(np.zeros(3, bool))
    with pytest.raises(ValueError, match="'five', 'six', 'ten' or 'twentyfour'"):
        heml.box_mesh([1.0, 1.0, 1.0], [1, 1, 1], "seven")
    assert heml.box_mesh([1.0, 1.0, 1.0], [1, 1, 1], "ten").n_tets == 10
    with pytest.raises(ValueError, match="parameter E is out of range"):
        heml.material("neo_hookean", E=10**400, nu=0.45)
    # every node fixed: the stable step is infinite, so dt must be given
    held = heml.System(mesh, law, fixed=np.ones(mesh.n_nodes, bool))
    with pytest.raises(ValueError, match="no node is free .* give the time step dt explicitly"):
        held.step()
    assert held.step(dt=1e-3)["time"] == 1e-3


# ----- arrays read in place ----------------------------------------------------------


def test_only_aligned_c_contiguous_arrays_are_read_in_place():
    """An array at an odd byte offset is C-contiguous but not aligned: forming a
    slice of f64 over it is undefined behaviour, so it is copied (NumPy's copy is
    aligned); aligned C-contiguous arrays are still read in place."""
    mesh, X, law = setup()
    odd = np.frombuffer(bytearray(X.nbytes + 1), np.float64, offset=1, count=X.size).reshape(X.shape)
    odd[:] = X * 1.01
    assert odd.flags.c_contiguous and not odd.flags.aligned
    assert _heml._reads_in_place(X)
    assert not _heml._reads_in_place(odd)
    assert not _heml._reads_in_place(np.asfortranarray(X))
    field = law.force_field(mesh)
    e, f = field.forces(odd)
    e0, f0 = field.forces(X * 1.01)
    assert e == e0 and np.array_equal(f, f0)
    assert np.array_equal(heml.Mesh(odd, mesh.tets).nodes, X * 1.01)
