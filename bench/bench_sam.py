"""SAM classification throughput: s2cl's OpenCL kernel against SPy's ``spectral_angles`` (+ argmin)
and a plain numpy matmul, side by side in one process, each checked first.

Data: references = random positive spectra (seeded); pixels = brightness x reference + Gaussian
noise (sigma 0.01), float32, structure-of-arrays for s2cl and (rows, cols, bands) for SPy (its
layout; the transposition is not timed). :func:`sam_baseline` is the measurement; the suite
(``python -m bench``, part ``vs-sam``, 13 bands) runs the same function. Writes bench/results/sam.json.

    python -m bench.bench_sam [--n 1000000]
"""

from __future__ import annotations

import argparse
from collections.abc import Callable
from typing import Any

import numpy as np

from bench.chain import Context
from bench.common import check, comparison_rows, machine_info, median_time, print_comparison, write_json
from s2cl.cl.runtime import get_runtime
from s2cl.reference import stages as ref
from s2cl.retrieve.sam import SamClassifier

CASES = ((2, 20), (6, 20), (13, 20))  # (bands, references): B11+B12 as in the paper, red edge, full MSI
CHECKED = 20_000  # pixels validated against the float64 oracle before timing


def scene(n: int, n_bands: int, n_refs: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    refs = rng.uniform(0.05, 0.6, (n_refs, n_bands))
    truth = rng.integers(0, n_refs, n)
    pix = (refs[truth].T * rng.uniform(0.5, 1.5, n) + rng.normal(0.0, 0.01, (n_bands, n))).astype(np.float32)
    return refs, truth, np.ascontiguousarray(pix)  # structure of arrays: bands x pixels, pixels contiguous


def numpy_sam(pix: np.ndarray, unit_refs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    dots = unit_refs.astype(np.float32) @ pix
    best = np.argmax(dots, axis=0)
    norm = np.sqrt(np.einsum("ij,ij->j", pix, pix))
    return best, np.arccos(np.clip(dots[best, np.arange(pix.shape[1])] / norm, -1, 1))


def spy_sam(pix: np.ndarray, refs: np.ndarray) -> Callable[[], tuple[np.ndarray, np.ndarray]]:
    """SPy's spectral_angles + argmin on ``pix`` in its (rows, cols, bands) layout (made here, not timed)."""
    import spectral

    cube = np.ascontiguousarray(pix.T).reshape(1, pix.shape[1], pix.shape[0])
    refs32 = refs.astype(np.float32)

    def run() -> tuple[np.ndarray, np.ndarray]:
        a = spectral.spectral_angles(cube, refs32)
        return np.argmin(a, axis=2).ravel(), np.min(a, axis=2).ravel()

    return run


def kernel_launcher(sam: SamClassifier, pix: np.ndarray) -> Callable[[], None]:
    """The SAM kernel alone (pixels on the device, outputs left there), through the launch
    :meth:`SamClassifier.classify` makes."""
    v = sam.buffers(pix)

    def launch() -> None:
        sam.enqueue(v)
        sam.rt.finish()

    return launch


def _check(what: str, best: np.ndarray, angle: np.ndarray, want: tuple[np.ndarray, np.ndarray]) -> float:
    """Same class as the float64 oracle on > 99.9 % of the pixels and angles within 1e-3 rad."""
    agree, d_angle = float(np.mean(best == want[0])), float(np.max(np.abs(angle - want[1])))
    check(agree > 0.999 and d_angle < 1e-3, f"{what} disagrees with the float64 oracle: {agree:.4%} same class, "
                                            f"max |d angle| {d_angle:.1e} rad")
    return agree


def sam_baseline(ctx: Context, n: int, bands: int, refs: int) -> dict[str, Any]:
    """SAM of ``n`` pixels (a multiple of 16) on ``bands`` bands against ``refs`` references: s2cl
    (with transfers; the kernel alone), SPy and numpy, each checked on 20,000 pixels first."""
    references, _, pix = scene(n, bands, refs)
    sam, part = SamClassifier(get_runtime(), references), pix[:, :CHECKED]
    best, angle, _ = ref.sam_classify(part, references)
    got = sam.classify(part)
    agree = _check("s2cl SAM", got.reference, got.angle, (best, angle))
    _check("SPy spectral_angles", *spy_sam(part, references)(), (best, angle))
    _check("numpy SAM", *numpy_sam(part, sam.unit_refs), (best, angle))
    spy, spy_ = spy_sam(pix, references), "SPy spectral_angles + argmin"
    runs = {"s2cl OpenCL": lambda: sam.classify(pix),
            "s2cl OpenCL kernel alone (data on the device)": kernel_launcher(sam, pix), spy_: spy,
            "numpy float32 matmul + argmax": lambda: numpy_sam(pix, sam.unit_refs)}
    rates = {k: n / median_time(run, ctx.repeat, warmup=1) for k, run in runs.items()}
    return {"title": f"SAM, {bands} bands, {refs} references", "unit": "pixels/s", "n": n,
            "validation_agreement": agree,
            "agreement_with_spy": float(np.mean(sam.classify(pix).reference == spy()[0])),
            "rows": comparison_rows(rates, spy_)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=1_000_000, help="pixels (a multiple of 16)")
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    ctx = Context.make(quick=False, repeat=args.repeat)
    cases = [sam_baseline(ctx, args.n, nb, nr) for nb, nr in CASES]
    for case in cases:
        print_comparison(case)
    rt = get_runtime()
    print("wrote", write_json("sam.json", {"benchmark": "sam", "machine": machine_info(rt), "cases": cases}))


if __name__ == "__main__":
    main()
