"""Bad input raises a Python exception with the library's message: never a crash."""

import numpy as np
import pytest

import heml

NODES = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]])


def test_degenerate_tet_is_a_heml_error():
    flat = NODES.copy()
    flat[3] = [1, 1, 0]  # all four nodes in the plane z = 0
    with pytest.raises(heml.HemlError, match="degenerate rest tet.*ids 0"):
        heml.Mesh(flat, [[0, 1, 2, 3]])


def test_out_of_range_index_names_the_tet():
    with pytest.raises(heml.HemlError, match="tet 0 refers to node 7"):
        heml.Mesh(NODES, [[0, 1, 2, 7]])


def test_non_finite_coordinate_names_the_node():
    bad = NODES.copy()
    bad[2, 1] = np.nan
    with pytest.raises(heml.HemlError, match="node 2 has a non-finite coordinate"):
        heml.Mesh(bad, [[0, 1, 2, 3]])


def test_negative_index_is_a_value_error():
    with pytest.raises(ValueError, match="indices must be >= 0"):
        heml.Mesh(NODES, [[0, 1, 2, -1]])


@pytest.mark.parametrize(
    "nodes, tets, exc",
    [
        (NODES.astype(np.float32), [[0, 1, 2, 3]], TypeError),
        (NODES.astype(np.int64), [[0, 1, 2, 3]], TypeError),
        (NODES[:, :2], [[0, 1, 2, 3]], ValueError),
        (NODES.ravel(), [[0, 1, 2, 3]], ValueError),
        (NODES, [[0.0, 1.0, 2.0, 3.0]], TypeError),
        (NODES, [[0, 1, 2]], ValueError),
        (NODES, np.array([[0, 1, 2, 3]], dtype=np.uint8), None),
        (NODES, np.array([[0, 1, 2, 3]], dtype=np.int32), None),
    ],
)
def test_mesh_array_shapes_and_dtypes(nodes, tets, exc):
    """Wrong dtypes are TypeErrors, wrong shapes ValueErrors; any integer dtype is
    accepted for the tets."""
    if exc is None:
        assert heml.Mesh(nodes, tets).n_tets == 1
    else:
        with pytest.raises(exc):
            heml.Mesh(nodes, tets)


def test_unknown_law_lists_the_known_ones():
    with pytest.raises(heml.HemlError, match="did you mean 'neo_hookean'.*known: .*mooney_rivlin"):
        heml.material("neo_hooken", E=3e3, nu=0.45)


@pytest.mark.parametrize(
    "params, message",
    [
        (dict(E=3e3), "nu"),
        (dict(mu=1e3, lambda_=1.0), "lambda_"),
        (dict(mu=float("nan"), **{"lambda": 1.0}), "mu"),
        (dict(mu=-1.0, **{"lambda": 1.0}), "mu"),
    ],
)
def test_bad_parameters_are_heml_errors(params, message):
    with pytest.raises(heml.HemlError, match=message):
        heml.material("neo_hookean", **params)


def test_non_numeric_parameter_is_a_type_error():
    with pytest.raises(TypeError, match="E must be a number"):
        heml.material("neo_hookean", E="soft", nu=0.45)


def test_force_input_shape_and_dtype():
    mesh = heml.Mesh(NODES, [[0, 1, 2, 3]])
    field = heml.material("neo_hookean", E=3e3, nu=0.45).force_field(mesh)
    with pytest.raises(ValueError, match=r"shape \(4, 3\)"):
        field.forces(np.zeros((5, 3)))
    with pytest.raises(TypeError, match="float64"):
        field.forces(NODES.astype(np.float32))
    with pytest.raises(TypeError, match="float64"):
        field.forces(NODES.astype(np.int64))
    with pytest.raises(ValueError):
        field.forces([[0.0, 0.0], [1.0]])  # ragged


def test_non_finite_positions_are_reported():
    mesh = heml.Mesh(NODES, [[0, 1, 2, 3]])
    field = heml.material("neo_hookean", E=3e3, nu=0.45).force_field(mesh)
    x = NODES.copy()
    x[1, 0] = np.inf
    with pytest.raises(heml.HemlError, match="x: node 1 has a non-finite coordinate"):
        field.forces(x)


def test_unreadable_and_malformed_files(tmp_path):
    with pytest.raises(heml.HemlError, match="missing.msh"):
        heml.read_mesh(tmp_path / "missing.msh")
    bad = tmp_path / "bad.msh"
    bad.write_text("$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n3\n1 0 0 0\n")
    with pytest.raises(heml.HemlError, match="bad.msh:"):
        heml.read_mesh(bad)
    with pytest.raises(heml.HemlError, match="unknown mesh extension"):
        heml.read_mesh(tmp_path / "mesh.stl")


def test_system_errors():
    mesh = heml.box_mesh([0.02, 0.02, 0.02], [2, 2, 2])
    law = heml.material("neo_hookean", E=3e3, nu=0.45)
    with pytest.raises(heml.HemlError, match="out of range"):
        heml.System(mesh, law, fixed=[10_000])
    with pytest.raises(ValueError, match="boolean mask must have shape"):
        heml.System(mesh, law, fixed=np.ones(3, dtype=bool))
    with pytest.raises(heml.HemlError, match="unknown material law"):
        heml.System(mesh, "rubber", {"E": 1.0})
    with pytest.raises(TypeError):
        heml.System(mesh, 42)
    sys = heml.System(mesh, law)
    with pytest.raises(heml.HemlError, match="unknown integrator"):
        sys.step("leapfrog", dt=1e-4)
    with pytest.raises(heml.HemlError):
        sys.step(dt=-1.0)
    with pytest.raises(heml.HemlError):
        sys.step(dt=float("nan"))


def test_blow_up_names_the_step_and_keeps_the_last_good_state():
    """A step far above the stable limit blows up: HemlError with the step, and the
    system holds finite positions afterwards."""
    mesh = heml.box_mesh([0.02, 0.02, 0.02], [2, 2, 2])
    sys = heml.System(
        mesh, heml.material("neo_hookean", E=3e3, nu=0.45), gravity=[0, 0, -9.81],
        fixed=mesh.nodes[:, 0] == 0, dt_policy="ignore",
    )
    with pytest.raises(heml.HemlError, match="step"):
        sys.step("explicit_euler", dt=1000 * sys.stable_dt, n=200)
    assert np.all(np.isfinite(sys.positions))


def test_scene_errors_name_the_key(tmp_path):
    with pytest.raises(heml.HemlError, match="densty"):
        heml.Scene.from_toml('[mesh]\ngenerate = { kind = "box", size = [1, 1, 1], cells = [1, 1, 1] }\n'
                             '[[material]]\nlaw = "neo_hookean"\nparams = { E = 1e3, nu = 0.3 }\ndensty = 1.0\n')
    with pytest.raises(heml.HemlError):
        heml.Scene.from_file(tmp_path / "nope.toml")
