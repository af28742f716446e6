"""The syntax of formula retrievals (:mod:`s2cl.retrieve.families.formula`): a tokenizer and a recursive-descent parser
that turn the text into a small AST. Python never evaluates the text (no ``eval``, no ``ast``)::

    expr    := term (('+' | '-') term)*
    term    := unary (('*' | '/') unary)*
    unary   := '-' unary | primary
    primary := NUMBER | BAND | FUNC '(' expr [',' expr] ')' | '(' expr ')'

NUMBER: ``12``, ``0.5``, ``.5``, ``2e-3`` (0, or 1e-30 <= x <= 1e30). BAND: one of the allowed band names, bare
when it is a letter followed by letters, digits or ``_`` (``B8A``), else in brackets (``[swir-1]``, ``[8a]``: a
sensor's band names may hold ``-`` and start with a digit, :mod:`s2cl.sensor.names`). FUNC: ``sqrt``, ``log``
(natural), ``exp``, ``abs`` (one argument), ``min``, ``max`` (two). Whitespace is free; ``−``, ``×`` and ``÷`` (as
printed in papers) stand for ``-``, ``*`` and ``/``.

Errors: :class:`~s2cl.errors.InputError` with key ``analysis.expression`` and one line naming the 1-based column
and what was expected there. At most :data:`MAX_LENGTH` characters and :data:`MAX_DEPTH` nested parentheses.
"""

from __future__ import annotations

import re
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from typing import NamedTuple

from s2cl.errors import InputError, token

KEY = "analysis.expression"
MAX_LENGTH = 500  #: characters
MAX_DEPTH = 32  #: nested parentheses (groups and calls)
MAX_TREE_DEPTH = 64  #: operations nested in one another (unary minus and chains of + - * / included)
LIMIT = 1e30  #: largest literal, and |intermediate| above which a pixel is invalid (formula.py)
TINY = 1e-30  #: smallest non-zero literal
#: function name -> number of arguments
FUNCTIONS: dict[str, int] = {"sqrt": 1, "log": 1, "exp": 1, "abs": 1, "min": 2, "max": 2}
_BARE = re.compile(r"[A-Za-z][A-Za-z0-9_]*")
_NUMBER = re.compile(r"(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][+-]?[0-9]+)?")
_TOKEN = re.compile(r"(?P<num>(?:[0-9]|\.[0-9])[A-Za-z0-9_.]*(?:(?<=[eE])[+-][A-Za-z0-9_.]*)?)"
                    r"|(?P<name>[A-Za-z_][A-Za-z0-9_]*)|(?P<band>\[[^\]]*\]?)|(?P<op>[-+*/(),\u2212\u00d7\u00f7])")
#: the typographic operators a formula copied from a paper may hold
_ALIASES = {"\u2212": "-", "\u00d7": "*", "\u00f7": "/"}


@dataclass(frozen=True)
class Number:
    """A constant (finite, non-negative: a minus sign is a :class:`Negate`)."""

    value: float


@dataclass(frozen=True)
class Band:
    """A band's reflectance (unitless)."""

    name: str


@dataclass(frozen=True)
class Negate:
    """Unary minus."""

    arg: Node


@dataclass(frozen=True)
class Binary:
    """``left op right``."""

    op: str  #: ``+ - * /``
    left: Node
    right: Node


@dataclass(frozen=True)
class Call:
    """A function of :data:`FUNCTIONS` and its arguments."""

    func: str  #: a key of :data:`FUNCTIONS`
    args: tuple[Node, ...]


Node = Number | Band | Negate | Binary | Call


class _Token(NamedTuple):
    kind: str  # num, name, band, op, end
    text: str
    pos: int  # 0-based


def _fail(pos: int, message: str) -> InputError:
    return InputError(f"column {pos + 1}: {message}", key=KEY)


def _tail(text: str) -> str:
    """The end of ``text`` quoted for a message (at most 20 characters)."""
    text = text.strip()
    return token(text if len(text) <= 20 else "…" + text[-19:])


def _tokens(text: str) -> list[_Token]:
    """The tokens of ``text``; parentheses nested deeper than :data:`MAX_DEPTH` are refused here."""
    out, pos, depth = [], 0, 0
    while True:
        while pos < len(text) and text[pos].isspace():
            pos += 1
        if pos == len(text):
            return [*out, _Token("end", "", pos)]
        m = _TOKEN.match(text, pos)
        if m is None or text[pos] == "_":
            raise _fail(pos, f"unexpected character {token(text[pos])}")
        depth += (m.group() == "(") - (m.group() == ")")
        if depth > MAX_DEPTH:
            raise _fail(pos, f"parentheses nested deeper than {MAX_DEPTH} levels")
        out.append(_Token(m.lastgroup or "op", _ALIASES.get(m.group(), m.group()), pos))
        pos = m.end()


def _describe(t: _Token) -> str:
    return "the end" if t.kind == "end" else token(t.text)


class _Parser:
    """One recursive-descent pass over the tokens; a method per rule of the grammar."""

    def __init__(self, text: str, bands: Sequence[str]):
        self.text, self.bands = text, tuple(bands)
        self.toks, self.i = _tokens(text), 0

    def peek(self) -> _Token:
        return self.toks[self.i]

    def take(self) -> _Token:
        self.i += 1
        return self.toks[self.i - 1]

    def after(self, pos: int) -> str:
        return f"after {_tail(self.text[:pos])}" if self.text[:pos].strip() else "at the start"

    def parse(self) -> Node:
        node = self.expr()
        t = self.peek()
        if t.kind != "end":
            raise _fail(t.pos, f"expected an operator {self.after(t.pos)}, found {_describe(t)}")
        return node

    def binary(self, ops: str, operand: str) -> Node:
        node = getattr(self, operand)()
        while self.peek().kind == "op" and self.peek().text in ops:
            op = self.take().text
            node = Binary(op, node, getattr(self, operand)())
        return node

    def expr(self) -> Node:
        return self.binary("+-", "term")

    def term(self) -> Node:
        return self.binary("*/", "unary")

    def unary(self) -> Node:
        signs = 0
        while self.peek().kind == "op" and self.peek().text == "-":  # iterative: 500 minus signs do not recurse
            self.take()
            signs += 1
        node = self.primary()
        for _ in range(signs):
            node = Negate(node)
        return node

    def close(self, opening: _Token) -> None:
        t = self.take()
        if t.text != ")" or t.kind != "op":
            raise _fail(t.pos, f"expected ')' after {_tail(self.text[opening.pos:t.pos])}, found {_describe(t)}")

    def primary(self) -> Node:
        t = self.take()
        if t.kind == "num":
            return Number(self.number(t))
        if t.kind == "band":
            if not t.text.endswith("]") or len(t.text) < 2:
                raise _fail(t.pos, f"expected ']' after {_tail(t.text)}")
            return self.band(t, t.text[1:-1])
        if t.kind == "name":
            if self.peek().text == "(" and self.peek().kind == "op":
                return self.call(t)
            if t.text in FUNCTIONS and t.text not in self.bands:
                raise _fail(self.peek().pos, f"expected '(' after {t.text!r}, found {_describe(self.peek())}")
            return self.band(t, t.text)
        if t.kind == "op" and t.text == "(":
            node = self.expr()
            self.close(t)
            return node
        raise _fail(t.pos, f"expected a number, a band, a function or '(' {self.after(t.pos)}, found {_describe(t)}")

    def number(self, t: _Token) -> float:
        if not _NUMBER.fullmatch(t.text):
            hint = f" (a band? write it as [{t.text}])" if t.text in self.bands else ""
            raise _fail(t.pos, f"malformed number {token(t.text)}{hint}")
        value = float(t.text)
        if value != 0.0 and not TINY <= value <= LIMIT:
            raise _fail(t.pos, f"number {token(t.text)} out of range (0, or {TINY:g} to {LIMIT:g})")
        return value

    def band(self, t: _Token, name: str) -> Band:
        """The band ``name`` names, matched without regard to case as every band key of a scene is (``b8a`` is
        B8a), under the sensor's own spelling."""
        if name in self.bands:
            return Band(name)
        same = [b for b in self.bands if b.lower() == name.lower()]
        if len(same) == 1:
            return Band(same[0])
        rest = self.text[t.pos:]
        hyphenated = [b for b in self.bands if t.kind == "name" and "-" in b and rest.startswith(b)]
        if hyphenated:
            raise _fail(t.pos, f"write the band {hyphenated[0]!r} in brackets: [{hyphenated[0]}]")
        raise _fail(t.pos, f"unknown band {token(name)}; bands: {', '.join(self.bands)}")

    def call(self, name: _Token) -> Call:
        if name.text not in FUNCTIONS:
            if name.text in self.bands:
                raise _fail(self.peek().pos, f"expected an operator after {token(name.text)}, found '('")
            raise _fail(name.pos, f"unknown function {token(name.text)}; functions: {', '.join(FUNCTIONS)}")
        opening, args = self.take(), [self.expr()]
        while self.peek().kind == "op" and self.peek().text == ",":
            self.take()
            args.append(self.expr())
        self.close(opening)
        n = FUNCTIONS[name.text]
        if len(args) != n:
            raise _fail(name.pos, f"{name.text}() takes {n} argument{'s' if n > 1 else ''}, got {len(args)}")
        return Call(name.text, tuple(args))


_PRECEDENCE = {"+": 1, "-": 1, "*": 2, "/": 2}


def to_text(node: Node) -> str:
    """``node`` as formula text that parses back to the same tree (canonical spacing and parentheses)."""
    if isinstance(node, Number):
        v = node.value
        return str(int(v)) if v.is_integer() and v < 1e16 else repr(v)
    if isinstance(node, Band):
        return node.name if _BARE.fullmatch(node.name) and node.name not in FUNCTIONS else f"[{node.name}]"
    if isinstance(node, Negate):
        inner = to_text(node.arg)
        return f"-({inner})" if isinstance(node.arg, Binary) else f"-{inner}"
    if isinstance(node, Call):
        return f"{node.func}({', '.join(to_text(a) for a in node.args)})"
    p = _PRECEDENCE[node.op]
    left, right = to_text(node.left), to_text(node.right)
    if isinstance(node.left, Binary) and _PRECEDENCE[node.left.op] < p:
        left = f"({left})"
    if isinstance(node.right, Binary) and _PRECEDENCE[node.right.op] <= p:
        right = f"({right})"
    return f"{left} {node.op} {right}"


def children(node: Node) -> tuple[Node, ...]:
    """The operands of ``node`` (none for a number or a band)."""
    if isinstance(node, Negate):
        return (node.arg,)
    if isinstance(node, Binary):
        return (node.left, node.right)
    return node.args if isinstance(node, Call) else ()


def tree_depth(root: Node) -> int:
    """Operations nested in one another in ``root`` (a band or a number: 0), counted without recursion."""
    deepest, stack = 0, [(root, 0)]
    while stack:
        node, depth = stack.pop()
        deepest = max(deepest, depth)
        stack.extend((child, depth + 1) for child in children(node))
    return deepest


def bands_of(node: Node) -> Iterator[str]:
    """Every band ``node`` names, in reading order (with repeats)."""
    if isinstance(node, Band):
        yield node.name
    for child in children(node):
        yield from bands_of(child)


def rename(node: Node, old: str, new: str) -> Node:
    """``node`` with band ``old`` replaced by ``new``."""
    if isinstance(node, Band):
        return Band(new) if node.name == old else node
    if isinstance(node, Negate):
        return Negate(rename(node.arg, old, new))
    if isinstance(node, Binary):
        return Binary(node.op, rename(node.left, old, new), rename(node.right, old, new))
    if isinstance(node, Call):
        return Call(node.func, tuple(rename(a, old, new) for a in node.args))
    return node


def parse_expression(text: str, bands: Sequence[str]) -> Node:
    """The AST of ``text``, a formula of the allowed ``bands``; :class:`InputError` when it is not one."""
    if not isinstance(text, str):
        raise InputError(f"must be a string, got {type(text).__name__}", key=KEY)
    if len(text) > MAX_LENGTH:
        raise _fail(MAX_LENGTH, f"the expression is longer than {MAX_LENGTH} characters")
    if not text.strip():
        raise _fail(0, "the expression is empty")
    root = _Parser(text, bands).parse()
    depth = tree_depth(root)
    if depth > MAX_TREE_DEPTH:
        raise _fail(0, f"the expression nests {depth} operations in one another; at most {MAX_TREE_DEPTH} (write "
                       "it more simply)")
    if not any(bands_of(root)):
        raise _fail(0, f"the expression names no band; bands: {', '.join(bands)}")
    return root
