"""The band-averaging residual of the atmospheric correction, as ``s2cl residuals`` prints it, written to a
results file: the largest |corrected - true| band reflectance per library and band, noise-free, under the
paper's standard atmosphere (:func:`s2cl.atmos.residuals.band_averaging_residuals`; float64, no 6S run).

Writes ``bench/results/correction_residuals.json`` atomically. Usage: ``python -m bench.correction_residuals``
(seconds).
"""

from __future__ import annotations

import argparse
from typing import Any

from bench.common import RESULTS, machine_info, write_json
from s2cl.atmos.residuals import DEFAULT_LIBRARIES, band_averaging_residuals
from s2cl.atmos.state import AtmosphereState

RESULT = RESULTS / "correction_residuals.json"


def measure(libraries: tuple[str, ...] = DEFAULT_LIBRARIES) -> dict[str, Any]:
    """Per library: the band names and the largest |corrected − true| per band (reflectance units)."""
    results = band_averaging_residuals(libraries)
    return {"benchmark": "correction_residuals", "machine": machine_info(), "command": "s2cl residuals",
            "state": str(AtmosphereState.paper_standard()), "sensor": "Sentinel-2 model SRFs",
            "bands": list(results[0].bands),
            "libraries": {r.library: {"spectra": int(r.true.shape[1]), "max_abs": r.max_abs().tolist()}
                          for r in results}}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m bench.correction_residuals", description=__doc__.split("\n\n")[0])
    ap.parse_args(argv)
    print("wrote", write_json(RESULT, measure()))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
