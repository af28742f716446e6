"""The paper's atmospheric-band studies (Segl et al. 2012, Sec. 3) and the spectral-stability study:
``s2cl study NAME``.

Each study is a scene ``scenes/study-NAME.toml`` with a [study] section (what varies besides the
bands) and a [sweep] section (the band variants, :mod:`s2cl.sensor.variants`), and a module here with a
``run(setup) -> StudyResult`` that computes only. :func:`run_study` loads the scene, runs the study and writes
``NAME.json`` and ``NAME.png`` atomically; the figure is drawn from the JSON's ``data`` alone
(:mod:`s2cl.studies.plots`), so :func:`replot` redraws it from a saved ``NAME.json``. The ``stability`` study
has no [sweep] of its own: its [study] names application scenes whose bands it drifts (:mod:`s2cl.studies.drift`).
The ``cellulose`` study scores the 2.1 µm band the paper recommends (Sec. 5) against Sentinel-2's own SWIR bands.
The ``instrument`` study puts each instrument effect ([instrument]) alone on a parcel image and reports its cost
against the ideal instrument (:mod:`s2cl.studies.instrument`).
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

from s2cl.errors import InputError
from s2cl.io.outdir import check_output_dir, claim
from s2cl.io.output import write_json
from s2cl.scene.scene import Scene
from s2cl.studies import (
    aerosol,
    cellulose,
    cirrus,
    instrument,
    methane,
    ozone,
    stability,
    water_vapour,
    water_vapour_1020,
)
from s2cl.studies.common import StudyResult, StudySetup, load_study
from s2cl.studies.plots import replot
from s2cl.version import __version__

_MODULES = {"cirrus": cirrus, "water-vapour": water_vapour, "water-vapour-1020": water_vapour_1020,
            "aerosol": aerosol, "ozone": ozone, "methane": methane,
            "stability": stability, "cellulose": cellulose, "instrument": instrument}
STUDIES: dict[str, Callable[[StudySetup], StudyResult]] = {name: m.run for name, m in _MODULES.items()}

__all__ = ["STUDIES", "StudyResult", "replot", "run_study", "study_scene"]


def study_scene(name: str) -> Scene:
    """The built-in scene ``study-NAME`` (or a scene file with a [study] section)."""
    if name.endswith(".toml") or Path(name).is_file():
        return Scene.load(name)
    if name not in STUDIES:
        raise InputError(f"unknown study {name!r}; studies: {', '.join(STUDIES)}")
    return Scene.load(f"study-{name}")


def check_needs(setup: StudySetup) -> None:
    """The study kind's bands are in [sweep] and the [study] lists it reads are not empty (each study module's
    ``NEEDS_BANDS`` and ``NEEDS_KEYS``), checked before any work."""
    kind = setup.study.kind
    module = _MODULES[kind]
    for key in module.NEEDS_KEYS:
        if not getattr(setup.study, key):
            raise InputError(f"the {kind} study needs at least one value here", source=setup.source,
                             key=f"study.{key}")
    sweep = setup.scene.spec.sweep
    swept = {b.lower() for b in sweep.bands} if sweep else set()
    missing = [b for b in module.NEEDS_BANDS if b.lower() not in swept]
    if missing:
        raise InputError(f"the {kind} study varies band(s) {', '.join(missing)}: list them in sweep.bands (with "
                         "their ranges)", source=setup.source, key="sweep.bands")


def run_study(name: str, *, quick: bool = False, output: Path | None = None) -> tuple[StudyResult, Path, Path]:
    """Run study ``name`` and write ``DIR/NAME.json`` and ``DIR/NAME.png`` (drawn from the JSON as written,
    :func:`replot`).

    :param output: the folder (default: s2cl-out/study-NAME).
    :returns: the result and the JSON and PNG paths.
    """
    scene = study_scene(name)
    setup = load_study(scene, quick=quick)
    check_needs(setup)
    out = Path(output) if output else Path("s2cl-out") / scene.name
    stem = setup.study.kind
    check_output_dir(out, where="--output" if output else f"scene.name in {scene.source}",
                     writes=(f"{stem}.json", f"{stem}.png"))
    result = STUDIES[stem](setup)
    with claim(out):
        payload = {"study": stem, **result.to_json(), "scene": scene.portable_source, "quick": quick,
                   "s2cl_version": __version__}
        js = write_json(out / f"{stem}.json", payload)
        png = replot(js, out / f"{stem}.png")
    return result, js, png
