"""Saved outputs of the forward chain, recomputed: library simulations, image cubes and sweeps, float32 and float64.

The outputs in ``tests/data/golden/`` were written by the code before the forward chain became declared stages
(issue 33); ``tests/test_golden_forward.py`` recomputes every case and compares bit for bit (``np.array_equal``,
NaN equal to NaN). A kernel's bits depend on the driver and code target (FMA contraction, the vector width), so
each file keeps one set of arrays per device it was written on (identical sets are stored once); a device with
none of its own is skipped by the test, with the devices that have one named.

Regenerate (only when a change of the outputs is intended, and say so in the commit) with

    python tests/golden_forward.py --device 0:0 --device 1:0

which adds or replaces the sets of those devices.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from s2cl.app.chain_parts import scene_simulator
from s2cl.app.image_simulation import simulate_image
from s2cl.app.library_simulation import simulate
from s2cl.cl.runtime import Runtime, get_runtime
from s2cl.scene.scene import Scene

GOLDEN = Path(__file__).resolve().parent / "data" / "golden"
PRECISIONS = ("float32", "float64")
Arrays = dict[str, np.ndarray]


def device_key(rt: Runtime) -> str:
    """The device as its kernels' bits depend on it: driver, version and device name (holds the code target)."""
    d = rt.device
    return (f"{rt.info.platform} {d.driver_version} | {rt.info.name} | lanes {rt.lanes('float32')}/"
            f"{rt.lanes('float64')}")


# -- cases ---------------------------------------------------------------------------------------------------------

def _lib_scene(name: str, precision: str, effects: dict[str, Any], **extra: Any) -> Scene:
    data: dict[str, Any] = {
        "scene": {"name": name},
        "surface": {"library": "builtin:lib1", "quantity": "reflectance", "copies": 3, "select": {"cab": [20, 45]}},
        "effects": {"atmosphere": True, "seed": 11, **effects},
        "compute": {"precision": precision}, **extra}
    return Scene.from_dict(data)


#: library scenes: the whole chain, corrected with another aerosol than the truth's; noise alone; no noise; 10 bits and
#: another frame. No case has a calibration error: [correction] calibration_gain, folded into the correction's terms
#: before issue 33, is since then the shorthand of the per-band calibration-error stage, which acts on the calibrated
#: radiance (the same reflectance up to rounding, tested in test_stages_new.py)
LIBRARY_CASES: dict[str, tuple[dict[str, Any], dict[str, Any]]] = {
    "lib-chain": ({"correct": True}, {"correction": {"aot550": 0.2}}),
    "lib-noise": ({"quantise": False, "calibrate": False}, {}),
    "lib-no-noise": ({"noise": False, "correct": True}, {}),
    "lib-bits10": ({"bits": 10, "frame": 5, "calibrate": False}, {"sensor": {"bands": ["B2", "B5", "B8A", "B12"]}}),
}


def library_case(rt: Runtime, name: str, precision: str) -> Arrays:
    effects, extra = LIBRARY_CASES[name]
    sim = simulate(_lib_scene(name, precision, effects, **extra), device=rt.info.spec)
    out = {"band_radiance": sim.band_radiance}
    for var in ("noisy", "dn", "flags", "calibrated", "reflectance", "clipped"):
        if getattr(sim, var) is not None:
            out[var] = getattr(sim, var)
    return out


def hard_case(rt: Runtime, precision: str) -> Arrays:
    """The radiometric stages on hard radiance: NaN, ±inf, zero, negative, below Lmin, saturated, at a DN's tie."""
    scene = Scene.from_dict({
        "scene": {"name": "hard"}, "surface": {"library": "builtin:lib1", "quantity": "radiance"},
        "sensor": {"bands": ["B2", "B4", "B11"]}, "effects": {"seed": 2}, "compute": {"precision": precision}})
    sim = scene_simulator(rt, scene)
    lmax = np.array([b.lmax for b in scene.sensor.bands])
    base = np.array([np.nan, np.inf, -np.inf, 0.0, -5.0, 1e-3, 1.0, 10.0, 80.0, 1e4, 1e30, -1e30])
    radiance = np.stack([np.concatenate([base, [lmax[k], lmax[k] * 0.999, lmax[k] * 1.2]]) for k in range(3)])
    out = sim.sense(radiance.astype(precision), seed=2, pixel_offset=7)
    assert out is not None
    return {k: getattr(out, k) for k in ("noisy", "dn", "flags", "calibrated", "clipped")}


def _cube_scene(name: str, precision: str, **extra: Any) -> Scene:
    data: dict[str, Any] = {
        "scene": {"name": name},
        "surface": {"cube": "builtin:fields:18x18", "gsd_m": 10.0, "quantity": "reflectance"},
        "effects": {"atmosphere": True, "correct": True, "seed": 5},
        "compute": {"precision": precision}, **extra}
    return Scene.from_dict(data)


def _dataset_arrays(ds: Any) -> Arrays:
    return {name: np.asarray(ds[name].values) for name in sorted(ds.data_vars)}


def cube_instrument_case(rt: Runtime, precision: str) -> Arrays:
    """A generated cube through every image effect (MTF, co-registration, smile, non-uniformity), given in the
    deprecated [instrument] section (still read: the same outputs as before issue 33)."""
    scene = _cube_scene("cube-instrument", precision, instrument={
        "mtf": True, "mtf_nyquist_bands": {"B5": 0.3}, "coregistration": True,
        "coregistration_shifts": {"B4": [0.2, -0.1]}, "smile": True, "smile_width_pct": [0.0, 1.0],
        "nonuniformity": True})
    return _dataset_arrays(simulate_image(rt, scene))


def cube_psf_case(rt: Runtime, precision: str) -> Arrays:
    """A radiance cube in memory with NaN pixels, through a Gaussian PSF of 1.5 band pixels FWHM, read in blocks of
    rows. Saved again after issue 33 made the [spatial] PSF the one PSF filter (the instrument's, with its reach):
    its radiance is the precision's now (float64 before, from scipy's filter), its values differ by float rounding
    inside and by the border rule (half-sample mirror, not nearest) near the edges, and a no-data pixel reaches the
    filter's support (tests/test_stages.py compares it with scipy's Gaussian inside)."""
    scene = Scene.from_dict({
        "scene": {"name": "cube-psf"}, "surface": {"cube": "cube.nc", "gsd_m": 10.0},
        "effects": {"seed": 6, "frame": 2, "psf": {"fwhm": 1.5}},
        "compute": {"precision": precision}})
    from s2cl.grid import DEFAULT_GRID

    rng = np.random.default_rng(3)
    wl = DEFAULT_GRID.wavelengths
    veg = 80.0 / (1.0 + np.exp(-(wl - 715.0) / 12.0)) + 20.0 * np.exp(-(((wl - 550) / 40) ** 2))
    soil = 30.0 + 0.02 * (wl - 400.0)
    cube = rng.uniform(0.2, 1.6, (24, 18, 1)) * np.where(rng.random((24, 18, 1)) < 0.5, veg, soil)
    cube[3, 4] = np.nan
    cube[20, 11, 100:200] = np.nan
    return _dataset_arrays(simulate_image(rt, scene, cube.astype(np.float32), block_rows=12))


def _sweep_job(name: str, precision: str) -> Any:
    from s2cl.app.plan import plan_sweep

    if name == "sweep-igrm":
        scene = _lib_scene(name, precision, {"correct": True}, correction={"water_vapour": 2.0},
                           analysis={"kind": "igrm", "parameter": "cab"},
                           sweep={"bands": ["B4", "B5", "B6", "B7"], "ranges": {
                               "B4": {"centres": [660, 670, 680], "widths": [20, 30]},
                               "B5": {"centres": [700, 705, 710], "widths": [10, 15]},
                               "B6": {"centres": [735, 745], "widths": [15, 20]},
                               "B7": {"centres": [775, 785], "widths": [20, 25]}}})
    else:
        scene = Scene.from_dict({
            "scene": {"name": name},
            "surface": {"library": "builtin:leaf-water", "quantity": "reflectance", "copies": 2},
            "effects": {"atmosphere": True, "correct": True, "seed": 4}, "compute": {"precision": precision},
            "sweep": {"bands": ["B8", "B11"], "ranges": {
                "B8": {"centres": [835, 842, 850], "widths": [100, 115]},
                "B11": {"left": 1500, "right": 1750, "min_width": 50, "max_width": 100}}},
            "analysis": {"kind": "gvmi", "parameter": "ewt", "nir": "B8", "swir": "B11"}})
    return plan_sweep(scene)


def _digest(a: np.ndarray) -> str:
    return hashlib.sha256(np.ascontiguousarray(a).tobytes()).hexdigest()


def sweep_case(rt: Runtime, name: str, precision: str) -> Arrays:
    """Per-configuration metrics (on the device) and the per-pixel outputs: raw for the first configurations,
    sha256 of the whole; a search's path too (designs gathered into their own tables, on one copy)."""
    from s2cl.sweep.design_tables import design_tables
    from s2cl.sweep.kernel import SweepKernel

    job = _sweep_job(name, precision)
    t = job.tables
    kernel = SweepKernel(t, job.analysis, rt, precision=precision)
    out: Arrays = {f"metric_{k}": np.asarray(v) for k, v in kernel.metrics(0, t.n_configs).items()}
    raw = kernel(0, t.n_configs)
    for field in ("index", "status", "bounds", "condition"):
        a = getattr(raw, field)
        out[f"raw_{field}_first"] = a[:3]
        out[f"raw_{field}_sha256"] = np.array(_digest(a))
    designs = np.array([[(i * (k + 1)) % c for k, c in enumerate(t.counts)] for i in range(0, 17, 3)])
    search = SweepKernel(design_tables(t, designs[:3], 1, rows=4), job.analysis, rt, precision=precision)
    first = search(0, 4)
    search.load(design_tables(t, designs[3:], 1, rows=4))  # a search's next batch, on the same kernel
    second = search(0, 4)
    out["design_index"] = np.concatenate([first.index, second.index])
    out["design_status"] = np.concatenate([first.status, second.status])
    return out


#: every case: name -> function of (runtime, precision)
CASES: dict[str, Callable[[Runtime, str], Arrays]] = {
    **{name: (lambda rt, p, name=name: library_case(rt, name, p)) for name in LIBRARY_CASES},
    "hard": hard_case,
    "cube-instrument": cube_instrument_case,
    "cube-psf": cube_psf_case,
    "sweep-igrm": lambda rt, p: sweep_case(rt, "sweep-igrm", p),
    "sweep-gvmi": lambda rt, p: sweep_case(rt, "sweep-gvmi", p),
}


# -- files: one per case and precision, one set of arrays per distinct output --------------------------------------

def path_of(case: str, precision: str) -> Path:
    return GOLDEN / f"{case}-{precision}.npz"


def load(case: str, precision: str) -> tuple[dict[str, int], list[Arrays]]:
    """(device key -> set number, the sets) of a saved case; empty when none is saved."""
    path = path_of(case, precision)
    if not path.exists():
        return {}, []
    with np.load(path, allow_pickle=False) as f:
        devices = json.loads(str(f["devices"]))
        sets: list[Arrays] = []
        for key in f.files:
            if key == "devices":
                continue
            n, name = key.split("/", 1)
            while len(sets) <= int(n):
                sets.append({})
            sets[int(n)][name] = f[key]
    return devices, sets


def equal(a: np.ndarray, b: np.ndarray) -> bool:
    """Bit for bit: same dtype, shape and values (NaN where NaN)."""
    a, b = np.asarray(a), np.asarray(b)
    if a.dtype != b.dtype or a.shape != b.shape:
        return False
    return bool(np.array_equal(a, b, equal_nan=a.dtype.kind in "fc"))


def differences(got: Arrays, want: Arrays) -> list[str]:
    """What differs between two sets of arrays, one line each."""
    lines = [f"{k}: missing" for k in sorted(set(want) - set(got))]
    lines += [f"{k}: not saved" for k in sorted(set(got) - set(want))]
    for k in sorted(set(got) & set(want)):
        g, w = np.asarray(got[k]), np.asarray(want[k])
        if not equal(g, w):
            if g.shape != w.shape or g.dtype != w.dtype:
                lines.append(f"{k}: {g.dtype}{g.shape} against saved {w.dtype}{w.shape}")
            else:
                bad = ~((g == w) | ((g != g) & (w != w))) if g.dtype.kind in "fc" else g != w
                at = tuple(int(i) for i in np.argwhere(np.atleast_1d(bad))[0])
                lines.append(f"{k}: {int(np.count_nonzero(bad))} of {g.size} differ, first at {at}: "
                             f"{np.atleast_1d(g)[at]!r} against saved {np.atleast_1d(w)[at]!r}")
    return lines


def save(case: str, precision: str, key: str, arrays: Arrays) -> None:
    """Add (or replace) device ``key``'s outputs of a case; a set equal to a saved one is shared."""
    devices, sets = load(case, precision)
    devices.pop(key, None)
    used = sorted(set(devices.values()))
    sets = [sets[i] for i in used]
    devices = {k: used.index(v) for k, v in devices.items()}
    for i, s in enumerate(sets):
        if not differences(arrays, s):
            devices[key] = i
            break
    else:
        devices[key] = len(sets)
        sets.append(arrays)
    GOLDEN.mkdir(parents=True, exist_ok=True)
    flat = {f"{i}/{k}": np.asarray(v) for i, s in enumerate(sets) for k, v in s.items()}
    np.savez_compressed(path_of(case, precision), devices=np.array(json.dumps(devices, sort_keys=True)), **flat)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--device", action="append", default=[], help="PLATFORM:DEVICE (repeatable; default: default)")
    ap.add_argument("--case", action="append", default=[], help="only these cases")
    args = ap.parse_args()
    for spec in args.device or [None]:
        rt = get_runtime(spec)
        key = device_key(rt)
        for case in args.case or list(CASES):
            for precision in PRECISIONS:
                save(case, precision, key, CASES[case](rt, precision))
                print(f"{key}: {case} {precision}: {path_of(case, precision).stat().st_size:,} bytes", flush=True)


if __name__ == "__main__":
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    main()
