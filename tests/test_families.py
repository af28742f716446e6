"""The analysis families are registered objects: every kind resolves to one, nothing outside the families branches on
a kind, and the formula family lives in four files (the count the architecture page states)."""

from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

from s2cl.errors import InputError
from s2cl.retrieve.family import Family, family_of, registry
from s2cl.retrieve.indices import INDICES

ROOT = Path(__file__).resolve().parents[1]
FAMILIES = ROOT / "s2cl" / "retrieve" / "families"
#: the files of the formula family, outside tests and docs
FORMULA_FILES = {"s2cl/retrieve/families/formula.py", "s2cl/retrieve/families/formula_syntax.py",
                 "kernels/formula.cl.mako", "s2cl/scene/schema.py"}


def _product_files() -> list[Path]:
    return sorted([*(ROOT / "s2cl").rglob("*.py"), *(ROOT / "kernels").rglob("*.mako")])


def _code_words(path: Path) -> set[str]:
    """Identifiers, attribute names, imported modules and the dotted or snake_case words of string constants
    (module paths, device function names; docstrings and comments left out) of a Python file; the words outside
    comments and ``<%doc>`` blocks of a template."""
    text = path.read_text()
    if path.suffix == ".mako":
        code = re.sub(r"<%doc>.*?</%doc>|/\*.*?\*/|//[^\n]*", "", text, flags=re.S)
        return set(re.findall(r"[A-Za-z_][A-Za-z0-9_.]*", code))
    tree = ast.parse(text)
    docstrings = {id(node.body[0].value) for node in ast.walk(tree)
                  if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef))
                  and node.body and isinstance(node.body[0], ast.Expr) and isinstance(node.body[0].value, ast.Constant)}
    words: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Name):
            words.add(node.id)
        elif isinstance(node, ast.Attribute):
            words.add(node.attr)
        elif isinstance(node, ast.ImportFrom) and node.module:
            words.add(node.module)
        elif isinstance(node, ast.Constant) and isinstance(node.value, str) and id(node) not in docstrings:
            words.update(w for w in re.findall(r"[A-Za-z_][A-Za-z0-9_.:]*", node.value) if "." in w or "_" in w)
    return words


def test_every_kind_has_its_family() -> None:
    kinds = registry()
    assert {"igrm", "sam", "formula", *INDICES} == set(kinds)
    for kind, family in kinds.items():
        assert isinstance(family, Family) and kind in family.kinds()
        assert family.metric in ("regression", "classification")
        module, name = family.twin.split(":")
        assert module.startswith("s2cl.") and name.isidentifier()
    with pytest.raises(InputError, match=r"unknown analysis kind 'ndwi'; known: .*formula") as err:
        family_of("ndwi")
    assert err.value.key == "analysis.kind"


def test_the_formula_family_touches_four_files() -> None:
    touching = {str(p.relative_to(ROOT)) for p in FAMILIES.glob("formula*.py")}  # the family's own modules
    touching |= {str(p.relative_to(ROOT)) for p in _product_files()
                if any(re.search(r"(^|[._:])formula($|[._s])", w.lower()) or w == "expression" for w in _code_words(p))}
    assert touching == FORMULA_FILES, sorted(touching ^ FORMULA_FILES)


def _kind_branches(path: Path) -> list[str]:
    """``x.kind == "sam"``-style comparisons and ``kind in INDICES`` tests in a Python file."""
    kinds = set(registry())
    found = []
    for node in ast.walk(ast.parse(path.read_text())):
        if not isinstance(node, ast.Compare):
            continue
        sides = [node.left, *node.comparators]
        names = {s.attr if isinstance(s, ast.Attribute) else getattr(s, "id", None) for s in sides}
        literal = {s.value for s in sides if isinstance(s, ast.Constant) and isinstance(s.value, str)}
        literal |= {e.value for s in sides if isinstance(s, (ast.Tuple, ast.List, ast.Set)) for e in s.elts
                    if isinstance(e, ast.Constant)}
        if ("kind" in names and literal & kinds) or "INDICES" in names:
            found.append(f"{path.relative_to(ROOT)}:{node.lineno}")
    return found


def test_no_code_outside_the_families_branches_on_a_kind() -> None:
    offenders = [hit for p in sorted((ROOT / "s2cl").rglob("*.py")) if FAMILIES not in p.parents
                 for hit in _kind_branches(p)]
    assert not offenders, offenders


def test_the_sweep_kernel_holds_only_its_family_code() -> None:
    from s2cl.cl.vectypes import VecTypes
    from s2cl.retrieve.analysis import AnalysisSettings
    from s2cl.retrieve.family import SweepContext

    ctx = SweepContext(("B4", "B5", "B6", "B7"), (2, 2, 2, 2), (8, 4, 2, 1), (0, 2, 4, 6), 3, 2.0)
    T = VecTypes("float32", 4)
    formula = AnalysisSettings("formula", "cab", slots=(0, 1, 2), options=(("expression", "(B7 - B4) / B5"),))
    settings = {"igrm": AnalysisSettings("igrm", "cab"), "gvmi": AnalysisSettings("gvmi", "ewt"),
                "sam": AnalysisSettings("sam"), "formula": formula}
    code = {kind: "".join(registry()[kind].sweep_code(s, T, ctx)) for kind, s in settings.items()}
    marks = {"igrm": "s2_igrm_fit_sweep", "gvmi": "s2_gvmi_", "sam": "s2_sam_", "formula": "s2_formula_"}
    for kind, text in code.items():
        assert [k for k, mark in marks.items() if mark in text] == [kind], kind
        assert all(f"{v} =" in text or f"{v}," in text or f"{v};" in text for v in ("value", "st", "bd", "code")), kind
