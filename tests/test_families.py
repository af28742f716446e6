"""The analysis families are registered objects: every kind resolves to one, nothing outside the families branches on
a kind, and the formula family lives in four files (the count the architecture page states)."""

from __future__ import annotations

import ast
import re
from dataclasses import dataclass
from pathlib import Path

import pytest

from s2cl.errors import InputError
from s2cl.retrieve.family import Family, family_of, registry
from s2cl.retrieve.indices import INDICES
from s2cl.retrieve.metric import CLASSIFICATION, METRICS, REGRESSION, Metric, metric_in, metric_scored_by

ROOT = Path(__file__).resolve().parents[1]
FAMILIES = ROOT / "s2cl" / "retrieve" / "families"
#: the files of the formula family, outside tests and docs
FORMULA_FILES = {"s2cl/retrieve/families/formula.py", "s2cl/retrieve/families/formula_syntax.py",
                 "kernels/formula.cl.mako", "s2cl/scene/analysis_schema.py"}  # [analysis] expression


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
        assert family.metric in METRICS
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



def _compared(node: ast.Compare) -> tuple[set, set]:
    """The names (attributes or variables) and the string literals (alone or in a literal tuple, list or set) on
    the sides of a comparison."""
    sides = [node.left, *node.comparators]
    names = {s.attr if isinstance(s, ast.Attribute) else getattr(s, "id", None) for s in sides}
    literal = {s.value for s in sides if isinstance(s, ast.Constant) and isinstance(s.value, str)}
    literal |= {e.value for s in sides if isinstance(s, (ast.Tuple, ast.List, ast.Set)) for e in s.elts
                if isinstance(e, ast.Constant)}
    return names, literal

def _kind_branches(path: Path) -> list[str]:
    """``x.kind == "sam"``-style comparisons and ``kind in INDICES`` tests in a Python file."""
    kinds = set(registry())
    found = []
    for node in ast.walk(ast.parse(path.read_text())):
        if not isinstance(node, ast.Compare):
            continue
        names, literal = _compared(node)
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


def test_each_family_resolves_to_its_metric() -> None:
    """Written out by hand: SAM classifies (ranked on the mean omission error), every other kind is regressed on a
    library parameter (ranked on the RMS); the settings and the score column follow the metric."""
    for kind, family in registry().items():
        expected = CLASSIFICATION if kind == "sam" else REGRESSION
        assert family.metric is expected, kind
        assert family.score_column == {"sam": "omission_error_pct"}.get(kind, "rms")
    assert metric_scored_by("rms") is REGRESSION and metric_scored_by("omission_error_pct") is CLASSIFICATION
    assert metric_scored_by("r2") is None
    assert metric_in(["config", "omission_error_pct", "failed_fraction"]) is CLASSIFICATION
    assert metric_in(["config", "rms", "r2"]) is REGRESSION and metric_in(["config"]) is REGRESSION
    assert {m.name for m in METRICS} == {"regression", "classification"}
    assert len({m.score_column for m in METRICS}) == len(METRICS)


#: what only the metric module may compare against: the metrics' names and score columns
_METRIC_WORDS = {"regression", "classification", "rms", "omission_error_pct"}


def _metric_branches(source: str, label: str) -> list[str]:
    """Comparisons that choose between metrics instead of asking one: ``x.metric == ...`` (``!=``, ``is``), or a
    metric's name or score column compared as a string (``== "rms"``, ``in ("regression", ...)``). A key looked up
    in a result (``"rms" in row``) is no choice."""
    found = []
    choosing = (ast.Eq, ast.NotEq, ast.Is, ast.IsNot)
    for node in ast.walk(ast.parse(source)):
        if not isinstance(node, ast.Compare):
            continue
        literal_set = any(isinstance(op, (ast.In, ast.NotIn)) and isinstance(c, (ast.Tuple, ast.List, ast.Set))
                          for op, c in zip(node.ops, node.comparators, strict=True))
        if not (literal_set or any(isinstance(op, choosing) for op in node.ops)):
            continue
        names, literal = _compared(node)
        if "metric" in names or literal & _METRIC_WORDS:
            found.append(f"{label}:{node.lineno}")
    return found


def test_no_code_outside_the_metric_module_chooses_a_metric() -> None:
    """Regression versus classification is asked of the family's :class:`Metric`, never decided by comparing
    names (the numpy twins in reference/ excepted: they are the independent check)."""
    skip = {ROOT / "s2cl" / "retrieve" / "metric.py"}
    offenders = [hit for p in sorted((ROOT / "s2cl").rglob("*.py")) if p not in skip and "reference" not in p.parts
                 for hit in _metric_branches(p.read_text(), str(p.relative_to(ROOT)))]
    assert not offenders, offenders


def test_the_metric_branch_finder_finds_a_branch() -> None:
    """The finder above is not blind: each way of choosing is caught, asking is not."""
    source = ('a = f.metric == "regression"\nb = m == "rms"\nc = k in ("classification", "x")\n'
              'd = family.metric is REGRESSION\ne = family.metric.classifies\nf = metric_in(cols).score_column\n')
    assert _metric_branches(source, "probe") == ["probe:1", "probe:2", "probe:3", "probe:4"]


def test_a_new_metric_is_asked_not_branched_on() -> None:
    """A third metric (written here, not registered) works through what the code asks of a metric: its score
    column, its columns and its bootstrap, without any code that names it."""
    import numpy as np

    @dataclass(frozen=True)
    class Worst(Metric):
        def score(self, sums: np.ndarray) -> np.ndarray:
            return np.max(sums, axis=-1)

    worst = Worst(name="worst", score_column="worst_error", columns=("worst_error", "host"),
                  ranking_columns=(("failed_fraction", "failed_fraction", ".2%"),), regressed=True,
                  stratified=False, pixel_scratch=False)
    assert worst.kernel_name == "worst_metrics" and not worst.classifies
    assert metric_in(["worst_error"]) is REGRESSION  # unregistered: a results table falls back to the RMS
    np.testing.assert_array_equal(worst.score(np.array([[1.0, 3.0, 2.0]])), [3.0])
