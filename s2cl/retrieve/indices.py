"""Normalised-difference band indices, regressed (second order) on a library parameter.

One formula serves them all, with a pair of offsets per index::

    index = ((ρ_a + o_a) - (ρ_b + o_b)) / ((ρ_a + o_a) + (ρ_b + o_b))

and one validity rule (``kernels/common/stages.mako``, ``normalised_difference``): both reflectances
finite and within ``max_abs``, both offset terms positive, else status INVALID and index 0. The
index then lies in (-1, 1).

:data:`INDICES` is the registry: one entry makes an analysis family (:mod:`s2cl.retrieve.families.index`): an
``[analysis] kind`` with its band-role keys, its design rule, device function, sweep code and numpy twin. Each role
names a scene key (``nir = "B8"``) and the sensor band used when the scene names none.
"""

from __future__ import annotations

from dataclasses import dataclass

from s2cl.errors import InputError


@dataclass(frozen=True)
class NormalisedDifference:
    """A normalised-difference index of bands ``a`` and ``b``.

    :param kind: the ``[analysis] kind`` that selects it.
    :param title: its name, with the reference that defines it.
    :param roles: scene keys of band a and band b (e.g. ``("nir", "swir")``).
    :param offsets: reflectance offsets (o_a, o_b) added before the difference, unitless.
    :param default_bands: sensor bands used for roles the scene leaves out.
    :param parameter: the library parameter it is usually regressed on (documentation and examples).
    """

    kind: str
    title: str
    roles: tuple[str, str]
    offsets: tuple[float, float]
    default_bands: tuple[str, str]
    parameter: str


#: every normalised-difference index the scenes can name, by ``[analysis] kind``
INDICES: dict[str, NormalisedDifference] = {
    index.kind: index for index in (
        NormalisedDifference("gvmi", "Global Vegetation Moisture Index (Ceccato et al. 2002; Segl et al. 2012 eq. 3)",
                             roles=("nir", "swir"), offsets=(0.1, 0.02), default_bands=("B8", "B11"),
                             parameter="ewt"),
        NormalisedDifference("ndvi", "Normalised Difference Vegetation Index (Rouse et al. 1974)",
                             roles=("nir", "red"), offsets=(0.0, 0.0), default_bands=("B8", "B4"), parameter="lai"),
    )
}



def index_of(kind: str) -> NormalisedDifference:
    """The registered index ``kind``; :class:`InputError` naming the known ones otherwise."""
    try:
        return INDICES[kind]
    except KeyError:
        raise InputError(f"unknown index {kind!r}; known: {', '.join(INDICES)}", key="analysis.kind") from None
