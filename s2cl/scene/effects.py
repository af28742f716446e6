"""Which stages of the sensor chain a scene runs; an effect that is off is not in the kernel."""

from __future__ import annotations

from dataclasses import asdict, dataclass

from s2cl.errors import InputError


@dataclass(frozen=True)
class EffectSet:
    """Stages of the forward chain, in order: atmosphere (ρ→L at 1 nm), resample (SRFs),
    noise, quantise (→ DN), calibrate (DN → L), correct (L → band reflectance through the
    band-effective terms of the assumed atmosphere). Frozen and hashable: it keys the program cache.

    ``resample = False`` makes each band an ideal monochromatic one: the spectrum's value at the
    band centre (linear interpolation between the two nearest grid samples) instead of the SRF
    integral.
    """

    atmosphere: bool = False
    resample: bool = True
    noise: bool = True
    quantise: bool = True
    calibrate: bool = True
    correct: bool = False

    def validate(self, source: str | None = None) -> EffectSet:
        if self.calibrate and not self.quantise:
            raise InputError("calibrate needs quantise = true (calibration turns DN back into radiance)",
                             source=source, key="effects.calibrate")
        if self.correct and not self.atmosphere:
            raise InputError("correct needs atmosphere = true (the correction inverts an atmosphere)",
                             source=source, key="effects.correct")
        return self

    @property
    def senses(self) -> bool:
        """Whether the radiometric stage (noise/quantise/calibrate) runs at all."""
        return self.noise or self.quantise or self.calibrate or self.correct

    def as_dict(self) -> dict[str, bool]:
        return asdict(self)

    def describe(self) -> str:
        on = [k for k, v in self.as_dict().items() if v]
        return ", ".join(on) if on else "none"
