"""The scene file's [analysis] section and its ``[[application]]`` tables (several applications, each with its own
analysis): pydantic models, re-exported by :mod:`s2cl.scene.schema`."""

from __future__ import annotations

import re
from typing import Any, Literal

from pydantic import Field, field_validator, model_validator

from s2cl.scene.grid_schema import GridSpec
from s2cl.scene.section import Section


class AnalysisSpec(Section):
    kind: str = Field(
        description="the retrieval, an analysis family (s2cl.retrieve.families): `igrm` (the IGRM red-edge fit), a "
        "normalised-difference index (`gvmi`, `ndvi`), `formula` (your own) or `sam` (SAM classes); another kind is "
        "refused with the list of registered ones")
    bands: list[str] | None = Field(None, min_length=2, description="bands analysed by `s2cl simulate` (default: the "
                                    "swept bands, else B4 B5 B6 B7 for igrm, an index's role bands, all for sam)")
    parameter: str | None = Field(None, description="library parameter regressed on the index (igrm: cab, gvmi: ewt)")
    expression: str | None = Field(None, max_length=500, description="formula: the index as an expression of band "
                                   "reflectances, e.g. S2REP '705 + 35 * ((B4 + B7) / 2 - B5) / (B6 - B5)': band "
                                   "names, numbers, + - * /, parentheses, sqrt log exp abs min max; a pixel whose "
                                   "denominator is zero or whose value is not finite is INVALID")
    roles: dict[str, str] = Field(default_factory=dict, description="an index's band of each role, written as keys of "
                                  "[analysis] (gvmi: nir = 'B8', swir = 'B11'; s2cl.retrieve.indices); the family "
                                  "refuses a key that is not one of its roles")
    classes: list[str] | None = Field(None, description="sam: library groups to tell apart (default: all)")
    angle_threshold_deg: float | None = Field(None, gt=0, le=90, description="sam: larger angles are unclassified")
    igrm: dict[str, Any] = Field(default_factory=dict, description="IGRM fit settings (see s2cl.retrieve.igrm)")
    regress: list[Literal["converged", "stalled", "iteration_limit"]] = Field(
        ["converged", "stalled", "iteration_limit"], min_length=1,
        description="IGRM fit statuses whose lp enters the regression (degenerate and invalid fits never do; "
        "the summary counts the pixels left out)")

    @model_validator(mode="before")
    @classmethod
    def _gather_roles(cls, data: Any) -> Any:
        """Keys that are not fields and hold a band name (``nir = "B8"``) go into :attr:`roles`: the analysis family
        checks them against its band roles (:meth:`s2cl.retrieve.family.Family.roles`)."""
        if isinstance(data, dict):
            extra = [k for k, v in data.items() if k not in cls.model_fields and isinstance(v, str)]
            if extra:
                data = dict(data)
                data["roles"] = {**data.get("roles", {}), **{k: data.pop(k) for k in extra}}
        return data


#: an application's name: it names results columns (``<name>_<metric>``), so letters, digits and ``_``
APPLICATION_NAME = re.compile(r"[a-z][a-z0-9_]{0,39}")


class ApplicationSpec(Section):
    """One application of a scene that serves several (``[[application]]``): its own library, analysis and
    requirement; the scene's [sweep], sensor, atmosphere and effects are shared (s2cl.scene.applications)."""

    name: str = Field(description="the application's name, lower-case letters, digits and _ (e.g. chlorophyll): it "
                      "names its results columns (chlorophyll_rms)")
    library: str | None = Field(None, description="its surface library (default: surface.library)")
    copies: int | None = Field(None, ge=1, le=1_000_000, description="noisy copies of each of its library's spectra "
                               "(default: surface.copies)")
    analysis: AnalysisSpec = Field(description="its retrieval: the keys of [analysis]")
    grid: GridSpec | None = Field(None, description="its own spectral grid (default: the scene's [grid]), for a "
                                  "library that holds data only on part of the scene's grid (builtin:minerals-swir: "
                                  "1500-2500 nm); the bands it reads must lie on it")
    target: float | str | None = Field(None, description="its requirement, a score to meet in the metric's units "
                                       "(lower is better): a number (5.0) or a number with the metric's unit "
                                       "('5 ug/cm2', '10 %')")

    @field_validator("name")
    @classmethod
    def _name(cls, value: str) -> str:
        if not APPLICATION_NAME.fullmatch(value):
            raise ValueError(f"must be 1-40 lower-case letters, digits or _, starting with a letter, got {value!r}")
        return value
