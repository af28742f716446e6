"""The forward chain on the device: its declared stages (``stages``), resampling, the per-pixel stages' kernel
(``sense``), library and streamed simulations, image cubes, datasets, the host Philox noise.
"""
