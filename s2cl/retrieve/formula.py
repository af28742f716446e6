"""A retrieval written as a formula of band reflectances: ``705 + 35 * ((B4 + B7) / 2 - B5) / (B6 - B5)`` (S2REP,
Frampton et al. 2013), parsed safely (:mod:`s2cl.retrieve.formula_syntax`: the grammar and its errors).

A scene selects it with ``[analysis] kind = "formula"``, ``expression = "..."`` and ``parameter = "..."`` (the
library parameter it is regressed on): :class:`s2cl.retrieve.analysis.AnalysisSettings` holds it, the design rule
uses :meth:`Formula.subtracted_pairs` and :meth:`Formula.divided_pairs`, ``simulate`` runs
:class:`s2cl.retrieve.formula_kernel.FormulaKernel` and the sweep kernel splices :meth:`Formula.device_source`.

Validity, one rule for the kernel and the float64 numpy twin: status INVALID and value 0 when a band is not
finite or |ρ| > ``max_abs``, a denominator is 0, sqrt has a negative or log a non-positive argument, or an
intermediate result is not finite or exceeds :data:`LIMIT` (1e30) in magnitude (inside float32's range, so both
precisions give one verdict). Reflectances are unitless; the value has the formula's unit (S2REP: nm).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from s2cl.cl.vectypes import VecTypes
from s2cl.errors import InputError
from s2cl.retrieve.formula_syntax import (
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
from s2cl.status import MAX_ABS_REFLECTANCE, Status

__all__ = ["KEY", "LIMIT", "Band", "Binary", "Formula", "Negate", "Node", "Number"]

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
