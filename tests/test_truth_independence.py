"""The lab's truth is independent of the model under calibration (issue
32, acceptance 1): no truth module imports ``dampertwin.model``, directly
or through another module, and no non-trivial function body of the truth
equals one of the model's (AST comparison with names normalised)."""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

from conftest import ROOT

SRC = ROOT / "src"
TRUTH = SRC / "dampertwin" / "truth"
MODEL = SRC / "dampertwin" / "model"
# what the truth may share with the rest of the project (issue 32): the generic solver, the sensor chain, the
# excitations, the design loader (nominal values) and what those import (jit: the solver's compile-at-first-use)
ALLOWED = ("dampertwin", "dampertwin.truth", "dampertwin.solver", "dampertwin.jit", "dampertwin.sensors",
           "dampertwin.excitation", "dampertwin.design", "dampertwin.errors")
MIN_NODES = 25  # a body of fewer AST nodes is trivial (a getter, a one-line formula shared by physics itself)


def _module_name(path: Path, src: Path) -> str:
    rel = path.relative_to(src).with_suffix("")
    parts = list(rel.parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def _imports(path: Path, src: Path, nested: bool = True) -> set[str]:
    """Absolute names of the modules a file imports (relative imports
    resolved); ``nested`` False: only the imports that importing the file
    runs (module level, not inside functions)."""
    mod = _module_name(path, src)
    package = mod if path.name == "__init__.py" else mod.rpartition(".")[0]
    out = set()
    tree = ast.parse(path.read_text())
    nodes = ast.walk(tree) if nested else _module_level(tree)
    for node in nodes:
        if isinstance(node, ast.Import):
            out.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                parts = package.split(".")
                parts = parts[: len(parts) - node.level + 1]
                base = ".".join(parts + ([node.module] if node.module else []))
            out.add(base)
            out.update(f"{base}.{a.name}" for a in node.names)  # `from pkg import module`
    return out


def _module_level(tree):
    """Nodes executed on import: everything outside function bodies."""
    todo = list(tree.body)
    while todo:
        node = todo.pop()
        yield node
        if not isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda)):
            todo.extend(ast.iter_child_nodes(node))


def _file_of(name: str, src: Path) -> Path | None:
    p = src / Path(*name.split("."))
    if (p / "__init__.py").is_file():
        return p / "__init__.py"
    if p.with_suffix(".py").is_file():
        return p.with_suffix(".py")
    return None


def import_violations(package: Path, src: Path) -> list[str]:
    """Chains 'a -> b -> dampertwin.model...' from the package's modules to
    the model, and imports of project modules outside ALLOWED."""
    bad = []
    seen: set[str] = set()
    stack = [(_module_name(f, src), (_module_name(f, src),)) for f in sorted(package.rglob("*.py"))]
    stack.append(("dampertwin", ("dampertwin",)))  # importing the package runs dampertwin/__init__
    while stack:
        name, chain = stack.pop()
        if name in seen:
            continue
        seen.add(name)
        f = _file_of(name, src)
        if f is None:
            continue
        inside = f.is_relative_to(package)  # the truth's own files: every import, also inside functions
        for imp in sorted(_imports(f, src, nested=inside)):
            if not imp.startswith("dampertwin"):
                continue
            if imp == "dampertwin.model" or imp.startswith("dampertwin.model."):
                bad.append(" -> ".join(chain + (imp,)))
            elif not any(imp == a or imp.startswith(a + ".") for a in ALLOWED):
                bad.append(" -> ".join(chain + (imp,)) + " (not an allowed shared module)")
            elif _file_of(imp, src) is not None:
                stack.append((imp, chain + (imp,)))
    return bad


class _Normalise(ast.NodeTransformer):
    """Names, arguments and attributes renamed in order of appearance;
    docstrings dropped."""

    def __init__(self):
        self.names: dict[str, str] = {}

    def _n(self, s: str) -> str:
        return self.names.setdefault(s, f"v{len(self.names)}")

    def visit_Name(self, node):
        return ast.copy_location(ast.Name(id=self._n(node.id), ctx=node.ctx), node)

    def visit_arg(self, node):
        return ast.copy_location(ast.arg(arg=self._n(node.arg)), node)

    def visit_Attribute(self, node):
        self.generic_visit(node)
        node.attr = self._n(node.attr)
        return node


def _bodies(path: Path) -> list[tuple[str, str, int]]:
    """(function name, normalised dump of its arguments and body, node count)
    of every function in a file."""
    out = []
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            body = list(node.body)
            if body and isinstance(body[0], ast.Expr) and isinstance(getattr(body[0], "value", None), ast.Constant):
                body = body[1:]
            mod = ast.Module(body=[ast.arguments(posonlyargs=[], args=node.args.args, kwonlyargs=[], kw_defaults=[],
                                                 defaults=[])] + body, type_ignores=[])
            norm = _Normalise().visit(ast.parse(ast.unparse(mod)) if False else mod)
            n = sum(1 for _ in ast.walk(ast.Module(body=body, type_ignores=[])))
            out.append((node.name, ast.dump(norm, annotate_fields=False), n))
    return out


def copied_bodies(package: Path, model: Path) -> list[str]:
    """'truth_file:function == model_file:function' for every non-trivial
    function body of the package equal (normalised) to one of the model's."""
    theirs = {}
    for f in sorted(model.rglob("*.py")):
        for name, dump, _ in _bodies(f):
            theirs.setdefault(dump, f"{f.name}:{name}")
    hits = []
    for f in sorted(package.rglob("*.py")):
        for name, dump, n in _bodies(f):
            if n >= MIN_NODES and dump in theirs:
                hits.append(f"{f.name}:{name} == {theirs[dump]}")
    return hits


def test_truth_never_imports_the_model():
    assert import_violations(TRUTH, SRC) == []


def test_truth_copies_no_function_body_of_the_model():
    assert copied_bodies(TRUTH, MODEL) == []


def test_importing_and_running_the_truth_loads_no_model_module():
    code = ("import sys, dampertwin.truth.run, dampertwin.truth.damper, dampertwin.truth.params;"
            "bad = [m for m in sys.modules if m.startswith('dampertwin.model')]; print(bad); sys.exit(1 if bad else 0)")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT,
                       env={"PYTHONPATH": str(SRC), "PATH": "/usr/bin:/bin"})
    assert r.returncode == 0, r.stdout + r.stderr


def _plant(tmp_path: Path, extra: str, file: str = "fluid.py") -> Path:
    """A copy of the truth package with ``extra`` appended to one module."""
    import shutil

    src = tmp_path / "src"
    shutil.copytree(SRC / "dampertwin", src / "dampertwin")
    (src / "dampertwin" / "truth" / file).write_text((TRUTH / file).read_text() + "\n" + extra)
    return src


def test_checks_catch_a_planted_model_import_and_a_copied_body(tmp_path):
    """The checkers are not vacuous: a direct import, an import through a
    non-allowed module, and a renamed copy of a model function are found."""
    src = _plant(tmp_path, "from ..model import layout as _l\n")
    assert any("dampertwin.model" in v for v in import_violations(src / "dampertwin" / "truth", src))
    src = _plant(tmp_path / "b", "from ..simulation import simulate as _s\n")
    hits = import_violations(src / "dampertwin" / "truth", src)
    assert any("dampertwin.simulation" in v for v in hits)
    # a model function copied with every name changed
    tree = ast.parse((MODEL / "valves.py").read_text())
    fn = max((n for n in tree.body if isinstance(n, ast.FunctionDef)), key=lambda n: len(ast.dump(n)))
    renamed = _Normalise().visit(fn)
    renamed.name = "innocent"
    src = _plant(tmp_path / "c", ast.unparse(renamed))
    assert copied_bodies(src / "dampertwin" / "truth", MODEL)
