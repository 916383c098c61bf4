"""The type stubs and the module agree, and everything public has a docstring."""

import ast
import inspect
import pathlib

import heml

STUBS = pathlib.Path(heml.__file__).with_name("__init__.pyi")
STUB_ONLY = {"MaterialInfo", "StepStats"}  # TypedDicts describing returned dicts


def stub_names():
    tree = ast.parse(STUBS.read_text())
    out = {}
    for node in tree.body:
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


def test_stubs_match_the_module():
    stubs = stub_names()
    public = {n for n in heml.__all__ if not n.startswith("__")}
    assert set(stubs) - STUB_ONLY == public
    for name, members in stubs.items():
        if name in STUB_ONLY:
            continue
        obj = getattr(heml, name)
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
