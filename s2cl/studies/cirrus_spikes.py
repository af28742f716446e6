"""6S's transmittance spikes near 1375 nm, for the B10 cirrus study (:mod:`s2cl.studies.cirrus`).

6S computes H₂O absorption on its own 2.5 nm grid (0.25 µm + k·2.5 nm) with a 10 cm⁻¹ band model; near
1.38 µm single samples stand far above both neighbours. The study measures what they do to the key figure
by removing them and recomputing the radiance:

- the LUT stores the 2.5 nm samples linearly interpolated to 1 nm, so :func:`sixs_samples`
  recovers them from the 1 nm water transmittance (exactly at LUT nodes);
- a sample is an **isolated spike** (:func:`isolated_spikes`) when its transmittance exceeds both
  neighbours' and its optical depth τ = −ln T is below ``1 − SPIKE_DIP`` = 2/3 of the mean of its
  neighbours' optical depths, i.e. ``T_k > (T_k−1 · T_k+1)^(1/3)``. Only samples in
  :data:`SPIKE_REGION_NM` (1360–1410 nm) are tested;
- a spike is replaced by the geometric mean of its neighbours (linear in ln T), and the test is
  repeated until no sample qualifies, so a shoulder left beside a removed spike is tested again
  (:func:`remove_spikes`);
- ground term and aerosol path radiance scale with the new water transmittance, the Rayleigh path
  does not (6S puts water vapour above the aerosol) (:func:`despiked_terms`).

Wavelengths in nm, transmittances unitless, radiances W m⁻² sr⁻¹ µm⁻¹.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

import numpy as np

from s2cl.atmos.state import AtmosphereState
from s2cl.atmos.terms import AtmosphericTerms
from s2cl.errors import InputError
from s2cl.studies.common import StudySetup

SIXS_STEP_NM = 2.5
"""6S's gas-absorption sampling step (its samples lie at 250 nm + k·2.5 nm)."""
SPIKE_REGION_NM = (1360.0, 1410.0)
"""6S samples tested for isolated spikes, nm (their outer neighbours 1357.5 and 1412.5 nm are not)."""
SPIKE_DIP = 1.0 / 3.0
"""A spike's optical depth is below ``1 − SPIKE_DIP`` of its neighbours' mean optical depth."""
SINGLE_SPIKE_NM = 1397.5
"""The sample the earlier explanation blamed alone; the study also removes just this one."""
SPIKE_RULE = (f"a 6S sample in {SPIKE_REGION_NM[0]:g}-{SPIKE_REGION_NM[1]:g} nm whose water transmittance exceeds "
              f"both neighbours' and whose optical depth is below {1 - SPIKE_DIP:.3g} of their mean; replaced by "
              "the neighbours' geometric mean, repeated until none is left")
CASES = {"as_6s": "as 6S gives them", "single_removed": f"{SINGLE_SPIKE_NM:g} nm removed",
         "spikes_removed": "spikes removed"}
"""Water transmittance as 6S gives it, with only :data:`SINGLE_SPIKE_NM` removed, with every isolated spike
removed: JSON key -> table label."""


def spike_nodes(region_nm: tuple[float, float] = SPIKE_REGION_NM) -> np.ndarray:
    """6S's sample wavelengths (nm) from one step below ``region_nm`` to one step above it."""
    lo, hi = region_nm
    n = round((hi - lo) / SIXS_STEP_NM) + 2
    return lo - SIXS_STEP_NM + SIXS_STEP_NM * np.arange(n + 1)


def spike_dips(t: np.ndarray) -> np.ndarray:
    """Optical-depth dip ``1 − τ_k / mean(τ_k−1, τ_k+1)`` (τ = −ln t) of each interior sample of a
    transmittance ``t (n,)``; NaN where the sample does not exceed both neighbours. Shape ``(n − 2,)``."""
    t = np.clip(np.asarray(t, dtype=np.float64), 1e-30, 1.0)
    tau = -np.log(t)
    mean = 0.5 * (tau[:-2] + tau[2:])
    peak = (t[1:-1] > t[:-2]) & (t[1:-1] > t[2:])   # a peak's neighbours have τ > 0
    return np.where(peak, 1.0 - tau[1:-1] / np.where(peak, mean, 1.0), np.nan)


def isolated_spikes(t: np.ndarray, dip: float = SPIKE_DIP) -> np.ndarray:
    """Indices of the isolated spikes of a sampled transmittance ``t (n,)``: interior samples above
    both neighbours whose optical-depth dip (:func:`spike_dips`) exceeds ``dip``."""
    d = spike_dips(t)
    return np.flatnonzero(np.nan_to_num(d, nan=-1.0) > dip) + 1


def replace_samples(t: np.ndarray, idx: Sequence[int]) -> np.ndarray:
    """Copy of ``t`` with each sample ``idx`` replaced by the geometric mean of its neighbours (linear
    in ln t); the samples ``idx`` must be interior and not adjacent."""
    out = np.array(t, dtype=np.float64)
    k = np.asarray(idx, dtype=int)
    out[k] = np.sqrt(out[k - 1] * out[k + 1])
    return out


def remove_spikes(t: np.ndarray, dip: float = SPIKE_DIP,
                  keep: Sequence[int] = ()) -> tuple[np.ndarray, list[list[int]]]:
    """Remove isolated spikes (:func:`isolated_spikes`) until none is left.

    Each pass replaces all spikes found (never adjacent: a spike's neighbours are below it) by
    :func:`replace_samples`; the next pass tests the result again.

    :param t: transmittance samples ``(n,)``, 0 < t ≤ 1.
    :param keep: indices never removed (to measure what one spike does).
    :returns: the new samples and the indices removed in each pass.
    """
    out = np.array(t, dtype=np.float64)
    passes: list[list[int]] = []
    for _ in range(out.size):
        k = [int(i) for i in isolated_spikes(out, dip) if i not in keep]
        if not k:
            break
        out = replace_samples(out, k)
        passes.append(k)
    return out, passes


def sixs_samples(wl: np.ndarray, values: np.ndarray, nodes: np.ndarray) -> tuple[np.ndarray, float]:
    """Samples at 6S's wavelengths ``nodes`` (nm) of a curve given on grid ``wl`` (nm) as their linear
    interpolation (how the LUT stores 6S's gas transmittance): least squares over the grid points
    from ``nodes[0]`` to ``nodes[-1]``.

    :returns: the samples ``(n_nodes,)`` and the largest absolute residual on the grid (0 up to
        rounding at LUT nodes; off-node states mix two such curves in ln T, a few 1e-4 at most).
    :raises InputError: if the grid does not resolve the nodes (too coarse).
    """
    sel = (wl >= nodes[0] - 1e-9) & (wl <= nodes[-1] + 1e-9)
    m = np.stack([np.interp(wl[sel], nodes, e) for e in np.eye(nodes.size)], axis=1)
    if np.linalg.matrix_rank(m) < nodes.size:
        raise InputError(f"the grid does not resolve 6S's {SIXS_STEP_NM:g} nm samples in "
                         f"{nodes[0]:g}–{nodes[-1]:g} nm (needs about 1 nm steps)", key="grid")
    samples = np.linalg.lstsq(m, values[sel], rcond=None)[0]
    return samples, float(np.abs(m @ samples - values[sel]).max())


def despiked_terms(terms: AtmosphericTerms, rayleigh: AtmosphericTerms, nodes: np.ndarray,
                   t_water_nodes: np.ndarray) -> AtmosphericTerms:
    """``terms`` with the water transmittance from ``nodes[0]`` to ``nodes[-1]`` (nm) replaced by the
    linear interpolation of ``t_water_nodes``.

    Ground term, ``t_gas`` and the aerosol part of the path radiance scale with the water
    transmittance; the Rayleigh part does not (6S: water vapour above the aerosol).

    :param rayleigh: terms of the same state at AOT550 = 0 (path radiance = the Rayleigh part).
    """
    wl = terms.wavelength_nm
    sel = (wl >= nodes[0] - 1e-9) & (wl <= nodes[-1] + 1e-9)
    t_new = np.array(terms.t_water, dtype=np.float64)
    t_new[sel] = np.interp(wl[sel], nodes, t_water_nodes)
    r = np.divide(t_new, terms.t_water, out=np.ones_like(t_new), where=terms.t_water > 0)
    lp, rho = rayleigh.path_radiance, rayleigh.path_reflectance
    return dataclasses.replace(
        terms,
        path_radiance=lp + r * (terms.path_radiance - lp),
        path_reflectance=rho + r * (terms.path_reflectance - rho),
        ground_term=terms.ground_term * r,
        t_gas=terms.t_gas * r,
        transmittance={**terms.transmittance, "water": t_new},
    )


@dataclasses.dataclass
class Spikes:
    """One water-vapour state: 6S's samples, what the rule removed, and the TOA radiance per case."""

    nodes: np.ndarray
    t_6s: np.ndarray
    t_removed: np.ndarray
    passes: list[list[int]]
    residual: float
    radiance: dict[str, np.ndarray]        # CASES -> (n_wl,)
    per_spike: dict[str, dict[str, np.ndarray]]   # "alone"/"all_but" -> "1390" -> (n_wl,)

    def removed_nm(self) -> list[float]:
        """The removed samples' wavelengths (nm), increasing."""
        return sorted(float(self.nodes[k]) for p in self.passes for k in p)

    def to_json(self) -> dict:
        """Removed samples, the dips (:func:`spike_dips`) of 6S's peaks, of each removed sample when it
        was removed, and the largest dip left (the margin below :data:`SPIKE_DIP`)."""
        t, at_removal = self.t_6s, {}
        for p in self.passes:
            d = spike_dips(t)
            at_removal.update({f"{self.nodes[k]:g}": round(float(d[k - 1]), 4) for k in p})
            t = replace_samples(t, p)
        return {
            "removed_nm": self.removed_nm(),
            "passes_nm": [[float(self.nodes[k]) for k in p] for p in self.passes],
            "optical_depth_dip": _peaks(self.nodes, self.t_6s),
            "dip_at_removal": at_removal,
            "largest_dip_left": max(_peaks(self.nodes, self.t_removed).values(), default=None),
            "t_water_6s": self.t_6s.tolist(),
            "t_water_spikes_removed": self.t_removed.tolist(),
            "recovery_residual": self.residual,
        }


def _peaks(nodes: np.ndarray, t: np.ndarray) -> dict[str, float]:
    """Dip of every sample above both neighbours, keyed by its wavelength (nm)."""
    return {f"{nodes[k + 1]:g}": round(float(d), 4) for k, d in enumerate(spike_dips(t)) if np.isfinite(d)}


def spikes_of(setup: StudySetup, state: AtmosphereState, rho: float) -> Spikes:
    """6S's samples of one state's water transmittance, the spikes the rule removes, and the TOA radiance over
    reflectance ``rho`` for each of :data:`CASES` and with each first-pass spike removed alone or kept alone."""
    terms = setup.terms(state)
    rayleigh = setup.terms(state.replace(aot550=0.0))
    nodes = spike_nodes()
    try:
        t6s, residual = sixs_samples(terms.wavelength_nm, terms.t_water, nodes)
    except InputError as err:
        raise InputError(err.detail, source=setup.source, key="grid") from None
    surface = np.full(terms.wavelength_nm.size, rho)

    def radiance(t_nodes: np.ndarray) -> np.ndarray:
        return despiked_terms(terms, rayleigh, nodes, t_nodes).toa_radiance(surface)

    removed, passes = remove_spikes(t6s)
    single = int(np.argmin(np.abs(nodes - SINGLE_SPIKE_NM)))
    cases = dict(zip(CASES, (terms.toa_radiance(surface), radiance(replace_samples(t6s, [single])),
                             radiance(removed)), strict=True))
    first = passes[0] if passes else []
    per_spike = {
        "alone": {f"{nodes[k]:g}": radiance(replace_samples(t6s, [k])) for k in first},
        "all_but": {f"{nodes[k]:g}": radiance(remove_spikes(t6s, keep=[k])[0]) for k in first},
    }
    return Spikes(nodes, t6s, removed, passes, residual, cases, per_spike)
