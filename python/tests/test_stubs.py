"""The type stubs (incise/_incise.pyi) name exactly what the compiled module has, and mypy
(Debian's) accepts the package and the examples against them."""

import ast
import inspect
import pathlib
import shutil
import subprocess
import sys

import pytest

import incise
from incise import _incise

STUB = pathlib.Path(incise.__file__).with_name("_incise.pyi")


def _stub_names():
    tree = ast.parse(STUB.read_text())
    names = {}
    for node in tree.body:
        if isinstance(node, ast.ClassDef):
            members = set()
            for item in node.body:
                if isinstance(item, (ast.FunctionDef, ast.AsyncFunctionDef)):
                    members.add(item.name)
                elif isinstance(item, ast.AnnAssign) and isinstance(item.target, ast.Name):
                    members.add(item.target.id)
            names[node.name] = members
        elif isinstance(node, ast.FunctionDef):
            names[node.name] = None
    return names


def test_the_stub_names_what_the_module_has():
    stub = _stub_names()
    runtime = {name for name in dir(_incise) if not name.startswith("__")}
    assert set(stub) - {"PathLike", "ArrayLike", "Point"} == runtime
    for name, members in stub.items():
        if members is None or not inspect.isclass(getattr(_incise, name)):
            continue
        cls = getattr(_incise, name)
        if issubclass(cls, BaseException):
            continue
        have = {m for m in vars(cls) if not m.startswith("_")} | {"__init__"} & set(vars(cls))
        have |= {"to_meshio", "from_meshio", "fix_slivers"} if name == "Mesh" else set()
        assert members - {"__init__"} == have - {"__init__"}, name


@pytest.mark.skipif(shutil.which("mypy") is None, reason="mypy (Debian's) is not installed")
def test_mypy_accepts_the_package_and_the_examples(source_dir):
    package = pathlib.Path(incise.__file__).parent
    result = subprocess.run(
        [sys.executable, "-m", "mypy", "--ignore-missing-imports", "--no-error-summary",
         "--cache-dir", "/dev/null", str(package), str(source_dir / "examples" / "python")],
        capture_output=True, text=True)
    assert result.returncode == 0, result.stdout + result.stderr
