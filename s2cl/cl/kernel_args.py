"""One ordered argument list per kernel, used both to write the OpenCL signature (in the template) and
to bind values (on the host), so the two cannot drift apart. Every s2cl kernel is declared this way.

``ctype`` ``"real"`` stands for the kernel's working precision (``float`` or ``double``, from its
:class:`~s2cl.cl.vectypes.VecTypes`); other ctypes are OpenCL scalar types.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np

from s2cl.cl.device_memory import DeviceBuffer
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
    #: a buffer's element count as the product of named sizes (such as ``("configs", "pitch")``: a value per
    #: configuration of a launch and padded pixel), which the kernel's host gives numbers for (:func:`buffers`)
    scales: tuple[str, ...] = ()

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


#: bytes per element of the OpenCL scalar types a buffer holds ("real": the kernel's working precision)
_CTYPE_BYTES = {"uchar": 1, "char": 1, "ushort": 2, "short": 2, "uint": 4, "int": 4, "float": 4, "ulong": 8,
                "long": 8, "double": 8}


def buffers(args: Sequence[Arg], sizes: Mapping[str, int], real_bytes: int, unit: str) -> list[DeviceBuffer]:
    """The device buffers of ``args`` (those that declare :attr:`Arg.scales`) for ``sizes``, each as fixed bytes
    plus bytes per ``unit`` (a size left out of ``sizes``: the configurations of a chunk, say)."""
    out = []
    for a in args:
        if a.kind == "scalar" or not a.scales:
            continue
        item = real_bytes if a.ctype == "real" else _CTYPE_BYTES[a.ctype]
        count = math.prod(int(sizes[s]) for s in a.scales if s != unit)
        per = a.scales.count(unit)
        if per > 1:
            raise S2CLError(f"kernel argument {a.name}: its size is not linear in {unit}")
        out.append(DeviceBuffer(a.name, 0.0 if per else float(item * count), float(item * count) if per else 0.0))
    return out
