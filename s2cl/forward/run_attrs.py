"""The run's global attributes of a simulation (``simulation.nc``, the in-memory Datasets, ``simulation.json``),
built in one place for a library scene and an image cube alike."""

from __future__ import annotations

from typing import Any

from s2cl.forward.parts import ChainParts
from s2cl.forward.stages import image_stage_names
from s2cl.version import __version__


def run_attrs(parts: ChainParts, device: str, *, image: bool) -> dict[str, Any]:
    """What ran: the scene's name and file (``""`` for a scene built in memory), the s2cl version, the OpenCL
    ``device``'s name, the precision, the stages that ran (an image runs them all; a library scene not the image-only
    ones, :func:`s2cl.forward.stages.image_stage_names`) and the noise seed; a library scene (``image`` False) adds its
    image layout."""
    r = parts.run
    attrs: dict[str, Any] = dict(scene=parts.name, scene_file=parts.scene_file, s2cl_version=__version__,
                                 device=device, precision=r.precision,
                                 effects=parts.effects.describe(frozenset() if image else image_stage_names()),
                                 seed=r.seed)
    if not image:
        attrs["layout"] = r.layout
    return attrs
