"""Formula retrievals (s2cl/retrieve/formula.py): the parser (precedence, errors with their column, nothing
evaluated by Python), the float64 numpy twin against hand-computed values, and the kernel against the twin at
every lane width, the hard cases (zero denominator, NaN/inf, sqrt/log out of their domain, overflow) included.

float32 tolerance: the kernel's inputs are the float32-rounded reflectances, so the twin is run on exactly those;
what remains is the rounding of each float32 operation. :func:`float32_bound` propagates a first-order bound of
it through the formula (running error analysis, unit roundoff u = 2^-24): + - * at 0.5 ulp, / at 2.5 ulp and
sqrt/log/exp at 3 ulp (the OpenCL 1.2 single-precision limits), literals rounded to float32; the test allows
twice that bound per pixel (the factor covers the second-order terms). A fixed tolerance would either hide a wrong
rule or fail on cancellation: S2REP divides by B6 - B5, whose relative error grows as the bands approach.
"""

from __future__ import annotations

import numpy as np
import pytest

from s2cl.errors import InputError
from s2cl.retrieve.families.formula import Formula, FormulaKernel, formula_values
from s2cl.retrieve.families.formula_syntax import (
    FUNCTIONS,
    MAX_DEPTH,
    MAX_LENGTH,
    MAX_TREE_DEPTH,
    Band,
    Binary,
    Call,
    Negate,
    Node,
    Number,
    bands_of,
    children,
    to_text,
)
from s2cl.retrieve.index_kernel import IndexKernel
from s2cl.status import Status

S2 = ("B1", "B2", "B3", "B4", "B5", "B6", "B7", "B8", "B8A", "B9", "B11", "B12")
S2REP = "705 + 35 * ((B4 + B7) / 2 - B5) / (B6 - B5)"
#: the shipped red-edge and chlorophyll indices, written as formulas
SHIPPED = {
    "s2rep": S2REP,  # Frampton et al. 2013
    "mtci": "(B6 - B5) / (B5 - B4)",  # Dash and Curran 2004
    "ci_red_edge": "B7 / B5 - 1",  # Gitelson et al. 2003
    "mcari_osavi": "((B5 - B4) - 0.2 * (B5 - B3)) * (B5 / B4) / (1.16 * (B8 - B4) / (B8 + B4 + 0.16))",
    "ndvi": "(B8 - B4) / (B8 + B4)",
    "functions": "sqrt(B8) * log(B8 / B4) - exp(-B5) + abs(B3 - B4) / max(B4, 0.01) + min(B6, B7)",
}
U32 = 2.0 ** -24
#: OpenCL 1.2 float32 accuracy of each operation, in ulp (one ulp <= 2 u |x|)
ULP = {"+": 0.5, "-": 0.5, "*": 0.5, "/": 2.5, "sqrt": 3.0, "log": 3.0, "exp": 3.0}


def parse(text: str) -> Formula:
    return Formula.parse(text, S2)


def vegetation(n: int, seed: int) -> dict[str, np.ndarray]:
    """Green-vegetation reflectances (unitless): low visible, a red edge from B5 to B7, a NIR plateau."""
    rng = np.random.default_rng(seed)
    ranges = {"B3": (0.04, 0.10), "B4": (0.02, 0.08), "B5": (0.10, 0.20), "B6": (0.30, 0.45), "B7": (0.40, 0.55),
              "B8": (0.40, 0.60)}
    return {band: rng.uniform(lo, hi, n) for band, (lo, hi) in ranges.items()}


def float32_bound(node: Node, values: dict[str, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """(value, first-order bound of the float32 rounding error) of ``node`` on float32-exact inputs."""
    if isinstance(node, Number):
        return np.float64(node.value), np.float64(U32 * node.value)
    if isinstance(node, Band):
        return values[node.name], np.zeros_like(values[node.name])
    args = [float32_bound(child, values) for child in children(node)]
    (a, ea), (b, eb) = args[0], args[-1]
    if isinstance(node, Negate):
        return -a, ea
    op = node.op if isinstance(node, Binary) else node.func
    with np.errstate(all="ignore"):
        if op in ("+", "-"):
            v, e = (a + b if op == "+" else a - b), ea + eb
        elif op == "*":
            v, e = a * b, np.abs(a) * eb + np.abs(b) * ea + ea * eb
        elif op == "/":
            v = a / b
            e = (ea + np.abs(v) * eb) / (np.abs(b) - eb)
        elif op == "sqrt":
            v, e = np.sqrt(a), np.sqrt(a) - np.sqrt(np.maximum(a - ea, 0.0))
        elif op == "log":
            v, e = np.log(a), np.log(a) - np.log(a - ea)
        elif op == "exp":
            v, e = np.exp(a), np.exp(a + ea) - np.exp(a)
        elif op == "abs":
            v, e = np.abs(a), ea
        else:
            v, e = (np.fmin(a, b) if op == "min" else np.fmax(a, b)), np.maximum(ea, eb)
    return v, e + 2.0 * ULP.get(op, 0.0) * U32 * np.abs(v)


def rows_of(formula: Formula, values: dict[str, np.ndarray]) -> np.ndarray:
    return np.vstack([values[b] for b in formula.bands])


def assert_kernel_matches_twin(formula: Formula, values: dict[str, np.ndarray], real_t: str, got) -> None:
    """Statuses identical; float64 values to 1e-10 relative, float32 within twice :func:`float32_bound`."""
    if real_t == "float32":
        values = {b: v.astype(np.float32).astype(np.float64) for b, v in values.items()}
    want, status = formula.evaluate(values)
    np.testing.assert_array_equal(got.status, status)
    assert np.all(np.isfinite(got.value)) and np.all(got.value[status == Status.INVALID] == 0.0)
    if real_t == "float64":
        np.testing.assert_allclose(got.value, want, rtol=1e-10, atol=0)
        return
    ok = status == Status.OK
    _, bound = float32_bound(formula.root, {b: v[ok] for b, v in values.items()})
    err = np.abs(got.value[ok] - want[ok])
    assert np.all(err <= 2.0 * bound + 1e-30), f"max error/bound {np.max(err / bound):.3g}"


# ---- the parser ----------------------------------------------------------------------------------------------

@pytest.mark.parametrize(("text", "tree"), [
    ("B4 - B5 - B6", Binary("-", Binary("-", Band("B4"), Band("B5")), Band("B6"))),
    ("B4 / B5 / B6", Binary("/", Binary("/", Band("B4"), Band("B5")), Band("B6"))),
    ("B4 - B5 / B6", Binary("-", Band("B4"), Binary("/", Band("B5"), Band("B6")))),
    ("B4 * B5 + B6", Binary("+", Binary("*", Band("B4"), Band("B5")), Band("B6"))),
    ("B4 * (B5 + B6)", Binary("*", Band("B4"), Binary("+", Band("B5"), Band("B6")))),
    ("-B4 * B5", Binary("*", Negate(Band("B4")), Band("B5"))),
    ("B4 - -B5", Binary("-", Band("B4"), Negate(Band("B5")))),
    ("--B4", Negate(Negate(Band("B4")))),
    ("-(B4 + B5)", Negate(Binary("+", Band("B4"), Band("B5")))),
    ("\tB4\n+  2.5e-1 ", Binary("+", Band("B4"), Number(0.25))),
    ("B4*.5/2./1E+2", Binary("/", Binary("/", Binary("*", Band("B4"), Number(0.5)), Number(2.0)), Number(100.0))),
    ("(B6 − B5) ÷ B5 × 2", Binary("*", Binary("/", Binary("-", Band("B6"), Band("B5")), Band("B5")), Number(2.0))),
    ("max(B4, min(B5, 0))", Call("max", (Band("B4"), Call("min", (Band("B5"), Number(0.0)))))),
    ("sqrt(abs(B4)) + exp(log(B8A))", Binary("+", Call("sqrt", (Call("abs", (Band("B4"),)),)),
                                              Call("exp", (Call("log", (Band("B8A"),)),)))),
])
def test_precedence_associativity_and_unary_minus(text: str, tree: Node) -> None:
    formula = parse(text)
    assert formula.root == tree
    assert parse(str(formula)).root == tree  # the canonical text parses back to the same tree


def test_bands_in_first_use_order_and_values_by_hand() -> None:
    formula = parse(S2REP)
    assert formula.bands == ("B4", "B7", "B5", "B6")
    one = {"B3": 0.08, "B4": 0.05, "B5": 0.15, "B6": 0.35, "B7": 0.45, "B8": 0.45}
    expect = {"s2rep": 705 + 35 * (0.25 - 0.15) / 0.2,  # 722.5 nm
              "mtci": 0.2 / 0.1, "ci_red_edge": 0.45 / 0.15 - 1, "ndvi": 0.4 / 0.5,
              "mcari_osavi": (0.1 - 0.2 * 0.07) * 3.0 / (1.16 * 0.4 / 0.66),
              "functions": np.sqrt(0.45) * np.log(9.0) - np.exp(-0.15) + 0.03 / 0.05 + 0.35}
    for name, text in SHIPPED.items():
        value, status = parse(text).evaluate({b: np.array([v]) for b, v in one.items()})
        assert status[0] == Status.OK and value[0] == pytest.approx(expect[name], rel=1e-14), name
    assert parse("B4 - 4 - 2").evaluate({"B4": np.array(8.0)})[0] == 2.0
    assert parse("B4 / 4 / 2").evaluate({"B4": np.array(8.0)})[0] == 1.0
    assert parse("B4 - 4").evaluate({"B4": np.array(12.0)})[1] == Status.INVALID  # |rho| > max_abs = 10
    assert parse("B4 - 4").evaluate({"B4": np.array(12.0)}, max_abs=100)[0] == 8.0


@pytest.mark.parametrize(("text", "column", "fragment"), [
    ("705 + 35 * ((B4 + B7) / 2 - B5) / (B6 - B5", 43, "expected ')' after '(B6 - B5', found the end"),
    ("(B4 + B5", 9, "expected ')' after '(B4 + B5'"),
    ("B4 +", 5, "expected a number, a band, a function or '(' after 'B4 +', found the end"),
    ("B4 + * B5", 6, "found '*'"),
    ("B4 B5", 4, "expected an operator after 'B4', found 'B5'"),
    ("B4 ** 2", 5, "found '*'"),
    ("B4 + )", 6, "found ')'"),
    ("()", 2, "found ')'"),
    ("sqrt B4", 6, "expected '(' after 'sqrt'"),
    ("min(B4)", 1, "min() takes 2 arguments, got 1"),
    ("sqrt(B4, B5)", 1, "sqrt() takes 1 argument, got 2"),
    ("B4 , B5", 4, "expected an operator after 'B4', found ','"),
    ("B4(B5)", 3, "expected an operator after 'B4', found '('"),
    ("2B4", 1, "malformed number '2B4'"),
    ("1.2.3 * B4", 1, "malformed number '1.2.3'"),
    ("B4 + 2e", 6, "malformed number '2e'"),
    ("B4 * 1e31", 6, "out of range"),
    ("B4 * 1e-31", 6, "out of range"),
    ("B4 = 1", 4, "unexpected character '='"),
    ("B4 ^ 2", 4, "unexpected character '^'"),
    ("[B4 + B5", 1, "expected ']'"),
    ("   ", 1, "the expression is empty"),
    ("2 + 3", 1, "names no band"),
])
def test_malformed_expressions_name_the_column(text: str, column: int, fragment: str) -> None:
    with pytest.raises(InputError) as err:
        parse(text)
    message = str(err.value)
    assert message.startswith(f"analysis.expression: column {column}: ") and fragment in message, message
    assert "\n" not in message and err.value.key == "analysis.expression"


def test_unknown_band_and_function_name_the_known_ones() -> None:
    with pytest.raises(InputError, match=r"column 6: unknown band 'B13'; bands: B1, B2, .*, B8A, B9, B11, B12$"):
        parse("B4 + B13")
    with pytest.raises(InputError, match=r"column 1: unknown function 'tan'; functions: sqrt, log, exp, abs, "
                                         r"min, max$"):
        parse("tan(B4)")
    assert parse("b4 + B5").bands == ("B4", "B5")  # band names match without regard to case, as the scene's keys


def test_band_names_with_hyphens_or_a_leading_digit_go_in_brackets() -> None:
    bands = ("swir-1", "8a", "log", "B4")
    formula = Formula.parse("([swir-1] - [8a]) / ([swir-1] + [8a]) + [log] * log(B4)", bands)
    assert formula.bands == ("swir-1", "8a", "log", "B4")
    assert Formula.parse(str(formula), bands).root == formula.root
    assert formula.subtracted_pairs() == (("swir-1", "8a"),)
    with pytest.raises(InputError, match=r"column 1: write the band 'swir-1' in brackets: \[swir-1\]"):
        Formula.parse("swir-1 + B4", bands)
    with pytest.raises(InputError, match=r"malformed number '8a' \(a band\? write it as \[8a\]\)"):
        Formula.parse("B4 * 8a", bands)
    with pytest.raises(InputError, match="column 6: unknown band 'B5'"):
        Formula.parse("B4 + [B5]", bands)


@pytest.mark.parametrize("text", ["__import__('os')", "__import__('os').system('true')", "B4.__class__",
                                  "exec('1')", "lambda: B4", "B4 if B5 else B6", "B4; B5", "'B4'", "B4[0]",
                                  "[B4].pop()", "getattr(B4, 'real')", "B4 @ B5", "open('x')"])
def test_python_is_never_evaluated(text: str) -> None:
    with pytest.raises(InputError, match=r"^analysis\.expression: column \d+: "):
        parse(text)


def test_length_and_nesting_limits() -> None:
    long = "B4" + " " * (MAX_LENGTH - 2)
    assert parse(long).bands == ("B4",)
    with pytest.raises(InputError, match=f"column {MAX_LENGTH + 1}: .* longer than {MAX_LENGTH} characters"):
        parse(long + " + B4")
    flat = "B4" + " + B4" * (MAX_TREE_DEPTH + 1)  # a chain of + is a tree as deep as it is long
    with pytest.raises(InputError, match=f"nests {MAX_TREE_DEPTH + 1} operations in one another"):
        parse(flat)
    assert len(parse("B4" + " + B4" * MAX_TREE_DEPTH).bands) == 1
    deep = "(" * MAX_DEPTH + "B4" + ")" * MAX_DEPTH
    assert parse(deep).root == Band("B4")
    with pytest.raises(InputError, match=f"column {MAX_DEPTH + 1}: parentheses nested deeper than {MAX_DEPTH}"):
        parse("(" + deep + ")")
    assert parse("sqrt(" * 16 + "B4" + ")" * 16).bands == ("B4",)
    assert parse("-" * MAX_TREE_DEPTH + "B4").evaluate({"B4": np.array(0.5)})[0] == 0.5  # an even count of signs
    with pytest.raises(InputError, match="nests"):
        parse("-" * 400 + "B4")  # nor is a tower of signs: each is an operation (and would recurse)
    with pytest.raises(InputError, match="must be a string"):
        Formula.parse(42, S2)  # type: ignore[arg-type]


def random_tree(rng: np.random.Generator, depth: int) -> Node:
    """A random formula tree over a few bands, numbers, operators and functions."""
    if depth == 0 or rng.random() < 0.2:
        return Band(str(rng.choice(["B4", "B5", "B8A"]))) if rng.random() < 0.7 \
            else Number(float(rng.choice([0.0, 0.5, 2.0, 705.0, 1e-3, 2.5e20])))
    kind = rng.integers(0, 3)
    if kind == 0:
        return Negate(random_tree(rng, depth - 1))
    if kind == 1:
        return Binary(str(rng.choice(list("+-*/"))), random_tree(rng, depth - 1), random_tree(rng, depth - 1))
    func = str(rng.choice(list(FUNCTIONS)))
    return Call(func, tuple(random_tree(rng, depth - 1) for _ in range(FUNCTIONS[func])))


def test_random_formulas_round_trip_and_random_text_gets_one_line_errors() -> None:
    rng = np.random.default_rng(11)
    checked = 0
    for _ in range(400):
        tree = random_tree(rng, 5)
        text = to_text(tree)
        if any(bands_of(tree)) and len(text) <= MAX_LENGTH:
            assert parse(text).root == tree, text
            checked += 1
    assert checked > 200
    alphabet = list("B4 58.e+-*/()[],sqrtminx_'\"$")
    for _ in range(3000):
        text = "".join(rng.choice(alphabet, size=rng.integers(0, 25)))
        try:
            parse(text)
        except InputError as err:
            assert "\n" not in str(err) and str(err).startswith("analysis.expression: column "), str(err)


@pytest.mark.parametrize(("text", "pairs"), [
    (S2REP, {("B6", "B5")}),
    ("(B6 - B5) / (B5 - B4)", {("B6", "B5"), ("B5", "B4")}),
    ("(B8 - B4) / (B8 + B4)", {("B8", "B4")}),
    ("log(B6) - log(B5) + (2 * B7 - 2 * B8)", {("B6", "B5"), ("B7", "B8")}),
    ("B7 / B5 - 1", set()),
    ("2 * B6 - B5", set()),  # B6 = B5 leaves B5: not a vanishing difference
    ("(B4 + B7) / 2 - B5", set()),
    ("B5 - B5", set()),
])
def test_subtracted_pairs(text: str, pairs: set) -> None:
    assert set(parse(text).subtracted_pairs()) == pairs


def test_twin_hard_cases_are_invalid_with_value_zero() -> None:
    """Zero denominator, NaN/inf, |rho| > 10, sqrt/log out of their domain and overflow: INVALID, 0, never NaN."""
    b4 = np.array([0.05, 0.05, np.nan, np.inf, -np.inf, 11.0, 0.05, 0.05, 0.05])
    b5 = np.array([0.15, 0.30, 0.15, 0.15, 0.15, 0.15, 0.15, 0.15, -0.15])
    b6 = np.array([0.35, 0.30, 0.35, 0.35, 0.35, 0.35, 0.35, 0.35, 0.35])
    b7 = np.array([0.45, 0.45, 0.45, 0.45, 0.45, 0.45, np.nan, 0.45, 0.45])
    value, status = parse(S2REP).evaluate({"B4": b4, "B5": b5, "B6": b6, "B7": b7})
    np.testing.assert_array_equal(status, [0, 3, 3, 3, 3, 3, 3, 0, 0])
    assert value[0] == value[7] == pytest.approx(722.5) and np.all(value[status == 3] == 0.0)
    cases = {"sqrt(B5)": [0, 0, 0, 0, 0, 0, 0, 0, 3], "log(B5 - B6)": [3, 3, 3, 3, 3, 3, 3, 3, 3],
             "log(B6 - B5)": [0, 3, 0, 0, 0, 0, 0, 0, 0], "exp(B6 * 1000)": [3] * 9,
             "B6 * 1e30 * 1e30": [3] * 9, "B6 / (B5 * 1e-30 * 1e-30)": [3] * 9, "1 / (B6 - B6)": [3] * 9}
    for text, expect in cases.items():
        value, status = parse(text).evaluate({"B4": b4, "B5": b5, "B6": b6, "B7": b7})
        np.testing.assert_array_equal(status, expect, err_msg=text)
        assert np.all(np.isfinite(value)) and np.all(value[status == Status.INVALID] == 0.0), text


#: Each guard at and around its boundary, values computed by hand (None: INVALID, value 0). Reflectances are
#: float32-exact or float32-rounded within the tolerance of ``test_guard_boundaries_by_hand``; the exact LIMIT
#: boundary (1e30, which float32 and float64 round differently) is left out.
GUARD_CASES: dict[str, list[tuple[dict[str, float], float | None]]] = {
    # sqrt: the argument may be 0 (or -0), not below
    "sqrt(B4)": [({"B4": 0.0}, 0.0), ({"B4": -0.0}, 0.0), ({"B4": 0.25}, 0.5), ({"B4": 1e-30}, 1e-15),
                 ({"B4": -1e-30}, None), ({"B4": -0.25}, None)],
    "sqrt(B4 - B5)": [({"B4": 0.25, "B5": 0.25}, 0.0), ({"B4": 0.5, "B5": 0.25}, 0.5),
                      ({"B4": 0.25, "B5": 0.5}, None)],
    # log: the argument must be > 0; ln(1e-30) = -30 ln 10
    "log(B4)": [({"B4": 1.0}, 0.0), ({"B4": 0.0}, None), ({"B4": -0.0}, None), ({"B4": 1e-30}, -69.07755278982137),
                ({"B4": -1e-30}, None), ({"B4": 10.0}, 2.302585092994046), ({"B4": 0.5}, -0.6931471805599453)],
    # /: the denominator (not the numerator) must be non-zero; the quotient must stay within LIMIT (1e30)
    "B5 / B4": [({"B5": 1.0, "B4": 0.0}, None), ({"B5": 1.0, "B4": -0.0}, None), ({"B5": 0.0, "B4": 0.0}, None),
                ({"B5": 0.0, "B4": 0.5}, 0.0), ({"B5": 1.0, "B4": 0.5}, 2.0), ({"B5": 1.0, "B4": 1.0}, 1.0),
                ({"B5": 1.0, "B4": 1e-29}, 1e29),
                ({"B5": 1.0, "B4": -1e-29}, -1e29), ({"B5": 1.0, "B4": 1e-31}, None),
                ({"B5": 1.0, "B4": -1e-31}, None)],
    # exp: e^69 = 9.2538e29 stays within LIMIT, e^69.1 = 1.0227e30 does not; e^-100 underflows harmlessly
    "exp(B4 * 10)": [({"B4": 6.9}, 9.253781725587787e29), ({"B4": 6.91}, None), ({"B4": 0.0}, 1.0),
                     ({"B4": -10.0}, 3.720075976020836e-44)],
    # |intermediate| <= LIMIT on both sides
    "B4 * 2e29": [({"B4": 4.9}, 9.8e29), ({"B4": -4.9}, -9.8e29), ({"B4": 5.1}, None), ({"B4": -5.1}, None)],
    # |rho| <= max_abs (10) on both sides, NaN and inf out
    "B4": [({"B4": 10.0}, 10.0), ({"B4": -10.0}, -10.0), ({"B4": 10.5}, None), ({"B4": -10.5}, None),
           ({"B4": np.nan}, None), ({"B4": np.inf}, None), ({"B4": -np.inf}, None)],
}


def _guard_case(text: str) -> tuple[Formula, dict[str, np.ndarray], np.ndarray, np.ndarray]:
    """The formula, its band values per pixel, the hand values (0 where invalid) and statuses."""
    formula, cases = parse(text), GUARD_CASES[text]
    values = {b: np.array([c[b] for c, _ in cases]) for b in formula.bands}
    want = np.array([0.0 if v is None else v for _, v in cases])
    status = np.array([Status.INVALID if v is None else Status.OK for _, v in cases], np.uint8)
    return formula, values, want, status


@pytest.mark.parametrize("text", list(GUARD_CASES))
def test_twin_guard_boundaries_by_hand(text: str) -> None:
    formula, values, want, status = _guard_case(text)
    value, got = formula.evaluate(values)
    np.testing.assert_array_equal(got, status)
    np.testing.assert_allclose(value, want, rtol=1e-14, atol=0)


@pytest.mark.parametrize("text", list(GUARD_CASES))
def test_kernel_guard_boundaries_by_hand(rt, real_t, text: str) -> None:
    """The same cases in the kernel, float32 and float64, 4 lanes (a partly filled last vector included)."""
    formula, values, want, status = _guard_case(text)
    got = FormulaKernel(rt, formula, real_t, 4)(rows_of(formula, values))
    np.testing.assert_array_equal(got.status, status)
    rtol = 1e-12 if real_t == "float64" else 1e-5  # float32: the inputs rounded (6.9 -> 6.9000001), then exp
    np.testing.assert_allclose(got.value, want, rtol=rtol, atol=1e-40)


def test_twin_needs_every_band() -> None:
    with pytest.raises(InputError, match="no reflectance for band"):
        parse("B4 + B5").evaluate({"B4": np.zeros(3)})


# ---- the kernel --------------------------------------------------------------------------------------------

@pytest.mark.parametrize("name", list(SHIPPED))
def test_kernel_matches_twin_at_every_lane_width(rt, real_t, lanes, name: str) -> None:
    formula = parse(SHIPPED[name])
    kernel = FormulaKernel(rt, formula, real_t, lanes)
    for n in (1, 13, 1037):
        values = vegetation(n, seed=n)
        assert_kernel_matches_twin(formula, values, real_t, kernel(rows_of(formula, values)))


@pytest.mark.parametrize("text", ["705 + 35 * ((B4 + B7) / 2 - B5) / (B6 - B5)", "sqrt(B5) + log(B6 - B5)",
                                  "exp(B6 * 100) - B4 * 1e30 / B7", "B6 / (B5 * 1e-20 * 1e-9)",
                                  "max(B4, B5) / min(B6, B7) - abs(-B4)"])
def test_kernel_hard_cases_give_the_twins_statuses(rt, real_t, lanes, text: str) -> None:
    """Every hard case, in every lane position, next to valid pixels that it must not touch."""
    formula = parse(text)
    base = {"B4": 0.05, "B5": 0.15, "B6": 0.35, "B7": 0.45}
    hard = [("B6", 0.15), ("B5", np.nan), ("B4", np.inf), ("B7", -np.inf), ("B6", 1e38), ("B5", -0.15),
            ("B6", 11.0), ("B5", 0.35), ("B7", 0.0), ("B4", -10.0), ("B6", 0.9), ("B6", 0.7), ("B5", 0.0)]
    n = 3 * len(hard) + 5
    values = {b: np.full(n, v) for b, v in base.items()}
    for k, (band, v) in enumerate(hard):
        values[band][3 * k + 1] = v
    got = FormulaKernel(rt, formula, real_t, lanes)(rows_of(formula, values))
    assert_kernel_matches_twin(formula, values, real_t, got)
    assert got.status[0] == Status.OK and np.all(got.value[::3] == got.value[0])  # neighbours unaffected
    assert np.any(got.status == Status.INVALID)


def test_ndvi_formula_equals_the_ndvi_index(rt, real_t, lanes) -> None:
    """(B8 - B4) / (B8 + B4) against s2cl's own NDVI (kernels/index.cl.mako) on positive reflectances (where the
    index's rule, both reflectances positive, and the formula's, a non-zero denominator, agree), NaN/inf and
    |rho| > 10 included."""
    rng = np.random.default_rng(5)
    red, nir = rng.uniform(0.01, 0.15, 1037), rng.uniform(0.2, 0.6, 1037)
    red[[3, 100]], nir[[7, 500]] = np.nan, [np.inf, 20.0]
    formula = parse(SHIPPED["ndvi"])
    got = FormulaKernel(rt, formula, real_t, lanes)(np.vstack([red, nir]), rows=[1, 0])
    index = IndexKernel(rt, "ndvi", real_t=real_t, lanes=lanes)(np.vstack([nir, red]), 0, 1)
    np.testing.assert_array_equal(got.status, index.status)
    assert np.sum(got.status == Status.INVALID) == 4
    np.testing.assert_allclose(got.value, index.index, rtol=1e-15 if real_t == "float64" else 1e-7, atol=0)


def test_kernel_rows_and_input_errors(rt) -> None:
    formula = parse("B5 / B4")
    refl = np.array([[0.1, 0.2], [0.3, 0.3], [0.05, 0.1]])
    got = formula_values(refl, formula, rows=[1, 2], real_t="float32", device=rt.info.spec)
    np.testing.assert_allclose(got.value, [6.0, 3.0], rtol=1e-6)
    value, status = formula_values(refl[1:], formula)  # rows default to the formula's bands, in order
    np.testing.assert_allclose(value, [6.0, 3.0], rtol=1e-6)
    np.testing.assert_array_equal(status, [0, 0])
    with pytest.raises(InputError, match=r"reflectance: needs one row in 0\.\.2 for each of the bands B5, B4"):
        FormulaKernel(rt, formula)(refl, rows=[0, 3])
    with pytest.raises(InputError, match=r"needs one row"):
        FormulaKernel(rt, formula)(refl, rows=[0])
    with pytest.raises(InputError, match=r"\(n_bands, n_pixels\)"):
        FormulaKernel(rt, formula)(np.zeros(4))


def test_device_source_is_one_guarded_function_per_type() -> None:
    from s2cl.cl.vectypes import VecTypes

    source = parse(S2REP).device_source(VecTypes("float64", 4))
    assert "static inline double4 s2_formula_d4(const double4 b0, const double4 b1, const double4 b2, " \
           "const double4 b3, long4 *status)" in source
    assert "#ifndef S2_FORMULA_D4" in source and "/* " + S2REP + " (b0 = B4, b1 = B7, b2 = B5, b3 = B6) */" in source
    assert "eval" not in source


def test_band_names_match_without_regard_to_case() -> None:
    """As every band key of a scene: ``b6 - b5`` is B6 - B5, under the sensor's spelling."""
    f = Formula.parse("(b6 - B5) / b8A", ["B5", "B6", "B8A"])
    assert f.bands == ("B6", "B5", "B8A") and f.subtracted_pairs() == (("B6", "B5"),)


def test_the_family_reads_each_band_from_its_slot(rt) -> None:
    """``B5 / B4`` on the analysis bands B4, B8, B5: its bands in the order it names them sit in slots 2 and 0."""
    from s2cl.retrieve.families.formula import FAMILY
    from s2cl.retrieve.family import AnalysisSettings

    settings = AnalysisSettings("formula", "cab", slots=(2, 0), options=(("expression", "B5 / B4"),))
    refl = np.array([[0.1, 0.2, 0.0], [0.5, 0.5, 0.5], [0.3, 0.3, 0.3]])  # B4, B8, B5
    out = FAMILY.run(rt, settings, ["B4", "B8", "B5"], refl, np.array([665.0, 842.0, 705.0]), real_t="float32",
                     lanes=None)
    np.testing.assert_allclose(out.index, [3.0, 1.5, 0.0], rtol=1e-6)
    np.testing.assert_array_equal(out.status, [Status.OK, Status.OK, Status.INVALID])
    np.testing.assert_array_equal(out.bounds, [0, 0, 0])
