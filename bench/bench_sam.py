"""SAM classification throughput: s2cl's OpenCL kernel against SPy's ``spectral_angles`` (+ argmin)
and a plain numpy matmul, side by side in one process, after a correctness check.

Data: references = random positive spectra (seeded); pixels = brightness x reference + Gaussian
noise (sigma 0.01), float32, structure-of-arrays for s2cl and (rows, cols, bands) for SPy (its
layout; the transposition is not timed). Writes bench/results/sam.json.

    python -m bench.bench_sam [--n 1000000]
"""

from __future__ import annotations

import argparse

import numpy as np

from bench.common import check, machine_info, median_time, write_json
from s2cl.reference import stages as ref
from s2cl.retrieve.sam import SamClassifier

CASES = ((2, 20), (6, 20), (13, 20))  # (bands, references): B11+B12 as in the paper, red edge, full MSI


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


def run(n: int, n_bands: int, n_refs: int) -> dict:
    import spectral

    refs, _, pix = scene(n, n_bands, n_refs)
    sam = SamClassifier(refs)
    part = slice(0, 20000)  # validated against the float64 oracle before timing
    best, angle, _ = ref.sam_classify(pix[:, part], refs)
    got = sam.classify(pix[:, part])
    agree = float(np.mean(got.reference == best))
    max_dangle = float(np.max(np.abs(got.angle - angle)))
    check(agree > 0.999 and max_dangle < 1e-3,
          f"SAM disagrees with the float64 oracle: {agree:.4%} same class, max |d angle| {max_dangle:.1e} rad")
    cube = np.ascontiguousarray(pix.T).reshape(1000, n // 1000, n_bands)

    def spy() -> tuple[np.ndarray, np.ndarray]:
        a = spectral.spectral_angles(cube, refs.astype(np.float32))
        return np.argmin(a, axis=2), np.min(a, axis=2)

    spy_best = spy()[0].ravel()
    t_ocl = median_time(lambda: sam.classify(pix), 3)
    t_spy = median_time(spy, 3)
    t_np = median_time(lambda: numpy_sam(pix, sam.unit_refs), 3)
    rt, T = sam.rt, sam.types
    bufs = [rt.empty(4 * n), rt.empty(n * 4), rt.empty(n), rt.to_device(pix), sam._refs_d]

    def launch() -> None:
        sam.kernel(rt.queue, (n // T.lanes,), None, *bufs, np.float32(sam.cos_min), np.int32(n))
        rt.finish()

    launch()
    t_kernel = median_time(launch, 3)
    out = {"n_pixels": n, "n_bands": n_bands, "n_refs": n_refs, "check_agreement": agree,
           "check_max_dangle_rad": max_dangle,
           "agreement_with_spy": float(np.mean(sam.classify(pix).reference == spy_best)),
           "s2cl_pixels_per_s": n / t_ocl, "s2cl_kernel_only_pixels_per_s": n / t_kernel,
           "spy_pixels_per_s": n / t_spy, "numpy_pixels_per_s": n / t_np}
    out["ratio_vs_spy"] = out["s2cl_pixels_per_s"] / out["spy_pixels_per_s"]
    out["ratio_vs_numpy"] = out["s2cl_pixels_per_s"] / out["numpy_pixels_per_s"]
    print(f"{n_bands:>2} bands {n_refs} refs: s2cl {out['s2cl_pixels_per_s']:.3g}/s (kernel "
          f"{out['s2cl_kernel_only_pixels_per_s']:.3g}/s), SPy {out['spy_pixels_per_s']:.3g}/s "
          f"(x{out['ratio_vs_spy']:.3g}), numpy {out['numpy_pixels_per_s']:.3g}/s (x{out['ratio_vs_numpy']:.3g})")
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=1_000_000, help="pixels (a multiple of 1000)")
    args = ap.parse_args()
    cases = [run(args.n, nb, nr) for nb, nr in CASES]
    rt = SamClassifier(np.ones((1, 2))).rt
    print("wrote", write_json("sam.json", {"benchmark": "sam", "machine": machine_info(rt), "cases": cases}))


if __name__ == "__main__":
    main()
