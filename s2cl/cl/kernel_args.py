"""One ordered argument list per kernel, used both to write the OpenCL signature (in the template) and
to bind values (on the host), so the two cannot drift apart. Every s2cl kernel is declared this way.

``ctype`` ``"real"`` stands for the kernel's working precision (``float`` or ``double``, from its
:class:`~s2cl.cl.vectypes.VecTypes`); other ctypes are OpenCL scalar types.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np

from s2cl.cl.vectypes import VecTypes
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
    """A kernel argument: a global buffer (``out``/``in``/``inout``) or a scalar.

    :param ctype: element type; ``"real"``: the working precision.
    """

    name: str
    kind: ArgKind
    ctype: str

    def declaration(self, T: VecTypes) -> str:
        ctype = T.R if self.ctype == "real" else self.ctype
        if self.kind == "scalar":
            return f"const {ctype} {self.name}"
        const = "const " if self.kind == "in" else ""
        return f"__global {const}{ctype} *restrict {self.name}"


def signature(args: Sequence[Arg], T: VecTypes) -> str:
    """The parameter list of a kernel, one argument per line (templates call it as ``signature(args, T)``)."""
    return ",\n    ".join(a.declaration(T) for a in args)


def bind(args: Sequence[Arg], values: dict[str, Any], T: VecTypes) -> list[Any]:
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
            dtype = T.dtype if a.ctype == "real" else _SCALAR_DTYPES[a.ctype]
            v = np.dtype(dtype).type(v)
        out.append(v)
    return out
