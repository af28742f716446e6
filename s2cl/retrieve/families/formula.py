"""A retrieval written as a formula of band reflectances: ``705 + 35 * ((B4 + B7) / 2 - B5) / (B6 - B5)`` (S2REP,
Frampton et al. 2013), parsed safely (:mod:`s2cl.retrieve.families.formula_syntax`: the grammar and its errors).

The whole analysis family (:class:`FormulaFamily`, registered as ``kind = "formula"``): a scene selects it with
``[analysis] kind = "formula"``, ``expression = "..."`` and ``parameter = "..."`` (the library parameter it is
regressed on); the design rule uses :meth:`Formula.subtracted_pairs` and :meth:`Formula.divided_pairs`, ``simulate``
runs :class:`FormulaKernel` (``kernels/formula.cl.mako``), the sweep kernel splices :meth:`Formula.device_source`,
and :func:`twin` is the float64 numpy twin.

Validity, one rule for the kernel and the float64 numpy twin: status INVALID and value 0 when a band is not
finite or |ρ| > ``max_abs``, a denominator is 0, sqrt has a negative or log a non-positive argument, or an
intermediate result is not finite or exceeds :data:`LIMIT` (1e30) in magnitude (inside float32's range, so both
precisions give one verdict). Reflectances are unitless; the value has the formula's unit (S2REP: nm).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np

from s2cl.cl.kernel_args import Arg, bind, signature
from s2cl.cl.runtime import Runtime, get_runtime
from s2cl.cl.templates import render
from s2cl.cl.vectypes import VecTypes, pad_pixels
from s2cl.errors import InputError
from s2cl.retrieve.analysis import AnalysisSettings
from s2cl.retrieve.design import same_band
from s2cl.retrieve.families.formula_syntax import (
    KEY,
    LIMIT,
    Band,
    Binary,
    Negate,
    Node,
    Number,
    bands_of,
    children,
    parse_expression,
    rename,
    to_text,
)
from s2cl.retrieve.family import Family, Outcome, SweepContext
from s2cl.status import MAX_ABS_REFLECTANCE, Status

__all__ = ["FAMILY", "KEY", "LIMIT", "Band", "Binary", "Formula", "FormulaKernel", "Negate", "Node", "Number"]

#: each operation in numpy and in OpenCL C ("neg": unary minus)
_NUMPY = {"+": np.add, "-": np.subtract, "*": np.multiply, "/": np.divide, "neg": np.negative, "sqrt": np.sqrt,
          "log": np.log, "exp": np.exp, "abs": np.abs, "min": np.fmin, "max": np.fmax}
_OPENCL = {"+": "{} + {}", "-": "{} - {}", "*": "{} * {}", "/": "{} / {}", "neg": "-{}", "sqrt": "sqrt({})",
           "log": "log({})", "exp": "exp({})", "abs": "fabs({})", "min": "fmin({}, {})", "max": "fmax({}, {})"}
#: domain guard of an operation's last argument: comparison with 0, and the value used where it fails
_GUARDS = {"/": (np.not_equal, "!=", 1.0), "sqrt": (np.greater_equal, ">=", 0.0), "log": (np.greater, ">", 1.0)}


class _Step(NamedTuple):
    op: str  #: "band", "num", or a key of _NUMPY
    args: tuple[int, ...] = ()  #: steps whose results it takes
    value: float = 0.0  #: num: the constant; band: its position in Formula.bands


@dataclass(frozen=True)
class Formula:
    """A parsed formula: ``text`` as written, ``root`` its AST, ``bands`` the bands it names (first use first)."""

    text: str
    root: Node
    bands: tuple[str, ...]

    @classmethod
    def parse(cls, text: str, bands: Sequence[str]) -> Formula:
        """``text`` parsed against the allowed band names; :class:`InputError` (key ``analysis.expression``,
        one line naming the 1-based column) when it is not a formula of them."""
        root = parse_expression(text, bands)
        return cls(text, root, tuple(dict.fromkeys(bands_of(root))))

    def __str__(self) -> str:
        return to_text(self.root)

    def subtracted_pairs(self) -> tuple[tuple[str, str], ...]:
        """Band pairs (X, Y) of every subtraction ``L - R`` whose sides each name one band, X and Y, and are the
        same expression apart from it (``B6 - B5``, ``log(B6) - log(B5)``): the difference vanishes when X and
        Y are one band. In order of appearance, without repeats."""
        return self._pairs("-")

    def divided_pairs(self) -> tuple[tuple[str, str], ...]:
        """As :meth:`subtracted_pairs` for divisions ``L / R`` (``B7 / B5``): the ratio is 1 when X and Y are one
        band."""
        return self._pairs("/")

    def _pairs(self, op: str) -> tuple[tuple[str, str], ...]:
        out: dict[tuple[str, str], None] = {}

        def walk(node: Node) -> None:
            if isinstance(node, Binary) and node.op == op:
                left, right = set(bands_of(node.left)), set(bands_of(node.right))
                if len(left) == len(right) == 1 and left != right:
                    (x,), (y,) = left, right
                    if rename(node.right, y, x) == node.left:
                        out[(x, y)] = None
            for child in children(node):
                walk(child)

        walk(self.root)
        return tuple(out)

    def _steps(self) -> list[_Step]:
        """The AST as straight-line steps, post-order (the root last; equal subexpressions computed once)."""
        steps: list[_Step] = []
        seen: dict[Node, int] = {}

        def lower(node: Node) -> int:
            if node not in seen:
                args = tuple(lower(child) for child in children(node))
                if isinstance(node, Number):
                    steps.append(_Step("num", value=node.value))
                elif isinstance(node, Band):
                    steps.append(_Step("band", value=float(self.bands.index(node.name))))
                else:
                    op = "neg" if isinstance(node, Negate) else node.op if isinstance(node, Binary) else node.func
                    steps.append(_Step(op, args))
                seen[node] = len(steps) - 1
            return seen[node]

        lower(self.root)
        return steps

    def evaluate(self, values: Mapping[str, np.ndarray], max_abs: float = MAX_ABS_REFLECTANCE
                 ) -> tuple[np.ndarray, np.ndarray]:
        """float64 numpy twin of :meth:`device_source`: the value (0 where invalid, never NaN) and the status
        (uint8, :class:`~s2cl.status.Status`) per pixel, from each band's reflectance (arrays that broadcast)."""
        missing = [b for b in self.bands if b not in values]
        if missing:
            raise InputError(f"no reflectance for band(s) {', '.join(missing)}", key=KEY)
        rho = [np.asarray(values[b], dtype=np.float64) for b in self.bands]
        shape = np.broadcast_shapes(*(r.shape for r in rho))
        ok = np.ones(shape, dtype=bool)
        t: list[np.ndarray] = []
        with np.errstate(all="ignore"):
            for r in rho:
                ok &= np.abs(r) <= max_abs
            for step in self._steps():
                if step.op in ("num", "band"):
                    t.append(np.float64(step.value) if step.op == "num" else rho[int(step.value)])
                    continue
                x = [t[i] for i in step.args]
                if step.op in _GUARDS:
                    good, _, safe = _GUARDS[step.op]
                    good = good(x[-1], 0.0)
                    ok &= good
                    x[-1] = np.where(good, x[-1], safe)
                t.append(_NUMPY[step.op](*x))
                ok &= np.abs(t[-1]) <= LIMIT
            value = np.where(ok, t[-1], 0.0)
        return np.broadcast_to(value, shape).copy(), np.where(ok, Status.OK, Status.INVALID).astype(np.uint8)

    def device_source(self, T: VecTypes, max_abs: float = MAX_ABS_REFLECTANCE) -> str:
        """OpenCL C of ``V s2_formula_<T.suffix>(const V b0, ..., M *status)`` (one argument per band of
        :attr:`bands`, in that order): the value and status of :meth:`evaluate`, lanes independent."""
        V, M, sfx = T.V, T.M, T.suffix
        body = [f"{M} ok = " + " & ".join(f"(b{i} <= {T.vlit(max_abs)}) & (b{i} >= {T.vlit(-max_abs)})"
                                        for i in range(len(self.bands))) + ";"]
        names: list[str] = []
        for k, step in enumerate(self._steps()):
            if step.op in ("num", "band"):
                names.append(T.vlit(step.value) if step.op == "num" else f"b{int(step.value)}")
                continue
            x = [names[i] for i in step.args]
            if step.op in _GUARDS:
                _, cmp, safe = _GUARDS[step.op]
                body += [f"const {M} g{k} = {x[-1]} {cmp} {T.vlit(0.0)};", f"ok = ok & g{k};"]
                x[-1] = f"(g{k} ? {x[-1]} : {T.vlit(safe)})"
            body += [f"const {V} t{k} = {_OPENCL[step.op].format(*x)};",
                     f"ok = ok & (t{k} <= {T.vlit(LIMIT)}) & (t{k} >= {T.vlit(-LIMIT)});"]
            names.append(f"t{k}")
        params = ", ".join(f"const {V} b{i}" for i in range(len(self.bands)))
        guard, lines = f"S2_FORMULA_{sfx.upper()}", "\n    ".join(body)
        return (f'#include "common/s2_status.clh"\n#ifndef {guard}\n#define {guard}\n'
                f"/* {self} ({', '.join(f'b{i} = {b}' for i, b in enumerate(self.bands))}) */\n"
                f"static inline {V} s2_formula_{sfx}({params}, {M} *status)\n{{\n    {lines}\n"
                f"    *status = ok ? (({M})(S2_OK)) : (({M})(S2_INVALID));\n"
                f"    return ok ? {names[-1]} : {T.vlit(0.0)};\n}}\n#endif\n")


class FormulaResult(NamedTuple):
    """``value`` (n_pixels,) in the working precision, in the formula's unit, and ``status`` (uint8)."""

    value: np.ndarray
    status: np.ndarray


#: the kernel's arguments (kernels/formula.cl.mako), in order
ARGS = (Arg("value", "out", "real"), Arg("status", "out", "uchar"), Arg("refl", "in", "real"),
        Arg("pitch", "scalar", "int"))


class FormulaKernel:
    """Compiled ``formula`` for one device, precision and lane count.

    :param rt: the OpenCL runtime to run on.
    :param formula: a parsed :class:`~s2cl.retrieve.families.formula.Formula`.
    :param real_t: ``"float32"`` or ``"float64"``.
    :param lanes: pixels per work-item (default: :meth:`Runtime.lanes`).
    :param max_abs: |reflectance| above which a pixel is invalid.
    """

    def __init__(self, rt: Runtime, formula: Formula, real_t: str = "float32", lanes: int | None = None, *,
                 max_abs: float = MAX_ABS_REFLECTANCE):
        self.rt, self.formula = rt, formula
        self.types = rt.types(real_t, lanes)
        source = render("formula.cl.mako", T=self.types, formula=formula, max_abs=float(max_abs), args=ARGS,
                        signature=signature)
        self.kernel = rt.kernel(rt.build(source, template="formula.cl.mako"), "formula")

    def __call__(self, refl: np.ndarray, rows: Sequence[int] | None = None) -> FormulaResult:
        """The formula per pixel of ``refl`` (n_rows, n_pixels); ``rows[i]`` is the row of ``formula.bands[i]``
        (default: the rows are the formula's bands, in order)."""
        refl = np.asarray(refl)
        n_bands = len(self.formula.bands)
        rows = list(range(n_bands)) if rows is None else [int(r) for r in rows]
        if refl.ndim != 2:
            raise InputError(f"must have shape (n_bands, n_pixels), got {refl.shape}", key="reflectance")
        if len(rows) != n_bands or not all(0 <= r < refl.shape[0] for r in rows):
            raise InputError(f"needs one row in 0..{refl.shape[0] - 1} for each of the bands "
                             f"{', '.join(self.formula.bands)}, got {rows}", key="reflectance")
        n = refl.shape[1]
        T, rt = self.types, self.rt
        host, pitch = pad_pixels(refl[rows], T.lanes, T.dtype)
        (value, value_d), (status, status_d) = rt.output((pitch,), T.dtype), rt.output((pitch,), np.uint8)
        values = {"value": value_d, "status": status_d, "refl": rt.upload_new(host), "pitch": pitch}
        self.kernel(rt.queue, (pitch // T.lanes,), rt.local_size(self.kernel, pitch // T.lanes), *bind(ARGS, values, T))
        return FormulaResult(rt.result(value_d, value)[:n], rt.result(status_d, status)[:n])


def formula_values(refl: np.ndarray, formula: Formula, rows: Sequence[int] | None = None, *, real_t: str = "float32",
                   device: str | None = None, **kwargs) -> FormulaResult:
    """One-shot :class:`FormulaKernel` on ``device`` (default: :func:`s2cl.cl.runtime.get_runtime`'s choice)."""
    return FormulaKernel(get_runtime(device), formula, real_t=real_t, **kwargs)(refl, rows)


class FormulaFamily(Family):
    """``kind = "formula"``: your own retrieval, ``[analysis] expression = "..."``, regressed on ``parameter``.
    Its bands are the bands the expression names; a design in which the two bands of a difference or a ratio it
    takes coincide is underdetermined (0, or 1, for every pixel)."""

    kind = "formula"
    keys = ("expression",)
    twin = "s2cl.retrieve.families.formula:twin"

    def default_bands(self, spec: Any, band_names: Sequence[str]) -> list[str]:
        return list(_parse(spec, band_names, None).bands)

    def settings(self, spec: Any, bands: list[str], slot: Any, source: str | None) -> AnalysisSettings:
        formula = _parse(spec, bands, source)
        slots = {b: slot(b, "expression") for b in formula.bands}
        pairs = tuple(dict.fromkeys((slots[x], slots[y]) for x, y in
                                    formula.subtracted_pairs() + formula.divided_pairs()))
        return AnalysisSettings("formula", spec.parameter, slots=tuple(slots.values()),
                                options=(("expression", spec.expression),), pairs=pairs)

    def problem(self, settings: AnalysisSettings, names: Sequence[str], c: np.ndarray, w: np.ndarray) -> str | None:
        for x, y in settings.pairs:
            if same_band(c[x], w[x], c[y], w[y]):
                return (f"underdetermined: the formula compares {names[x]} with {names[y]} (a difference or a ratio, "
                        f"0 or 1 for one band), and they are the same band ({c[x]:g}/{w[x]:g} nm)")
        return None

    def underdetermined(self, settings: AnalysisSettings, c: np.ndarray, w: np.ndarray) -> np.ndarray:
        bad = np.zeros(c.shape[0], dtype=bool)
        for x, y in settings.pairs:
            bad |= same_band(c[:, x], w[:, x], c[:, y], w[:, y])
        return bad

    def sweep_code(self, settings: AnalysisSettings, T: VecTypes, ctx: SweepContext) -> tuple[str, str]:
        args = ", ".join(f"rho[{k}]" for k in settings.slots)
        body = (f"    {T.M} st;\n    const {T.V} value = s2_formula_{T.suffix}({args}, &st);\n"
                f"    const {T.M} bd = ({T.M})(0), code = ({T.M})(0);")
        return formula_of(settings, ctx.bands).device_source(T, ctx.max_abs), body

    def run(self, rt: Runtime, settings: AnalysisSettings, bands: Sequence[str], refl: np.ndarray,
            centres: np.ndarray, *, real_t: str, lanes: int | None, references: np.ndarray | None = None) -> Outcome:
        g = FormulaKernel(rt, formula_of(settings, bands), real_t=real_t, lanes=lanes)(refl, rows=list(settings.slots))
        return Outcome(g.value, g.status, np.zeros_like(g.status))


def twin(settings: AnalysisSettings, bands: Sequence[str], rhos: Sequence[np.ndarray], centres: np.ndarray,
         references: np.ndarray | None) -> Outcome:
    """The float64 numpy twin of the family's sweep code: :meth:`Formula.evaluate` on each slot's reflectance."""
    formula = formula_of(settings, bands)
    value, status = formula.evaluate({b: rhos[s] for b, s in zip(formula.bands, settings.slots, strict=True)})
    return Outcome(value, status, np.zeros_like(status))


def formula_of(settings: AnalysisSettings, bands: Sequence[str]) -> Formula:
    """The formula of a ``formula`` analysis whose slots hold ``bands``."""
    return Formula.parse(dict(settings.options)["expression"], bands)


def _parse(spec: Any, bands: Sequence[str], source: str | None) -> Formula:
    """The scene's expression parsed on ``bands``; errors name ``analysis.expression``."""
    if spec.expression is None:
        raise InputError("kind = 'formula' needs an expression (e.g. S2REP: '705 + 35 * ((B4 + B7) / 2 - B5) / "
                         "(B6 - B5)')", source=source, key="analysis.expression")
    try:
        return Formula.parse(spec.expression, bands)
    except InputError as err:
        raise InputError(err.detail, source=source, key="analysis.expression") from None


FAMILY = FormulaFamily()
