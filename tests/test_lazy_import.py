"""``import s2cl`` is light: the public names are imported on first use (:data:`s2cl.LAZY`), each from the module
it names, and they are the same names the type checkers see."""

from __future__ import annotations

import ast
import importlib
import subprocess
import sys
from pathlib import Path

import pytest

import s2cl

INIT = Path(s2cl.__file__)


def test_import_s2cl_imports_no_engine_and_no_numpy() -> None:
    code = "import sys, s2cl; print(sorted(m for m in sys.modules if m.startswith(('s2cl', 'numpy'))))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert ast.literal_eval(out) == ["s2cl", "s2cl.errors", "s2cl.logs", "s2cl.version"]


def _type_checking_names() -> dict[str, str]:
    """name -> module of the imports under ``if TYPE_CHECKING:`` in s2cl/__init__.py (read, not imported)."""
    out = {}
    for node in ast.parse(INIT.read_text()).body:
        if isinstance(node, ast.If) and isinstance(node.test, ast.Name) and node.test.id == "TYPE_CHECKING":
            for imp in node.body:
                assert isinstance(imp, ast.ImportFrom) and imp.module
                out.update({a.name: imp.module for a in imp.names})
    return out


def test_lazy_names_are_those_type_checkers_see() -> None:
    assert s2cl.LAZY == _type_checking_names()


@pytest.mark.parametrize("name", sorted(s2cl.__all__))
def test_each_public_name_resolves_to_its_modules_object(name: str) -> None:
    module = s2cl.LAZY.get(name)
    value = getattr(s2cl, name)
    if module is not None:
        assert value is getattr(importlib.import_module(module), name)
    assert name in dir(s2cl)


def test_an_unknown_name_is_an_attribute_error_naming_it() -> None:
    with pytest.raises(AttributeError, match="'no_such_name'"):
        s2cl.no_such_name  # noqa: B018
