"""Which stages of the forward chain a scene switches on; a stage that is off is not in the kernel.

The switches are the ``[effects]`` keys of the schema that take ``true``/``false`` (:class:`s2cl.scene.schema.
EffectsSpec`, in the chain's order), so this module names no stage: the stages themselves are declared in
:mod:`s2cl.forward.stages`.
"""

from __future__ import annotations

import types
import typing
from collections.abc import Iterable
from dataclasses import dataclass

from s2cl.errors import InputError
from s2cl.scene.schema import EffectsSpec


def _is_switch(annotation: object) -> bool:
    """A ``bool`` key, or one that takes ``bool`` or a table of the stage's settings."""
    if annotation is bool:
        return True
    return typing.get_origin(annotation) in (typing.Union, types.UnionType) and bool in typing.get_args(annotation)


#: the on/off keys of [effects], in the chain's order
SWITCHES: tuple[str, ...] = tuple(n for n, f in EffectsSpec.model_fields.items() if _is_switch(f.annotation))
#: the switches a scene turns on when it says nothing
DEFAULTS: frozenset[str] = frozenset(n for n in SWITCHES if EffectsSpec.model_fields[n].default not in (False, None))


def _needs(name: str) -> tuple[str, str] | None:
    """(the switch ``name`` needs on, why) where the schema says so."""
    extra = EffectsSpec.model_fields[name].json_schema_extra
    needs = extra.get("needs") if isinstance(extra, dict) else None
    return (str(needs[0]), str(needs[1])) if needs else None


@dataclass(frozen=True, init=False)
class EffectSet:
    """The stages of the chain that are on. Frozen and hashable: it keys the program cache.

    ``EffectSet(noise=False)``: the defaults with those switches changed; ``effects.noise``, :meth:`on`: whether a
    stage is on."""

    enabled: frozenset[str]

    def __init__(self, enabled: Iterable[str] | None = None, **flags: bool):
        unknown = sorted(set(flags) - set(SWITCHES))
        if unknown:
            raise TypeError(f"unknown effects {unknown}; known: {', '.join(SWITCHES)}")
        on = set(DEFAULTS if enabled is None else enabled)
        for name, value in flags.items():
            (on.add if value else on.discard)(name)
        object.__setattr__(self, "enabled", frozenset(on))

    @classmethod
    def of(cls, spec: EffectsSpec) -> EffectSet:
        """The switches of a scene's ``[effects]`` (a stage given as a table of settings is on unless it says
        ``on = false``)."""
        return cls(enabled=[n for n in SWITCHES if getattr(getattr(spec, n), "on", getattr(spec, n)) is True])

    def on(self, name: str) -> bool:
        """Whether stage ``name`` is on."""
        return name in self.enabled

    def __getattr__(self, name: str) -> bool:
        if name in SWITCHES:
            return name in self.enabled
        raise AttributeError(name)

    def validate(self, source: str | None = None) -> EffectSet:
        for name in SWITCHES:
            need = _needs(name)
            if need and self.on(name) and not self.on(need[0]):
                raise InputError(f"{name} needs {need[0]} = true ({need[1]})", source=source, key=f"effects.{name}")
        return self

    def as_dict(self) -> dict[str, bool]:
        return {n: n in self.enabled for n in SWITCHES}

    def describe(self) -> str:
        on = [n for n in SWITCHES if n in self.enabled]
        return ", ".join(on) if on else "none"
