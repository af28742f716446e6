"""Host side of ``kernels/common/vecmath.mako``: coefficients and numpy twins of the device math.

PoCL 3.0 never inlines builtin math (``exp``, ``sqrt``, ``fma``, ``fmin``), and a builtin call
in a hot loop costs ~10-20x (``python -m bench.bench_igrm``: the "builtin exp" row). The vectorised kernels
therefore use their own ``exp`` for non-positive arguments: Cody-Waite range reduction
``a = n ln2 + f`` with ``|f| <= ln2/2``, a polynomial for ``exp(f)`` and ``2^n`` from the
exponent bits. The polynomial degree is an accuracy/time knob; :func:`exp_neg_model` is the
same computation in numpy so that its accuracy can be stated and tested.
"""

from __future__ import annotations

import math

import numpy as np

from s2cl.errors import InputError

#: Default polynomial degree per precision. Relative error of the polynomial alone on
#: |f| <= ln2/2 (measured): degree 5: 1.0e-7, 6: 2.5e-9, 7: 5.5e-11, 12 (Taylor): 3.3e-16; the
#: device result adds rounding (tests/test_vecmath.py states and checks 3e-7 and 4e-16).
EXP_DEGREE = {"float32": 5, "float64": 12}

#: Smallest argument the device exp evaluates; below it the result is exp(EXP_MIN), a
#: normal number (~1.6e-38 in float32): no denormals, no zero, no underflow to inf/NaN.
EXP_MIN = {"float32": -87.0, "float64": -708.0}

LN2_HI = {"float32": 0.693359375, "float64": 6.93147180369123816490e-01}
LN2_LO = {"float32": -2.12194440e-4, "float64": 1.90821492927058770002e-10}
ROUND_MAGIC = {"float32": 1.5 * 2.0**23, "float64": 1.5 * 2.0**52}


def exp_poly_coefficients(degree: int) -> list[float]:
    """Coefficients c0..cD (ascending) of the polynomial approximating exp on [-ln2/2, ln2/2].

    Degrees up to 8 interpolate exp at the Chebyshev nodes (near-minimax); higher degrees use
    the Taylor series (interpolation at high degree is ill-conditioned in float64, and Taylor
    is already below float64 rounding there). Deterministic: the same degree gives the same
    text and so the same compiled program.
    """
    if not 3 <= degree <= 16:
        raise InputError(f"must be in 3..16, got {degree}", key="exp_degree")
    if degree > 8:
        return [1.0 / math.factorial(i) for i in range(degree + 1)]
    h = math.log(2.0) / 2.0
    k = np.arange(degree + 1)
    nodes = np.cos((2 * k + 1) * np.pi / (2 * degree + 2)) * h
    coef = np.polynomial.polynomial.polyfit(nodes, np.exp(nodes), degree)
    return [float(c) for c in coef]


def exp_neg_model(a: np.ndarray, degree: int, real_t: str = "float32") -> np.ndarray:
    """numpy twin of the device ``s2_exp_neg``: exp(a) for a <= 0 in ``real_t`` arithmetic."""
    dt = np.dtype(real_t).type
    a = np.maximum(np.asarray(a, dtype=dt), dt(EXP_MIN[real_t]))
    n = np.rint(a * dt(1.0 / math.log(2.0)))
    f = (a - n * dt(LN2_HI[real_t])) - n * dt(LN2_LO[real_t])
    coef = exp_poly_coefficients(degree)
    p = np.full_like(f, dt(coef[-1]))
    for c in reversed(coef[:-1]):
        p = p * f + dt(c)
    return p * np.ldexp(dt(1.0), n.astype(np.int32)).astype(dt)


def exp_template_vars(real_t: str, degree: int | None = None) -> dict:
    """Template variables ``exp_coef`` and ``exp_consts`` for ``vecmath.exp_neg``."""
    deg = EXP_DEGREE[real_t] if degree is None else degree
    return {
        "exp_coef": exp_poly_coefficients(deg),
        "exp_consts": {
            "emin": EXP_MIN[real_t],
            "ln2_hi": LN2_HI[real_t],
            "ln2_lo": LN2_LO[real_t],
            "magic": ROUND_MAGIC[real_t],
        },
    }
