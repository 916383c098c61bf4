"""The type stubs and the module agree, and everything public has a docstring."""

import ast
import inspect
import pathlib
import typing

import numpy as np
import pytest

import heml

STUBS = pathlib.Path(heml.__file__).with_name("__init__.pyi")
# the returned dicts: TypedDicts of `_types.py`, which the package and the stubs import
TYPES = pathlib.Path(heml.__file__).with_name("_types.py")
TYPED_DICTS = {"Energies", "MaterialInfo", "StaticReport", "StepStats"}


def stub_body():
    """The stubs' top-level statements, with the TypedDicts they import."""
    return ast.parse(STUBS.read_text()).body + ast.parse(TYPES.read_text()).body


def stub_names():
    out = {}
    for node in stub_body():
        if isinstance(node, (ast.FunctionDef, ast.ClassDef)):
            members = set()
            if isinstance(node, ast.ClassDef):
                for m in node.body:
                    if isinstance(m, ast.FunctionDef):
                        members.add(m.name)
                    elif isinstance(m, ast.AnnAssign):
                        members.add(m.target.id)
            out[node.name] = members
    return out


def stub_all():
    for node in ast.parse(STUBS.read_text()).body:
        if isinstance(node, ast.Assign) and [t.id for t in node.targets] == ["__all__"]:
            return [ast.literal_eval(e) for e in node.value.elts]
    raise AssertionError("the stubs have no __all__")


def test_stubs_match_the_module():
    stubs = stub_names()
    public = {n for n in heml.__all__ if not n.startswith("__")}
    assert set(stubs) == public
    assert stub_all() == heml.__all__
    for name, members in stubs.items():
        obj = getattr(heml, name)
        if name in TYPED_DICTS:
            # the TypedDicts exist at run time, with the stubs' keys
            assert set(obj.__annotations__) == members, name
            continue
        for m in members - {"__init__"}:
            assert hasattr(obj, m), f"{name}.{m} is in the stubs but not in the module"
        if inspect.isclass(obj) and name != "HemlError":
            actual = {m for m in vars(obj) if not m.startswith("_")}
            assert actual <= members, f"{name}: {sorted(actual - members)} missing from the stubs"


def test_every_public_item_has_a_docstring():
    for name in heml.__all__:
        obj = getattr(heml, name)
        if name.startswith("__"):
            continue
        assert (obj.__doc__ or "").strip(), name
        if inspect.isclass(obj):
            for m, member in vars(obj).items():
                if not m.startswith("_"):
                    assert (getattr(member, "__doc__", None) or "").strip(), f"{name}.{m}"


def stub_literal(cls, member):
    """The strings of the `Literal[...]` annotation of `cls.member` in the stubs
    (a property's return, a field's type or a parameter named `member` of a function)."""
    for node in stub_body():
        if isinstance(node, (ast.ClassDef, ast.FunctionDef)) and node.name == cls:
            for sub in ast.walk(node):
                ann = None
                if isinstance(sub, ast.AnnAssign) and getattr(sub.target, "id", None) == member:
                    ann = sub.annotation
                elif isinstance(sub, ast.FunctionDef) and sub.name == member:
                    ann = sub.returns
                elif isinstance(sub, ast.arg) and sub.arg == member:
                    ann = sub.annotation
                if ann is not None:
                    return {c.value for c in ast.walk(ann) if isinstance(c, ast.Constant)}
    raise AssertionError(f"{cls}.{member} not in the stubs")


def test_stub_literals_cover_what_the_module_returns_and_accepts():
    kinds = {m["kind"] for m in heml.materials()}
    assert "fibre" in kinds
    assert kinds <= stub_literal("MaterialInfo", "kind")
    assert stub_literal("Material", "kind") == stub_literal("MaterialInfo", "kind") == {
        "invariant", "link", "stretch", "fibre"}
    assert set(typing.get_args(typing.get_type_hints(heml.MaterialInfo)["kind"])) == stub_literal("MaterialInfo", "kind")
    splits = stub_literal("box_mesh", "split")
    assert splits == {"five", "six", "ten", "twentyfour"}
    for split in splits:
        assert heml.box_mesh([1.0, 1.0, 1.0], [1, 1, 1], split).n_tets > 0


def test_step_without_steps_is_a_value_error():
    """`step(n=0)` used to return {}, which is no StepStats."""
    mesh = heml.box_mesh([0.02, 0.02, 0.02], [1, 1, 1])
    sys = heml.System(mesh, heml.material("neo_hookean", E=3e3, nu=0.45))
    with pytest.raises(ValueError, match="n must be >= 1"):
        sys.step(n=0)
    stats = sys.step(n=2)
    assert set(stats) == set(heml.StepStats.__annotations__)
    assert set(stats["energies"]) == set(heml.Energies.__annotations__)
    assert set(sys.energies()) == set(heml.Energies.__annotations__)


def test_tangent_products_from_both_sides():
    """`K @ dx` takes dx positionally; `dx @ K` (a NumPy array on the left) gives K·dx
    too (K is symmetric) instead of NumPy's object-array error."""
    mesh = heml.box_mesh([0.02, 0.02, 0.02], [1, 1, 1])
    x = mesh.nodes * 1.05
    k = heml.material("neo_hookean", E=3e3, nu=0.45).force_field(mesh).tangent(x)
    dx = np.linspace(-1.0, 1.0, 3 * mesh.n_nodes).reshape(-1, 3)
    assert np.array_equal(dx @ k, k @ dx) and np.array_equal(k @ dx, k.dot(dx))
    stub = next(n for n in ast.walk(ast.parse(STUBS.read_text()))
                if isinstance(n, ast.ClassDef) and n.name == "Tangent")
    for name in ("__matmul__", "__rmatmul__"):
        f = next(m for m in stub.body if isinstance(m, ast.FunctionDef) and m.name == name)
        assert [a.arg for a in f.args.posonlyargs] == ["self", "dx"], f"{name}: dx must be positional-only"


def test_runtime_signatures_show_the_defaults():
    sig = inspect.signature(heml.Scene.from_toml)
    assert sig.parameters["base_dir"].default == "."
