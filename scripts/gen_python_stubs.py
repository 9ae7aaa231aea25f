#!/usr/bin/env python3
# SPDX-License-Identifier: Apache-2.0
# SPDX-FileCopyrightText: 2026 ds3d authors
"""Writes python/ds3d/_ds3d.pyi, the type stub of the compiled module, from its pybind11
docstring signatures (no pybind11-stubgen needed).

    PYTHONPATH=build/python /usr/bin/python3 scripts/gen_python_stubs.py          # rewrite
    PYTHONPATH=build/python /usr/bin/python3 scripts/gen_python_stubs.py --check  # exit 1 if stale

python/tests/stubs_test.py checks the committed stub against the module with the same parser.
Types that are not valid Python annotations (C++ names of unbound types) become ``Any``; numpy
shapes and dtypes are kept in a comment-free form (``numpy.ndarray``).
"""
import argparse
import ast
import importlib
import pathlib
import re
import sys

ROOT = pathlib.Path(__file__).resolve().parents[1]
STUB = ROOT / "python" / "ds3d" / "_ds3d.pyi"
_OPEN, _CLOSE = "([{", ")]}"
_BOUND = set()  # class names of the module being written


def split_top(text, sep=","):
    """Splits at `sep` outside brackets and quotes."""
    parts, depth, quote, cur = [], 0, None, ""
    for ch in text:
        if quote:
            quote = None if ch == quote else quote
        elif ch in "'\"":
            quote = ch
        elif ch in _OPEN:
            depth += 1
        elif ch in _CLOSE:
            depth -= 1
        elif ch == sep and depth == 0:
            parts.append(cur)
            cur = ""
            continue
        cur += ch
    if cur.strip():
        parts.append(cur)
    return [p.strip() for p in parts]


def parse_signature(line):
    """'name(a: T, b: U = 1, *, c: V = 2) -> R' -> (name, [(name, type, default, kw_only)], R)
    with default the text of the default value or None.
    None when the line is not a signature."""
    m = re.match(r"^\s*(?:\d+\.\s+)?([A-Za-z_]\w*)?\((.*)\)(?:\s*->\s*(.+))?\s*$", line)
    if not m:
        return None
    name, body, ret = m.group(1) or "", m.group(2), m.group(3) or "None"
    params, kw_only = [], False
    for p in split_top(body):
        if p == "*":
            kw_only = True
            continue
        if p.startswith("**") or p.startswith("*"):
            params.append((p.split(":")[0], "Any", None, False))
            continue
        pieces = split_top(p, "=")
        head, default = pieces[0], (pieces[1] if len(pieces) > 1 else None)
        pname, _, ann = head.partition(":")
        params.append((pname.strip(), ann.strip() or "Any", default, kw_only))
    return name, params, ret.strip()


def signatures(obj):
    """Every signature of a pybind11 function (one per overload)."""
    doc = getattr(obj, "__doc__", None) or ""
    lines = doc.splitlines()
    if len(lines) > 1 and lines[1].strip() == "Overloaded function.":
        return [s for s in (parse_signature(line) for line in lines[2:]
                            if re.match(r"^\d+\. ", line)) if s]
    first = parse_signature(lines[0]) if lines else None
    return [first] if first else []


def _drop_brackets(text, opener):
    """'numpy.ndarray[numpy.float32[m, 3]]' -> 'numpy.ndarray' (the subscript dropped)."""
    while opener in text:
        start = text.index(opener)
        depth, i = 0, start + len(opener) - 1
        for i in range(i, len(text)):
            depth += text[i] == "["
            depth -= text[i] == "]"
            if depth == 0:
                break
        text = text[:start] + opener[:-1] + text[i + 1:]
    return text


def annotation(text):
    """A pybind11 type name as a valid annotation."""
    t = text.replace("ds3d._ds3d.", "")
    t = _drop_brackets(t, "numpy.ndarray[")
    t = re.sub(r"\b(int|float|bool|str)\[\d+\]", r"\1", t)
    t = t.replace("os.PathLike", "os.PathLike[str]")
    # C++ names of types bound after the function (registration order): the Python class of
    # the same name when there is one.
    t = re.sub(r"\b(?:\w+::)+(\w+)", lambda m: m.group(1) if m.group(1) in _BOUND else m.group(0),
               t)
    try:
        ast.parse(t, mode="eval")
    except SyntaxError:
        return "Any"
    if re.search(r"\b(std|cv|Eigen|ds3d)::", t):
        return "Any"
    return t


def _def(sig, indent, decorators=(), method=False):
    name, params, ret = sig
    out, kw_started = [], False
    for i, (pname, ann, default, kw_only) in enumerate(params):
        if method and i == 0 and pname == "self":
            out.append("self")
            continue
        if kw_only and not kw_started:
            out.append("*")
            kw_started = True
        if pname.startswith("*"):
            out.append(pname)
            continue
        ann = annotation(ann)
        if default == "None" and not ann.startswith("Optional[") and ann not in ("object", "Any"):
            ann = f"Optional[{ann}]"
        out.append(f"{pname}: {ann}" + ("" if default is None else " = ..."))
    lines = [f"{indent}@{d}" for d in decorators]
    lines.append(f"{indent}def {name}({', '.join(out)}) -> {annotation(ret)}: ...")
    return lines


def _function(name, obj, indent="", method=False, static=False):
    sigs = signatures(obj)
    if not sigs:
        sigs = [(name, [("self", "Any", None, False)] if method else [], "Any")]
        sigs[0][1].extend([("*args", "Any", None, False), ("**kwargs", "Any", None, False)])
    lines = []
    for s in sigs:
        deco = (["staticmethod"] if static else []) + (["overload"] if len(sigs) > 1 else [])
        lines += _def((name,) + s[1:], indent, deco, method=method and not static)
    return lines


def _class(name, cls, module):
    bases = [b.__name__ for b in cls.__bases__ if getattr(module, b.__name__, None) is b]
    lines = [f"class {name}({', '.join(bases)}):" if bases else f"class {name}:"]
    body = []
    for attr, value in cls.__dict__.items():
        if attr in ("__doc__", "__module__", "__dict__", "__weakref__", "__entries",
                    "__members__") or attr.startswith("_pybind11"):
            continue
        kind = type(value).__name__
        if isinstance(value, cls):  # enum members
            body.append(f"    {attr}: {name}")
        elif kind == "instancemethod":
            body += _function(attr, value, "    ", method=True)
        elif kind == "staticmethod":
            body += _function(attr, value.__func__, "    ", static=True)
        elif kind == "property":
            sig = signatures(value.fget) if value.fget else []
            ann = annotation(sig[0][2]) if sig else "Any"
            body.append("    @property")
            body.append(f"    def {attr}(self) -> {ann}: ...")
            if value.fset is not None:
                body.append(f"    @{attr}.setter")
                body.append(f"    def {attr}(self, value: {ann}) -> None: ...")
    return lines + (body or ["    ..."])


def public_names(module):
    """Every name of the module a stub must hold (all but dunders and imported modules)."""
    return sorted(n for n in dir(module) if not (n.startswith("__") and n.endswith("__"))
                  or n == "__version__")


def generate(module):
    _BOUND.clear()
    _BOUND.update(n for n in dir(module) if isinstance(getattr(module, n), type))
    out = ["# SPDX-License-Identifier: Apache-2.0",
           "# SPDX-FileCopyrightText: 2026 ds3d authors",
           "# Type stub of the compiled module ds3d._ds3d, written by scripts/gen_python_stubs.py",
           "# from its pybind11 signatures; python/tests/stubs_test.py keeps it in sync.",
           "import os",
           "from typing import Any, Callable, Dict, Iterator, List, Optional, Tuple, overload",
           "",
           "import numpy", ""]
    for name in public_names(module):
        obj = getattr(module, name)
        if name == "__version__":
            out.append("__version__: str")
        elif isinstance(obj, type):
            out += [""] + _class(name, obj, module) + [""]
        elif callable(obj):
            out += _function(name, obj)
        else:
            out.append(f"{name}: {type(obj).__name__}")
    return "\n".join(out).rstrip() + "\n"


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--check", action="store_true", help="exit 1 when the stub is stale")
    ap.add_argument("--out", type=pathlib.Path, default=STUB)
    args = ap.parse_args()
    text = generate(importlib.import_module("ds3d._ds3d"))
    if args.check:
        same = args.out.exists() and args.out.read_text() == text
        print(f"{args.out}: {'up to date' if same else 'stale: run ' + sys.argv[0]}")
        return 0 if same else 1
    args.out.write_text(text)
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
