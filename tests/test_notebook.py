"""The worked example, docs/examples/choose-red-edge-bands.ipynb, runs top to bottom on a fresh clone (it cannot
rot): the sweep through ``s2cl.optimise``, the ranking and heatmap plots, a user CSV library with parameters, a user
sensor table, and two designs compared."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

NOTEBOOK = Path(__file__).resolve().parent.parent / "docs" / "examples" / "choose-red-edge-bands.ipynb"


@pytest.mark.slow
@pytest.mark.skipif(not NOTEBOOK.is_file(), reason="docs/ is not in this checkout")
def test_the_worked_example_runs_and_the_swept_design_wins(tmp_path) -> None:
    nbformat = pytest.importorskip("nbformat")
    nbclient = pytest.importorskip("nbclient")
    pytest.importorskip("ipykernel")
    nb = nbformat.read(NOTEBOOK, as_version=4)
    assert not any(c.get("outputs") for c in nb.cells if c.cell_type == "code"), "commit the notebook without outputs"
    nbclient.NotebookClient(nb, timeout=600, kernel_name="python3", resources={"metadata": {"path": str(tmp_path)}}
                            ).execute()
    text = "".join(o.get("text", "") for o in nb.cells[-1].outputs)
    rms = {name: float(v) for name, v in re.findall(r"^(A|B): .*?cab RMS ([0-9.]+)", text, flags=re.M)}
    assert set(rms) == {"A", "B"}, text
    assert rms["B"] < rms["A"], text  # the sweep's best design beats ESA's on the same pixels and noise
    assert (tmp_path / "notebook-out" / "default" / "results.parquet").is_file()
    assert any(o.get("output_type") == "display_data" for c in nb.cells for o in c.get("outputs", []))
