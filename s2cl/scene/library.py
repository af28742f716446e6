"""A scene's surface library: the file or built-in library it names, on its grid, with its ``surface.select``
ranges applied; checked once by :mod:`s2cl.app.checks` and handed to the engines from there."""

from __future__ import annotations

import numpy as np

from s2cl.errors import InputError, token
from s2cl.io.budget import Budget
from s2cl.libraries.library import SpectralLibrary
from s2cl.libraries.registry import load_library
from s2cl.scene.scene import Scene


def scene_library(scene: Scene, *, budget: Budget | None = None) -> SpectralLibrary:
    """The scene's spectral library on the scene's grid (a file sized against ``budget`` before it is read)."""
    spec = scene.spec.surface.library
    assert spec is not None
    want = scene.spec.surface.quantity
    lib = load_library(spec, scene.grid, source=scene.source, key="surface.library", quantity=want,
                       base_dir=scene.base_dir, budget=budget)
    if lib.quantity != want:
        raise InputError(f"library {token(spec)} holds {lib.quantity}, the scene says surface.quantity = {want!r}",
                         source=scene.source, key="surface.quantity")
    return _selected(scene, lib)


def _selected(scene: Scene, lib: SpectralLibrary) -> SpectralLibrary:
    """The spectra of ``lib`` whose parameters lie in the scene's ``surface.select`` ranges (all without one)."""
    keep = np.ones(lib.size, dtype=bool)
    for name, (low, high) in scene.spec.surface.select.items():
        if name not in lib.params:
            raise InputError(f"library has no parameter {name!r}; it has {', '.join(sorted(lib.params)) or 'none'}",
                             source=scene.source, key=f"surface.select.{name}")
        keep &= (lib.params[name] >= low) & (lib.params[name] <= high)
    if not keep.any():
        raise InputError("no spectrum of the library lies in these ranges", source=scene.source,
                         key="surface.select")
    return lib if keep.all() else lib.subset(np.flatnonzero(keep))
