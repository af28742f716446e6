#!/usr/bin/env python
"""Extract measured soils and non-photosynthetic vegetation from the earthlib wheel into s2cl's data file.

earthlib (MIT licence, Christopher Anderson, https://github.com/earth-chris/earthlib) ships a global
spectral library as an ENVI spectral library (``earthlib/data/spectra.sli`` + ``.sli.hdr``: 7,261 spectra,
180 bands at 400–2450 nm, 10 nm, with the water-vapour bands 1360–1450 and 1800–1950 nm left out) and a
metadata table (``earthlib/data/spectra.csv``: NAME, LEVEL_1–LEVEL_4, LAT, LON, SOURCE, NOTES). This
script keeps

* every **ICRAF-ISRIC soil** (LEVEL_3 ``soil``, SOURCE ``icraf-isric-soil-database``: 4,168 spectra), and
* every **measured non-photosynthetic vegetation** spectrum (LEVEL_2 ``npv``: litter, bark, wood, npv),

on the wheel's own 180 wavelengths (no resampling here; s2cl interpolates at load time, see
:mod:`s2cl.libraries.earthlib_spectra`), float32 exactly as stored in the ``.sli``, and writes
``s2cl/data/earthlib_soils_npv.npz`` with source, licence, version and the wheel's sha256 in its metadata.
earthlib is needed only to run this script, never at run time; the wheel is read as a zip file
(earthlib is not imported).

Usage: ``python tools/extract_earthlib.py [--wheel PATH] [--out PATH]``; without ``--wheel`` it runs
``pip download earthlib==1.1.0 --no-deps`` into a temporary folder.
"""

from __future__ import annotations

import argparse
import csv
import hashlib
import io
import re
import subprocess
import sys
import tempfile
import zipfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from s2cl.libraries.earthlib_spectra import (
    CITATION,
    DATA_FILE,
    EARTHLIB_URL,
    EARTHLIB_VERSION,
    NPV_GROUP_PREFIX,
    SOIL_GROUP,
    SOIL_SOURCE,
)
from s2cl.libraries.npz import write_library_file

MEMBER = "earthlib/data/spectra"


def download_wheel(folder: Path) -> Path:
    """``pip download earthlib==VERSION --no-deps`` into ``folder``; the wheel's path."""
    subprocess.run([sys.executable, "-m", "pip", "download", f"earthlib=={EARTHLIB_VERSION}", "--no-deps",
                    "--only-binary=:all:", "-d", str(folder)], check=True)
    wheels = sorted(folder.glob(f"earthlib-{EARTHLIB_VERSION}-*.whl"))
    if not wheels:
        raise SystemExit(f"pip downloaded no earthlib {EARTHLIB_VERSION} wheel into {folder}")
    return wheels[0]


def header_list(text: str, key: str) -> list[str]:
    """The ``key = { a , b , … }`` list of an ENVI header, stripped."""
    m = re.search(rf"^{re.escape(key)}\s*=\s*\{{(.*?)\}}", text, flags=re.M | re.S)
    if not m:
        raise SystemExit(f"ENVI header has no '{key}' list")
    return [v.strip() for v in m.group(1).split(",")]


def header_value(text: str, key: str) -> str:
    m = re.search(rf"^{re.escape(key)}\s*=\s*(.+)$", text, flags=re.M)
    if not m:
        raise SystemExit(f"ENVI header has no '{key}'")
    return m.group(1).strip()


def read_wheel(wheel: Path) -> tuple[np.ndarray, np.ndarray, list[str], list[dict[str, str]]]:
    """Wavelengths (nm), spectra (float32, lines × samples), header names and CSV rows from the wheel."""
    with zipfile.ZipFile(wheel) as zf:
        hdr = zf.read(MEMBER + ".sli.hdr").decode("utf-8")
        raw = zf.read(MEMBER + ".sli")
        rows = list(csv.DictReader(io.StringIO(zf.read(MEMBER + ".csv").decode("utf-8"))))
    samples, lines = int(header_value(hdr, "samples")), int(header_value(hdr, "lines"))
    if header_value(hdr, "data type") != "4" or header_value(hdr, "byte order") != "0":
        raise SystemExit("expected little-endian float32 (data type 4, byte order 0)")
    if int(header_value(hdr, "header offset")) != 0 or len(raw) != 4 * samples * lines:
        raise SystemExit(f"{len(raw)} bytes do not hold {lines} x {samples} float32 values")
    if header_value(hdr, "wavelength units").lower() != "micrometers":
        raise SystemExit("expected wavelengths in micrometers")
    w_nm = np.round(np.asarray([float(v) for v in header_list(hdr, "wavelength")]) * 1000.0, 6)
    names = header_list(hdr, "spectra names")
    if w_nm.size != samples or len(names) != lines or len(rows) != lines:
        raise SystemExit(f"header/CSV sizes disagree: {w_nm.size} wavelengths, {len(names)} names, {len(rows)} rows")
    spectra = np.frombuffer(raw, dtype="<f4").reshape(lines, samples)
    return w_nm, spectra, names, rows


def select(names: list[str], rows: list[dict[str, str]]) -> tuple[list[int], list[str]]:
    """Row indices kept (soils first, then NPV) and their s2cl groups."""
    soils = [i for i, r in enumerate(rows) if r["LEVEL_3"] == "soil" and r["SOURCE"] == SOIL_SOURCE]
    npv = [i for i, r in enumerate(rows) if r["LEVEL_2"] == "npv" and r["LEVEL_4"] == "measured"]
    for i in soils + npv:  # header and CSV are in the same order (one burned row's names differ; not kept)
        if rows[i]["NAME"] != names[i]:
            raise SystemExit(f"row {i}: header name {names[i]!r} differs from the CSV's {rows[i]['NAME']!r}")
    groups = [SOIL_GROUP] * len(soils) + [NPV_GROUP_PREFIX + rows[i]["LEVEL_3"] for i in npv]
    return soils + npv, groups


def site_numbers(rows: list[dict[str, str]]) -> np.ndarray:
    """1, 2, … per distinct (LAT, LON) of ``rows`` in order of first appearance; 0 where the location is
    missing or the 0/0 placeholder (ICRAF soils of one profile share a site)."""
    sites: dict[tuple[float, float], int] = {}
    out = []
    for r in rows:
        try:
            lat, lon = float(r["LAT"]), float(r["LON"])
        except ValueError:
            lat = lon = float("nan")
        if not (np.isfinite(lat) and np.isfinite(lon)) or (lat == 0.0 and lon == 0.0):
            out.append(0)
            continue
        out.append(sites.setdefault((lat, lon), len(sites) + 1))
    return np.asarray(out, dtype=np.float64)


def unique_names(names: list[str]) -> list[str]:
    """Names made unique: a repeated name gets `` #2``, `` #3``… (earthlib repeats a few NPV names)."""
    seen: dict[str, int] = {}
    out = []
    for n in names:
        seen[n] = seen.get(n, 0) + 1
        out.append(n if seen[n] == 1 else f"{n} #{seen[n]}")
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--wheel", type=Path, default=None, help="earthlib wheel (default: pip download it)")
    parser.add_argument(
        "--out", type=Path, default=Path(__file__).resolve().parent.parent / "s2cl" / "data" / DATA_FILE
    )
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        wheel = args.wheel or download_wheel(Path(tmp))
        sha = hashlib.sha256(wheel.read_bytes()).hexdigest()
        w_nm, spectra, names, rows = read_wheel(wheel)
    if f"earthlib-{EARTHLIB_VERSION}-" not in wheel.name:
        raise SystemExit(f"{wheel.name} is not earthlib {EARTHLIB_VERSION}")
    keep, groups = select(names, rows)
    sel = spectra[keep]
    if not np.all(np.isfinite(sel)) or sel.min() < 0.0 or sel.max() > 1.0:
        raise SystemExit(f"kept spectra outside [0, 1] or not finite: {sel.min()}..{sel.max()}")
    n_soil = groups.count(SOIL_GROUP)
    metadata = {
        "quantity": "reflectance",
        "source": f"earthlib {EARTHLIB_VERSION} spectral library ({EARTHLIB_URL}): ICRAF-ISRIC soils and "
                  "measured non-photosynthetic vegetation",
        "citation": CITATION,
        "licence": "earthlib is MIT-licensed (Copyright (c) 2023 Christopher Anderson)",
        "extracted_from": {"package": "earthlib", "version": EARTHLIB_VERSION, "file": MEMBER + ".sli",
                           "wheel": wheel.name, "sha256": sha},
        "selection": (f"{n_soil} spectra with LEVEL_3 'soil' and SOURCE '{SOIL_SOURCE}'; {len(keep) - n_soil} "
                      "with LEVEL_2 'npv' and LEVEL_4 'measured' (group 'npv:' + LEVEL_3); names from the ENVI "
                      "header, repeated names suffixed ' #2'"),
        "wavelengths": "the wheel's own 180 wavelengths: 400-1350, 1460-1790, 1960-2450 nm at 10 nm; the "
                       "water-vapour bands between are not in the data",
        "storage": "float32, the .sli values unchanged",
        "npv_sources": sorted({f"{rows[i]['SOURCE']}: {rows[i]['NOTES']}" for i in keep[n_soil:]}),
    }
    site = site_numbers([rows[i] for i in keep])
    site[n_soil:] = 0.0  # sites are given for soils only
    metadata["site"] = ("param site: 1, 2, ... per distinct (LAT, LON) of earthlib's metadata among the soils (the "
                        "horizons of one ICRAF profile share a site); 0 = no usable location (missing or 0/0), "
                        "and for every NPV spectrum")
    path = write_library_file(args.out, wavelength_nm=w_nm, spectra=sel,
                              names=unique_names([names[i] for i in keep]), groups=groups,
                              params={"site": site}, metadata=metadata)
    print(f"wrote {path} ({path.stat().st_size / 1024:.0f} KiB): {n_soil} soils at {int(site.max())} sites "
          f"({int((site[:n_soil] == 0).sum())} without one), {len(keep) - n_soil} NPV; "
          f"wheel sha256 {sha}")
    for g in sorted(set(groups)):
        print(f"  {g:12s} {groups.count(g)}")


if __name__ == "__main__":
    main()
