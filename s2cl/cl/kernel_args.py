"""One ordered argument list per kernel, used both to write the OpenCL signature (in the
template) and to bind values (on the host), so the two cannot drift apart.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Literal

import numpy as np

from s2cl.errors import S2CLError

ArgKind = Literal["out", "in", "inout", "scalar"]

_SCALAR_DTYPES = {
    "uint": np.uint32,
    "int": np.int32,
    "ulong": np.uint64,
    "float": np.float32,
    "double": np.float64,
}


@dataclass(frozen=True)
class Arg:
    """A kernel argument: a global buffer (``out``/``in``/``inout``) or a scalar."""

    name: str
    kind: ArgKind
    ctype: str

    def declaration(self) -> str:
        if self.kind == "scalar":
            return f"const {self.ctype} {self.name}"
        const = "const " if self.kind == "in" else ""
        return f"__global {const}{self.ctype} *restrict {self.name}"


def signature(args: list[Arg] | tuple[Arg, ...]) -> str:
    """The parameter list of a kernel, one argument per line."""
    return ",\n    ".join(a.declaration() for a in args)


def bind(args: list[Arg] | tuple[Arg, ...], values: dict[str, Any], real_dtype: Any) -> list[Any]:
    """Values in signature order; scalars converted to their exact dtype.

    :raises S2CLError: an argument has no value, or a value is left over (a programming error).
    """
    missing = [a.name for a in args if a.name not in values]
    extra = sorted(set(values) - {a.name for a in args})
    if missing or extra:
        raise S2CLError(f"kernel arguments do not match: missing {missing}, unexpected {extra}")
    out = []
    for a in args:
        v = values[a.name]
        if a.kind == "scalar":
            dtype = real_dtype if a.ctype == "real_t" else _SCALAR_DTYPES[a.ctype]
            v = np.dtype(dtype).type(v)
        out.append(v)
    return out
