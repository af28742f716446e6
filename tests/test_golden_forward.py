"""The forward chain reproduces, bit for bit, the outputs saved before it became declared stages (issue 33): library
simulations (noise, quantisation, calibration, correction on and off; hard radiance), image cubes ([instrument]
effects; [spatial] PSF with no-data pixels, in blocks of rows) and sweeps (per-configuration metrics, per-pixel
outputs, a search's design tables), in float32 and float64 (:mod:`golden_forward` says how they were made)."""

from __future__ import annotations

import golden_forward as golden
import pytest

from s2cl.cl.runtime import Runtime


@pytest.mark.parametrize("case", list(golden.CASES))
def test_saved_outputs_are_reproduced_bit_for_bit(rt: Runtime, real_t: str, case: str) -> None:
    devices, sets = golden.load(case, real_t)
    assert sets, f"no saved outputs for {case} {real_t}: {golden.path_of(case, real_t)}"
    key = golden.device_key(rt)
    if key not in devices:
        pytest.skip(f"outputs saved on {sorted(devices)} only; this device is {key}")
    got = golden.CASES[case](rt, real_t)
    problems = golden.differences(got, sets[devices[key]])
    assert not problems, f"{case} {real_t} on {key}:\n" + "\n".join(problems)
