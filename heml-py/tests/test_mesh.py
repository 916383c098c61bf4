"""Meshes: arrays, tags, the boundary surface, files and meshio."""

import numpy as np
import pytest

import heml

NODES = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 1]])
TETS = np.array([[0, 1, 2, 3], [1, 2, 4, 3]])


def test_arrays_round_trip_and_reorientation():
    """Arrays come back as given, except a negatively oriented tet, whose nodes 2
    and 3 are swapped."""
    m = heml.Mesh(NODES, TETS, tags=[1, 2])
    assert np.array_equal(m.nodes, NODES)
    assert m.reoriented_count == 1
    assert np.array_equal(m.tets, [[0, 1, 2, 3], [1, 2, 3, 4]])
    assert np.array_equal(m.tags, [1, 2])
    assert m.volume == pytest.approx(1 / 6 + 1 / 3, rel=1e-14)
    assert m.lumped_masses(1000.0).sum() == pytest.approx(1000.0 * m.volume, rel=1e-14)


def test_surface_is_closed_and_outward():
    """Every boundary edge is shared by exactly two triangles, and the divergence
    theorem with the triangles' normals gives the box's volume (outward)."""
    m = heml.box_mesh([0.3, 0.2, 0.1], [3, 2, 2])
    points, faces = m.surface()
    assert points.shape == (m.n_nodes, 3) and faces.shape[1] == 3
    assert len(faces) == 2 * (2 * 3 * 2 + 2 * 3 * 2 + 2 * 2 * 2)  # 2 triangles per boundary quad
    p = points[faces]
    volume = np.einsum("ij,ij->i", p[:, 0], np.cross(p[:, 1], p[:, 2])).sum() / 6
    assert volume == pytest.approx(0.3 * 0.2 * 0.1, rel=1e-12)
    _, padded = m.surface(padded=True)
    assert np.array_equal(padded.reshape(-1, 4)[:, 1:], faces)
    assert np.all(padded.reshape(-1, 4)[:, 0] == 3)


def test_system_surface_follows_the_positions():
    m = heml.box_mesh([0.02, 0.02, 0.02], [2, 2, 2])
    sys = heml.System(m, heml.material("neo_hookean", E=3e3, nu=0.45), gravity=[0, 0, -9.81])
    sys.step("symplectic_euler", n=5)
    points, faces = sys.surface()
    assert np.array_equal(points, sys.positions)
    assert np.array_equal(faces, m.surface()[1])


def test_file_round_trip(tmp_path):
    m = heml.box_mesh([0.3, 0.2, 0.1], [3, 2, 1])
    for ext in ("msh", "vtu", "vtk", "mesh", "ply"):
        path = tmp_path / f"box.{ext}"
        heml.write_mesh(path, m)
        back = heml.read_mesh(path)
        assert np.array_equal(back.tets, m.tets), ext
        assert np.allclose(back.nodes, m.nodes, rtol=0, atol=1e-15), ext


def test_ply_boundary_conditions_fix_a_system():
    """An OpenSurgSim-style .ply (heml-core's fixture: two tets, boundary conditions
    2, 0, 1, 1) gives its boundary nodes as a node set, which fixes a system's
    nodes: under gravity they stay exactly at rest while the others fall."""
    from pathlib import Path

    path = Path(__file__).parents[2] / "heml-core" / "tests" / "data" / "tiny_surgsim.ply"
    m = heml.read_mesh(path)
    assert list(m.node_sets) == ["boundary_condition"]
    held = m.node_sets["boundary_condition"]
    assert held.dtype == np.int64 and list(held) == [0, 1, 2]
    assert heml.box_mesh([1, 1, 1], [1, 1, 1]).node_sets == {}
    sys = heml.System(m, heml.material("neo_hookean", E=3e3, nu=0.45), gravity=[0, 0, -9.81], fixed=held)
    sys.step("symplectic_euler", dt=0.1 * sys.stable_dt, n=5)
    d = sys.displacements
    assert np.all(d[held] == 0.0)
    assert np.all(d[[3, 4], 2] < 0)


def test_gmsh_physical_surfaces_are_node_sets():
    """A file written by Gmsh (heml-core's fixture, a unit cube) gives its physical
    points, curves and surfaces as node sets by name: "clamp" is the face z = 0."""
    from pathlib import Path

    m = heml.read_mesh(Path(__file__).parents[2] / "heml-core" / "tests" / "data" / "gmsh_groups_b41.msh")
    sets = m.node_sets
    assert sorted(sets) == ["clamp", "edge", "point 9", "surface 7"]
    assert np.array_equal(sets["clamp"], np.flatnonzero(np.abs(m.nodes[:, 2]) < 1e-12))
    assert len(sets["point 9"]) == 1 and np.allclose(m.nodes[sets["point 9"][0]], [1, 1, 1], atol=1e-12)


def test_meshio_round_trip_in_memory():
    """Mesh → meshio.Mesh → Mesh keeps nodes, tets and tags exactly."""
    pytest.importorskip("meshio")
    m = heml.Mesh(NODES, TETS, tags=[3, 7])
    mm = m.to_meshio()
    assert mm.cells[0].type == "tetra"
    back = heml.Mesh.from_meshio(mm)
    assert np.array_equal(back.nodes, m.nodes)
    assert np.array_equal(back.tets, m.tets)
    assert np.array_equal(back.tags, [3, 7])


def test_meshio_written_files_read_the_same(tmp_path):
    """Files meshio writes in the formats our readers take (ASCII Gmsh 2.2, VTU
    uncompressed/zlib, VTK) read back to meshio's nodes and tets."""
    meshio = pytest.importorskip("meshio")
    m = heml.box_mesh([0.3, 0.2, 0.1], [3, 2, 1])
    mm = meshio.Mesh(m.nodes, [("tetra", m.tets)])
    cases = [("a.msh", dict(file_format="gmsh22", binary=False)), ("a.vtu", dict(compression=None)),
             ("b.vtu", dict(compression="zlib")), ("a.vtk", dict(binary=False))]
    for name, kw in cases:
        path = tmp_path / name
        meshio.write(path, mm, **kw)
        back = heml.read_mesh(path)
        assert np.array_equal(back.nodes, m.nodes), name
        assert np.array_equal(back.tets, m.tets), name


def test_from_meshio_skips_other_cells_and_reads_gmsh_tags():
    meshio = pytest.importorskip("meshio")
    mm = meshio.Mesh(NODES, [("triangle", np.array([[0, 1, 2]])), ("tetra", TETS)],
                     cell_data={"gmsh:physical": [np.array([9]), np.array([4, 5])]})
    m = heml.Mesh.from_meshio(mm)
    assert m.n_tets == 2 and np.array_equal(m.tags, [4, 5])


def test_materials_registry():
    """materials() lists every law with its parameters and energy text."""
    laws = {m["name"]: m for m in heml.materials()}
    assert laws["mooney_rivlin"]["parameters"] == ["c10", "c01", "kappa"]
    assert "ln" in laws["neo_hookean"]["energy"]
    assert laws["mass_spring"]["kind"] == "link" and not laws["mass_spring"]["young_poisson"]
    law = heml.material("neo_hookean", E=3e3, nu=0.45)
    mu = 3e3 / (2 * 1.45)
    assert law.params["mu"] == pytest.approx(mu, rel=1e-15)
    assert law.params["lambda"] == pytest.approx(3e3 * 0.45 / (1.45 * 0.1), rel=1e-14)
    assert "velocity_verlet" in dict(heml.integrators())
