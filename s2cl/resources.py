"""Locate the folders s2cl ships beside its package: ``kernels/`` and ``scenes/``.

In an installed wheel they sit inside the package (``s2cl/kernels``, ``s2cl/scenes``, found through
:mod:`importlib.resources`); in a source checkout or editable install they are the top-level
folders next to the package. Never relative to the working directory.
"""

from __future__ import annotations

import hashlib
import importlib.resources
from functools import cache
from pathlib import Path

from s2cl.errors import S2CLError


@cache
def shipped_dir(name: str, marker: str) -> Path:
    """The shipped folder ``name`` (``"kernels"`` or ``"scenes"``) that contains ``marker``."""
    candidates = [
        Path(str(importlib.resources.files("s2cl") / name)),
        Path(__file__).resolve().parent.parent / name,
    ]
    for path in candidates:
        if (path / marker).exists():
            return path
    raise S2CLError(f"s2cl's {name}/ folder is missing (looked in {', '.join(map(str, candidates))}); reinstall s2cl")


def kernel_dir() -> Path:
    """Directory of the OpenCL sources."""
    return shipped_dir("kernels", "common")


def scene_dir() -> Path:
    """Directory of the built-in scenes."""
    return shipped_dir("scenes", "default.toml")


@cache
def code_fingerprint() -> str:
    """SHA-256 (hex) of s2cl's package (sources and data) and its OpenCL kernels: it keys results that a
    code change could alter (a resumed sweep never reuses chunks computed by other code)."""
    h = hashlib.sha256()
    for root in (Path(__file__).resolve().parent, kernel_dir()):
        for path in sorted(p for p in root.rglob("*") if p.is_file() and "__pycache__" not in p.parts):
            h.update(path.relative_to(root).as_posix().encode() + b"\0" + path.read_bytes())
    return h.hexdigest()
