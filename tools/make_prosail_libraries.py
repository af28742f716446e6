#!/usr/bin/env python
"""Regenerate the shipped PROSAIL libraries ``s2cl/data/prosail_{lib1,lib2,leaf_water}.npz``.

Needs prosail (``pip install "s2cl[prosail]"``) and the shipped USGS mineral file (the
iron-bearing backgrounds). Deterministic: the same prosail version gives the same files.

Usage: ``python tools/make_prosail_libraries.py [--out-dir DIR] [NAME ...]``
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from s2cl.libraries.vegetation import SHIPPED, generate, prosail_version, shipped_path, write_library


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "names", nargs="*", default=list(SHIPPED), help=f"libraries to build (default: {list(SHIPPED)})"
    )
    parser.add_argument("--out-dir", type=Path, default=None, help="write here instead of s2cl/data")
    args = parser.parse_args()
    version = prosail_version()
    for name in args.names:
        spec = SHIPPED[name]
        lib = generate(spec)
        target = shipped_path(name) if args.out_dir is None else args.out_dir / shipped_path(name).name
        write_library(spec, lib, target, version=version)
        err = np.abs(lib.spectra.astype(np.float32).astype(np.float64) - lib.spectra).max()
        print(
            f"{target}: {lib.size} spectra, {target.stat().st_size / 1024:.0f} KiB, "
            f"reflectance {lib.spectra.min():.4f}–{lib.spectra.max():.4f}, float32 max abs error {err:.2e}"
        )


if __name__ == "__main__":
    main()
