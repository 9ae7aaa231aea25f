# SPDX-License-Identifier: Apache-2.0
# SPDX-FileCopyrightText: 2026 ds3d authors
"""python/ds3d/_ds3d.pyi against the compiled module: the same names, the same parameter names
(from the pybind11 docstring signatures), shipped with py.typed (PEP 561)."""
import ast
import importlib.util
import pathlib

import pytest

from ds3d import _ds3d

ROOT = pathlib.Path(__file__).resolve().parents[2]
STUB = ROOT / "python" / "ds3d" / "_ds3d.pyi"
_spec = importlib.util.spec_from_file_location("gen_python_stubs",
                                               ROOT / "scripts" / "gen_python_stubs.py")
gen = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(gen)
FULL = all(hasattr(_ds3d, n) for n in ("Slam", "SparseDetector"))  # SLAM and HTx built


def _stub():
    tree = ast.parse(STUB.read_text())
    funcs, classes, names = {}, {}, set()
    for node in tree.body:
        if isinstance(node, ast.FunctionDef):
            funcs.setdefault(node.name, []).append(node)
            names.add(node.name)
        elif isinstance(node, ast.ClassDef):
            members = {}
            for item in node.body:
                if isinstance(item, ast.FunctionDef):
                    members.setdefault(item.name, []).append(item)
                elif isinstance(item, ast.AnnAssign):
                    members.setdefault(item.target.id, [])
            classes[node.name] = members
            names.add(node.name)
        elif isinstance(node, ast.AnnAssign):
            names.add(node.target.id)
    return names, funcs, classes


def _arg_names(node, method):
    a = node.args
    names = [x.arg for x in a.posonlyargs + a.args + a.kwonlyargs]
    if a.vararg:
        names.append("*" + a.vararg.arg)
    if a.kwarg:
        names.append("**" + a.kwarg.arg)
    return names[1:] if method and names[:1] == ["self"] else names


def _module_arg_names(obj, method):
    out = []
    for _, params, _ in gen.signatures(obj):
        names = [p[0] for p in params]
        out.append(names[1:] if method and names[:1] == ["self"] else names)
    return sorted(out)


def test_stub_is_shipped_and_parses():
    assert (ROOT / "python" / "ds3d" / "py.typed").exists()
    pyproject = (ROOT / "pyproject.toml").read_text()
    assert '"py.typed"' in pyproject and '"_ds3d.pyi"' in pyproject
    ast.parse(STUB.read_text())


def test_every_module_name_is_in_the_stub_and_back():
    names, _, _ = _stub()
    module = set(gen.public_names(_ds3d))
    assert module - names == set(), "missing from the stub: run scripts/gen_python_stubs.py"
    if FULL:
        assert names - module == set(), "in the stub but not in the module"


def test_parameter_names_match():
    _, funcs, classes = _stub()
    checked = 0
    for name in gen.public_names(_ds3d):
        obj = getattr(_ds3d, name)
        if isinstance(obj, type):
            members = classes[name]
            for attr, value in obj.__dict__.items():
                kind = type(value).__name__
                if kind not in ("instancemethod", "staticmethod", "property"):
                    continue
                assert attr in members, f"{name}.{attr} missing from the stub"
                if kind == "property":
                    continue
                fn = value.__func__ if kind == "staticmethod" else value
                stub = sorted(_arg_names(n, kind == "instancemethod") for n in members[attr])
                assert stub == _module_arg_names(fn, kind == "instancemethod"), f"{name}.{attr}"
                checked += 1
            if FULL:  # and nothing the class lacks
                extra = {m for m in members if m not in obj.__dict__}
                assert extra == set(), f"{name}: {extra} in the stub only"
        elif callable(obj):
            stub = sorted(_arg_names(n, False) for n in funcs[name])
            assert stub == _module_arg_names(obj, False), name
            checked += 1
    assert checked > 100


@pytest.mark.skipif(not FULL, reason="the committed stub describes the full build")
def test_stub_is_up_to_date():
    assert STUB.read_text() == gen.generate(_ds3d), "stale stub: run scripts/gen_python_stubs.py"


def test_signature_parser():
    sig = gen.parse_signature("f(a: List[int[4]], b: str = 'x, y', *, c: Optional[int] = None)"
                              " -> Tuple[int, int]")
    assert sig == ("f", [("a", "List[int[4]]", None, False), ("b", "str", "'x, y'", False),
                         ("c", "Optional[int]", "None", True)], "Tuple[int, int]")
    assert gen.annotation("numpy.ndarray[numpy.float32[m, 3], flags.c_contiguous]") == \
        "numpy.ndarray"
    assert gen.annotation("ds3d::detail::Unbound") == "Any"
