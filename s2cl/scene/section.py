"""The base of every scene section's model: unknown keys refused, values frozen and strictly typed."""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict


class Section(BaseModel):
    """One ``[section]`` of a scene file."""

    model_config = ConfigDict(extra="forbid", frozen=True, strict=True)
