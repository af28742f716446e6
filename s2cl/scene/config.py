"""The resolved run configuration: everything downstream needs to know about how a scene runs, read from
the TOML once, at load, and frozen. Only :mod:`s2cl.scene` reads the raw TOML; engines, sweeps and
studies read :attr:`s2cl.scene.scene.Scene.run`.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

from s2cl.cl.vectypes import VALID_LANES
from s2cl.errors import InputError
from s2cl.scene.effects import EffectSet
from s2cl.scene.schema import SceneSpec

_log = logging.getLogger(__name__)


@dataclass(frozen=True)
class RunConfig:
    """How a scene runs (hashable: it can key caches).

    :param effects: the stages of the chain.
    :param seed, frame: the noise stream (Philox key and counter word).
    :param support: SRF support, ± this many FWHM around each band centre.
    :param precision: ``"float32"`` or ``"float64"``, the working precision of every kernel.
    :param lanes: pixels per work-item of the vectorised kernels (None: the device's choice).
    :param device: the OpenCL device the scene asks for (None: the default; the CLI's ``--device`` wins).
    :param calibration_gain: [correction] calibration_gain (1.0: none), the shorthand of a common calibration error.
    :param copies: noisy copies per library spectrum.
    :param layout: ``"rows"`` or ``"blocks"``: how library pixels are laid out as an image.
    """

    effects: EffectSet
    seed: int
    frame: int
    support: float
    precision: str
    lanes: int | None
    device: str | None
    calibration_gain: float
    copies: int
    layout: str


def resolve_run(spec: SceneSpec, effects: EffectSet, source: str) -> RunConfig:
    """The :class:`RunConfig` of a validated scene. ``output.precision`` still works (it moved to
    ``compute.precision``, which is where it changes the computation) and says so at WARNING level."""
    precision = spec.compute.precision
    if spec.output.precision is not None:
        if "precision" in spec.compute.model_fields_set and spec.compute.precision != spec.output.precision:
            raise InputError(f"output.precision ({spec.output.precision}) and compute.precision "
                             f"({spec.compute.precision}) disagree; keep compute.precision only", source=source,
                             key="output.precision")
        _log.warning("%s: output.precision is deprecated: write it as compute.precision", source)
        precision = spec.output.precision
    if spec.compute.lanes is not None and spec.compute.lanes not in VALID_LANES:
        raise InputError(f"must be one of {VALID_LANES}, got {spec.compute.lanes}", source=source,
                         key="compute.lanes")
    return RunConfig(effects=effects, seed=spec.effects.seed, frame=spec.effects.frame,
                     support=spec.sensor.support, precision=precision, lanes=spec.compute.lanes,
                     device=spec.compute.device, calibration_gain=spec.correction.calibration_gain,
                     copies=spec.surface.copies, layout=spec.surface.layout)
