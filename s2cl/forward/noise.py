"""Sensor noise on the host: numpy Philox4x32-10 and the Box–Muller normals of
``kernels/common/random.mako`` (float64), and noise added with them (the sweep's noise tables, the
studies). A deviate is a pure function of (seed, pixel, band id, frame), so host and device agree.

Philox4x32-10 (Salmon et al. 2011, "Parallel random numbers: as easy as 1, 2, 3"): 10 rounds of
``(hi0, lo0) = M0·c0, (hi1, lo1) = M1·c2, c = (hi1^c1^k0, lo1, hi0^c3^k1, lo0)`` with the key
bumped by the Weyl constants between rounds. Known answer: counter 0, key 0 →
``6627e8d5 e169c58d bc57ac4c 9b00dbd8``.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from s2cl.sensor.noise_model import noise_sigma

M0, M1 = 0xD2511F53, 0xCD9E8D57
W0, W1 = 0x9E3779B9, 0xBB67AE85
MASK = 0xFFFFFFFF
TAG_SENSOR_NOISE = 0x53324E31


def philox4x32(counter: np.ndarray, key: tuple[int, int], rounds: int = 10) -> np.ndarray:
    """Philox words for counters ``(..., 4)`` uint32 and a key (k0, k1); returns ``(..., 4)`` uint32."""
    c = [np.asarray(counter[..., i], dtype=np.uint64) for i in range(4)]
    k0, k1 = np.uint64(key[0] & MASK), np.uint64(key[1] & MASK)
    for r in range(rounds):
        if r:
            k0 = np.uint64((int(k0) + W0) & MASK)
            k1 = np.uint64((int(k1) + W1) & MASK)
        p0 = np.uint64(M0) * c[0]
        p1 = np.uint64(M1) * c[2]
        hi0, lo0 = p0 >> np.uint64(32), p0 & np.uint64(MASK)
        hi1, lo1 = p1 >> np.uint64(32), p1 & np.uint64(MASK)
        c = [hi1 ^ c[1] ^ k0, lo1, hi0 ^ c[3] ^ k1, lo0]
    return np.stack(c, axis=-1).astype(np.uint32)


def uniform(words: np.ndarray) -> np.ndarray:
    """((x >> 9) + 0.5) · 2⁻²³: strictly inside (0, 1), exact in float32 and float64."""
    return ((np.asarray(words, dtype=np.uint32) >> np.uint32(9)).astype(np.float64) + 0.5) * 2.0**-23


def normal4(seed: int, tag: int, pixel: np.ndarray, group: np.ndarray, frame: int = 0, draw: int = 0) -> np.ndarray:
    """The four normals of counter (pixel, group, frame, draw): array ``(..., 4)`` float64."""
    pixel, group = np.broadcast_arrays(np.asarray(pixel, dtype=np.uint64), np.asarray(group, dtype=np.uint64))
    ctr = np.stack([pixel, group, np.full_like(pixel, frame), np.full_like(pixel, draw)], axis=-1)
    u = uniform(philox4x32(ctr, (seed, tag)))
    r0 = np.sqrt(-2.0 * np.log(u[..., 0]))
    r1 = np.sqrt(-2.0 * np.log(u[..., 2]))
    t0, t1 = 2.0 * np.pi * u[..., 1], 2.0 * np.pi * u[..., 3]
    return np.stack([r0 * np.cos(t0), r0 * np.sin(t0), r1 * np.cos(t1), r1 * np.sin(t1)], axis=-1)


def sensor_noise(seed: int, pixels: np.ndarray, band_ids: list[int] | tuple[int, ...], frame: int = 0) -> np.ndarray:
    """Standard normals ``(n_bands, n_pixels)`` that the sense kernel adds (before scaling by σ)."""
    pixels = np.asarray(pixels, dtype=np.uint64)
    out = np.empty((len(band_ids), pixels.size))
    for k, bid in enumerate(band_ids):
        out[k] = normal4(seed, TAG_SENSOR_NOISE, pixels, np.full(pixels.shape, bid >> 2), frame)[..., bid & 3]
    return out


#: eight-byte values per pixel the draw of one band holds at once besides its output (the counter's four words as
#: uint64, the Philox products, halves and round outputs, the uniforms and normals in float64; :func:`normal4`):
#: what tests/test_host_footprint.py measures
DRAW_VALUES_PER_PIXEL = 22


def sensor_noise_bytes(n_pixels: int, n_bands: int) -> int:
    """Bytes :func:`sensor_noise` holds at its peak for ``n_pixels`` pixels of ``n_bands`` bands: its float64 output
    and one band's draw."""
    return 8 * n_pixels * (n_bands + DRAW_VALUES_PER_PIXEL)


def add_noise(radiance: np.ndarray, noise_a: np.ndarray, noise_b: np.ndarray, band_ids: Sequence[int], seed: int,
              pixel_offset: int = 0, frame: int = 0) -> np.ndarray:
    """``radiance`` ``(n_bands, n_pixels)`` plus σ(L)·z on the host, float64: σ from each band's noise
    coefficients at its width (:func:`s2cl.sensor.noise_model.noise_sigma`), z the sense kernel's deviate
    of (seed, pixel, band id, frame). The sense kernel adds the same noise on the device."""
    L = np.asarray(radiance, dtype=np.float64)
    z = sensor_noise(seed, np.arange(L.shape[1]) + pixel_offset, list(band_ids), frame)
    return L + noise_sigma(L, np.asarray(noise_a)[:, None], np.asarray(noise_b)[:, None]) * z
