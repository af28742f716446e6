"""Plots written to PNG, drawn off screen without touching matplotlib's global backend (a notebook or an
application that imports s2cl keeps its own)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from s2cl.io.output import atomic_path

_FIGURE_KEYS = ("figsize", "dpi", "layout", "constrained_layout", "tight_layout", "facecolor")


class _Figures:
    """The part of ``matplotlib.pyplot`` s2cl draws with, on :class:`matplotlib.figure.Figure` objects that no
    pyplot state holds (``savefig`` renders them with Agg): no screen needed, no backend switched."""

    @staticmethod
    def subplots(nrows: int = 1, ncols: int = 1, **kwargs: Any) -> tuple[Any, Any]:
        from matplotlib.figure import Figure

        fig = Figure(**{k: kwargs.pop(k) for k in _FIGURE_KEYS if k in kwargs})
        return fig, fig.subplots(nrows, ncols, **kwargs)

    @staticmethod
    def figure(**kwargs: Any) -> Any:
        """A :class:`matplotlib.figure.Figure` (``figsize``, ``dpi``, ...) that no pyplot state holds."""
        from matplotlib.figure import Figure

        return Figure(**kwargs)

    @staticmethod
    def close(fig: Any) -> None:
        """Nothing to release: no pyplot state holds the figure."""

    @staticmethod
    def get_cmap(name: str) -> Any:
        import matplotlib

        return matplotlib.colormaps[name]

    @property
    def Rectangle(self) -> Any:
        from matplotlib.patches import Rectangle

        return Rectangle


def pyplot() -> Any:
    """What s2cl draws with (``subplots``, ``figure``, ``close``, ``get_cmap``, ``Rectangle``, as in
    ``matplotlib.pyplot``), without pyplot's global figures or backend."""
    return _Figures()


def save_png(fig: Any, path: str | Path, dpi: float | None = None, compress_level: int | None = None) -> Path:
    """Write ``fig`` as PNG atomically (temporary file + rename) and close it; ``compress_level``: zlib's level (1
    fastest … 9 smallest; default Pillow's, 6)."""
    extra = {} if compress_level is None else {"pil_kwargs": {"compress_level": compress_level}}
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", dpi=dpi, **extra)
    pyplot().close(fig)
    return Path(path)
