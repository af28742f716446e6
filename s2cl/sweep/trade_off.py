"""The trade-off of a finished multi-application sweep in one call (:mod:`s2cl.sweep.pareto` and its figures): the
margins measured on each application's own sweep, ``summary.json``'s ``pareto`` record, the ``pareto`` column of
``results.parquet`` and the figure."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from s2cl.sweep.digest import rankable_rows
from s2cl.sweep.pareto import (
    add_pareto_column,
    application_columns,
    noise_margins,
    pareto_record,
    read_scores,
)
from s2cl.sweep.pareto_plots import pareto_plot

FIGURE = "pareto.png"


def trade_off(results: str | Path, applications: Sequence[dict[str, Any]], jobs: Sequence[Any],
              to_application: Sequence[Callable[[Any], Any] | None], *, device: str | None = None,
              evaluator_of: Callable[[Any], Any] | None = None) -> tuple[dict[str, Any], list[Path]]:
    """``summary["pareto"]`` of the sweep whose ``results.parquet`` is ``results`` (``applications``:
    ``summary["applications"]``; ``jobs`` and ``to_application``: each application's single-application sweep and
    the map of joint configuration numbers onto it, as :func:`s2cl.sweep.pareto.noise_margins` takes them), and the
    files written: ``results.parquet`` again (with its ``pareto`` column) and, for two or more applications, the
    figure :data:`FIGURE` beside it. Only the designs a ranking may use (:func:`s2cl.sweep.digest.rankable_rows`)
    take part."""
    path = Path(results)
    df, meta = read_scores(path, applications)
    df = rankable_rows(df, meta)  # a search's designs scored on every pixel only, as every ranking
    margins, how = noise_margins(df, applications, jobs, to_application, device=device, evaluator_of=evaluator_of)
    record = pareto_record(df, applications, margins, margin_records=how)
    written = [add_pareto_column(path, record["front"]["configs"])]
    on = df["config"].isin(record["front"]["configs"]).to_numpy()
    figure = pareto_plot(df[application_columns(applications)].to_numpy(), on, applications, path.parent / FIGURE)
    return record, written + ([figure] if figure is not None else [])
