"""Three-channel water vapour (paper Sect. 5: "a channel around 1020 nm for an improved three-channel water vapor
retrieval"): APDA with a second window channel above B9, against the two-channel B8a/B9 retrieval.

The second window is [study] ``window2`` (:class:`s2cl.scene.schema.WindowSpec`): a channel that is not in the
sensor (default name N1020), swept over its centres × widths, with the SNR model of the sensor band
``window2.noise_band`` (default B9, the 60 m atmospheric band) rescaled to each width exactly as a swept band's
(:meth:`s2cl.sensor.sensor.Band.with_shape`); its noise stream is the band slot after the [sweep] bands.

Retrieval (:mod:`s2cl.studies.water_vapour`, same LUT terms, truth, noise and crossing): the continuum at the
absorption band is linear in wavelength between the two windows, weights
``a_8a = (λ_w − λ_9)/(λ_w − λ_8a)`` and ``a_w = (λ_9 − λ_8a)/(λ_w − λ_8a)`` (band centres), so the measured ratio
is Schläpfer et al.'s (1998) APDA ratio ``(L9 − Lp9) / (a_8a (L8a − Lp8a) + a_w (Lw − Lpw))`` and its model the
same ratio for a surface whose B9 reflectance is ``a_8a ρ_8a + a_w ρ_w``. With one window (a_w = 0) it is the
two-channel retrieval. The two-channel and three-channel retrievals see the same noisy pixels.

Reported: relative RMS of the retrieved column (%) per target class, with noise and without (the surface-shape
error alone), for the two-channel retrieval and every window variant; the continuum error at B9 of each target
(surface reflectance only); each band's water sensitivity (drop of its ground term over the retrieval axis);
winter scenes with the winter and the summer LUT terms for both retrievals.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from s2cl.errors import InputError
from s2cl.libraries.library import SpectralLibrary
from s2cl.sensor.variants import BandGrid, SweepSpace
from s2cl.studies.common import KeyFigure, StudyResult, StudySetup, apply
from s2cl.studies.water_vapour import (
    SUMMER,
    WINTER,
    Retrieval,
    Truth,
    band_weights,
    continuum,
    interpolation_weights,
    lut_terms,
    reference,
    retrieve_continuum,
    scores,
    winter_scores,
    wv_axis,
)

#: what the study needs: bands in [sweep], non-empty [study] keys (checked by s2cl.studies.run_study)
NEEDS_BANDS, NEEDS_KEYS = ("B9", "B8a"), ("water_vapour", "targets", "window2")
ABSORPTION, WINDOW = "B9", "B8a"
Terms = dict[str, list[dict[str, np.ndarray]]]
Ref = tuple[np.ndarray, np.ndarray]


def window_grid(setup: StudySetup, space: SweepSpace) -> BandGrid:
    """The [study] ``window2`` channel's variants, checked: a name no sensor band has, a ``noise_band`` the sensor
    has, model SRFs inside the spectral grid, and every variant's FWHM interval above every B9 variant's (the
    continuum is interpolated, not extrapolated, and the window must not see the absorption band).

    :raises InputError: naming ``study.window2`` and the rule broken.
    """
    w = setup.study.window2
    assert w is not None  # run_study's check_needs
    src, key = setup.source, "study.window2"
    if w.name.lower() in (n.lower() for n in setup.scene.sensor.band_names):
        raise InputError(f"{w.name!r} is a sensor band; name the new window channel otherwise (e.g. 'N1020')",
                         source=src, key=f"{key}.name")
    setup.band(w.name)   # the noise band exists
    grid = BandGrid(w.name, tuple(w.centres), tuple(w.widths))
    support = setup.scene.run.support
    lo, hi = grid.support_extent(support)
    if not setup.scene.grid.covers(lo, hi):
        raise InputError(f"the channel's SRFs (centre ± {support:g} × width, sensor.support) reach {lo:g}–{hi:g} nm, "
                         f"outside the spectral grid {setup.scene.grid.describe()}", source=src, key=key)
    b9 = space.per_band[space.bands.index(ABSORPTION)]
    top9 = float(np.max(b9[:, 0] + b9[:, 1] / 2))
    low = min(c - wd / 2 for c in w.centres for wd in w.widths)
    if low < top9:
        raise InputError(f"the channel's variants reach down to {low:g} nm (centre − width/2), into the absorption "
                         f"band {ABSORPTION} (its variants reach up to {top9:g} nm); the second window must lie "
                         f"above {top9:g} nm", source=src, key=key)
    return grid


def _continua(shapes: dict[str, np.ndarray], i9: int, i8: int, name: str, i8_refs: Ref, w_refs: list[Ref]
              ) -> list[Ref]:
    """The three-channel continuum of B9 variant ``i9`` and B8a variant ``i8`` with every window variant."""
    c9, c8 = shapes[ABSORPTION][i9, 0], shapes[WINDOW][i8, 0]
    out = []
    for j, ref in enumerate(w_refs):
        a = interpolation_weights([c8, shapes[name][j, 0]], c9)
        out.append(continuum([i8_refs, ref], a))
    return out


def _surface_continuum(targets: dict[str, SpectralLibrary], weights: dict, shapes: dict[str, np.ndarray],
                       name: str, i9: int, i8: int, jw: int) -> dict[str, dict[str, float]]:
    """Mean |ρ_c − ρ_9| / ρ_9 (%) of each target class at B9 from the surface reflectance alone: the continuum
    error the retrieval's assumption makes, two-channel (ρ_c = ρ_8a) and three-channel (linear in wavelength)."""
    a = interpolation_weights([shapes[WINDOW][i8, 0], shapes[name][jw, 0]], shapes[ABSORPTION][i9, 0])
    out: dict[str, dict[str, float]] = {"two": {}, "three": {}}
    for label, lib in targets.items():
        r9 = apply(weights[ABSORPTION][i9], lib.spectra)
        r8 = apply(weights[WINDOW][i8], lib.spectra)
        rw = apply(weights[name][jw], lib.spectra)
        out["two"][label] = float(100 * np.mean(np.abs(r8 - r9) / r9))
        out["three"][label] = float(100 * np.mean(np.abs(a[0] * r8 + a[1] * rw - r9) / r9))
    return out


def _score_all(setup: StudySetup, space: SweepSpace, name: str, variants: dict[str, np.ndarray],
               weights: dict, targets: dict[str, SpectralLibrary], axis: np.ndarray, lut: Terms
               ) -> tuple[list[dict[str, float]], list[list[dict[str, float]]]]:
    """Two-channel scores per [sweep] configuration and three-channel scores per configuration × window variant."""
    truth = Truth(setup, SUMMER, variants, weights, targets)
    refs8 = [reference(L, t) for L, t in zip(truth.radiance[WINDOW], lut[WINDOW], strict=True)]
    refs_w = [reference(L, t) for L, t in zip(truth.radiance[name], lut[name], strict=True)]
    two, three = [], []
    for i9, i8 in space.indices(0, space.size):
        L9, t9 = truth.radiance[ABSORPTION][i9], lut[ABSORPTION][i9]
        two.append(scores(retrieve_continuum(L9, t9, axis, refs8[i8]), truth))
        three.append([scores(retrieve_continuum(L9, t9, axis, cont), truth)
                      for cont in _continua(variants, i9, i8, name, refs8[i8], refs_w)])
    return two, three


def run(setup: StudySetup) -> StudyResult:
    space = setup.space()
    grid = window_grid(setup, space)
    k = setup.nominal(space)
    name = grid.band
    variants = {b: space.per_band[i] for i, b in enumerate(space.bands)}
    variants[name] = grid.variants()
    weights = band_weights(setup, variants)
    targets = setup.targets()
    axis = wv_axis(setup)
    lut = lut_terms(setup, SUMMER, axis, weights)
    two, three = _score_all(setup, space, name, variants, weights, targets, axis, lut)
    quiet = replace(setup, scene=replace(setup.scene, effects=replace(setup.scene.effects, noise=False)),
                    study=setup.study.model_copy(update={"pixels": 1}))
    two_nf, three_nf = _score_all(quiet, space, name, variants, weights, targets, axis, lut)
    classes = list(two[0])
    shapes = space.shapes(0, space.size)
    wvar = variants[name]
    w = setup.study.window2
    assert w is not None
    head = int(np.flatnonzero((wvar[:, 0] == w.centre) & (wvar[:, 1] == w.width))[0])
    best = int(np.argmin([s["all"] for s in three[k]]))
    i9, i8 = space.indices(0, space.size)[k]

    # winter scenes, nominal B9/B8a with the headline and the best window (one noise stream per band, as in the
    # sweep): both retrievals on the same noisy pixels
    nom = {ABSORPTION: [i9], WINDOW: [i8], name: [head, best]}
    nom_vars = {b: variants[b][i] for b, i in nom.items()}
    nom_weights = {b: [weights[b][j] for j in i] for b, i in nom.items()}
    c9, c8 = variants[ABSORPTION][i9, 0], variants[WINDOW][i8, 0]

    def retrieval(jw: int | None) -> Retrieval:
        """Two-channel (``jw`` None) or three-channel with window variant ``jw`` of ``nom[name]``."""
        def run_one(rad: dict[str, np.ndarray], lt: Terms) -> np.ndarray:
            refs = [reference(rad[WINDOW][0], lt[WINDOW][0])]
            centres = [c8]
            if jw is not None:
                refs.append(reference(rad[name][jw], lt[name][jw]))
                centres.append(nom_vars[name][jw, 0])
            return retrieve_continuum(rad[ABSORPTION][0], lt[ABSORPTION][0], axis,
                                      continuum(refs, interpolation_weights(centres, c9)))
        return run_one

    winter = winter_scores(setup, axis, nom_vars, nom_weights,
                           {b: [lut[b][j] for j in i] for b, i in nom.items()}, targets,
                           {"two": retrieval(None), "three": retrieval(0), "three_best": retrieval(1)})
    surface = _surface_continuum(targets, weights, variants, name, i9, i8, head)

    def band(b: str, i: int) -> str:
        return f"{variants[b][i, 0]:g}/{variants[b][i, 1]:g}"

    b9, b8 = band(ABSORPTION, i9), band(WINDOW, i8)
    rows = [["two-channel", b9, b8, "–", *(f"{two[k][c]:.2f}" for c in classes)],
            ["  no noise", b9, b8, "–", *(f"{two_nf[k][c]:.2f}" for c in classes)],
            [f"three-channel, {name}", b9, b8, band(name, head), *(f"{three[k][head][c]:.2f}" for c in classes)],
            ["  no noise", b9, b8, band(name, head), *(f"{three_nf[k][head][c]:.2f}" for c in classes)],
            [f"best {name} (all)", b9, b8, band(name, best), *(f"{three[k][best][c]:.2f}" for c in classes)],
            ["  no noise", b9, b8, band(name, best), *(f"{three_nf[k][best][c]:.2f}" for c in classes)]]
    for tag, cw_ in (("two", "–"), ("three", band(name, head)), ("three_best", band(name, best))):
        for prof, lab in ((WINTER, "winter LUT"), (SUMMER, "summer LUT")):
            rows.append([f"winter, {lab}, {tag.replace('_', ' ')}", b9, b8, cw_,
                         *(f"{winter[tag][prof][c]:.2f}" for c in classes)])
    figures = [KeyFigure(f"relative RMS of WV, three-channel ({name} {band(name, head)}) minus two-channel, {c}",
                         round(three[k][head][c] - two[k][c], 2), None, "pp",
                         f"{two[k][c]:.2f} → {three[k][head][c]:.2f} %; paper: third channel 'improved'")
               for c in classes]
    def increase(tag: str, c: str) -> float:
        return 100 * (winter[tag][SUMMER][c] / winter[tag][WINTER][c] - 1)

    figures += [KeyFigure(f"winter scenes with the summer LUT, three-channel: RMS increase, {c}",
                          round(increase("three", c), 1), 6.0, "% of the RMS",
                          f"two-channel: {increase('two', c):+.1f} %; paper (two-channel): +6 %") for c in classes]
    data = {
        "water_vapour_true": list(setup.study.water_vapour), "retrieval_axis": axis.tolist(),
        "targets": {t: lib.names for t, lib in targets.items()}, "pixels": setup.study.pixels,
        "bands": space.bands, "configurations": shapes.tolist(), "nominal_configuration": int(k),
        "window": {"name": name, "noise_band": w.noise_band, "variants": wvar.tolist(), "headline": head,
                   "best": best},
        "two_channel": {"rel_rms_pct": {c: [s[c] for s in two] for c in classes},
                        "rel_rms_pct_no_noise": {c: [s[c] for s in two_nf] for c in classes}},
        "three_channel": {"rel_rms_pct": {c: [[s[c] for s in row] for row in three] for c in classes},
                          "rel_rms_pct_no_noise": {c: [[s[c] for s in row] for row in three_nf] for c in classes}},
        "continuum_error_pct": surface,
        # how much of a window each band is: drop of its ground term G over the retrieval axis (assumed state)
        "water_sensitivity_pct": {b: [float(100 * (1 - t["g"][-1] / t["g"][0])) for t in lut[b]] for b in lut},
        "winter": winter,
    }
    return StudyResult(
        title=f"Water vapour, three-channel APDA (B8a + {name} windows) vs two-channel: relative RMS of WV (%)",
        columns=["case", "B9 c/w", "B8a c/w", f"{name} c/w", *classes], rows=rows, key_figures=figures, data=data,
        notes=[f"true WV {', '.join(f'{x:g}' for x in setup.study.water_vapour)} g/cm²; {setup.study.pixels} noisy "
               f"pixels per target and column, the same for both retrievals; {name} noise: {w.noise_band}'s SNR model "
               "at each width; 'no noise': the surface-shape (continuum) error alone."])
