"""The command line: the main jobs run, errors are one line with exit code 2, nothing partial is left."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pyarrow.parquet as pq
import pytest
import xarray as xr
from sweep_fixtures import SMALL_SWEEP_TOML

from s2cl.scene.scene import find_scene


def run(*args: str, cwd: Path) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "s2cl", *args], cwd=cwd, capture_output=True, text=True,
                          timeout=600)


def test_help_lists_the_commands(tmp_path) -> None:
    out = run("--help", cwd=tmp_path)
    assert out.returncode == 0
    for command in ("simulate", "optimise", "sweep", "sensor", "srf", "scenes", "libraries", "devices"):
        assert command in out.stdout


def test_simulate_default_scene(tmp_path) -> None:
    out = run("simulate", "--quiet", "--output", "sim", cwd=tmp_path)
    assert out.returncode == 0, out.stderr
    assert out.stderr == ""  # no compiler output, no warnings: only the "wrote ..." line on stdout
    assert "warning" not in out.stdout.lower()
    summary = json.loads((tmp_path / "sim" / "simulation.json").read_text())
    assert summary["pixels"] == 12_000 and len(summary["bands"]) == 13 and summary["warnings"] == []
    assert summary["analysis"]["kind"] == "igrm" and 0 < summary["analysis"]["rms"] < 30
    ds = xr.open_dataset(tmp_path / "sim" / "simulation.nc", engine="h5netcdf")
    assert ds["dn"].shape == (13, 120, 100) and ds["reflectance"].shape == (13, 120, 100)
    # CF-1.10: the convention, units everywhere, standard names where the CF table has them
    assert ds.attrs["Conventions"] == "CF-1.10"
    assert ds["noisy"].attrs["standard_name"] == "toa_outgoing_radiance_per_unit_wavelength"
    assert ds["reflectance"].attrs["standard_name"] == "surface_bidirectional_reflectance"
    assert ds["centre_nm"].attrs["standard_name"] == "sensor_band_central_radiation_wavelength"
    assert all("units" in ds[v].attrs for v in ("noisy", "dn", "calibrated", "reflectance", "band_radiance"))
    assert not list((tmp_path / "sim").glob(".*.tmp"))


def _small_sweep(tmp_path: Path) -> Path:
    scene = tmp_path / "small.toml"
    scene.write_text(SMALL_SWEEP_TOML.format(copies=5))
    return scene


def test_sweep_count_run_report_and_refuse_mixing(tmp_path) -> None:
    scene = _small_sweep(tmp_path)
    count = run("sweep", "count", str(scene), cwd=tmp_path)
    assert count.returncode == 0 and "configurations: 6" in count.stdout
    first = run("optimise", str(scene), "-q", "-o", "out", cwd=tmp_path)
    assert first.returncode == 0, first.stderr
    assert "warning" not in (first.stdout + first.stderr).lower()
    verbose = run("-v", "devices", cwd=tmp_path)  # -v: the DEBUG log on stderr
    assert verbose.returncode == 0 and "s2cl.cl.runtime DEBUG: OpenCL device" in verbose.stderr
    table = pq.read_table(tmp_path / "out" / "results.parquet")
    assert table.num_rows == 6 and table.schema.metadata[b"scene"] == b"small"
    assert (tmp_path / "out" / "heatmap_B4.png").stat().st_size > 1000
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert summary["reference"]["bands"]["B4"] == [665.0, 30.0]
    again = run("sweep", "run", str(scene), "-q", "-o", "out", cwd=tmp_path)
    assert again.returncode == 0 and "6 configurations already done, 0 to go" in again.stdout
    scene.write_text(scene.read_text().replace("copies = 5", "copies = 6"))
    mixed = run("sweep", "run", str(scene), "-q", "-o", "out", cwd=tmp_path)
    assert mixed.returncode == 2
    assert mixed.stderr.count("\n") == 1 and "different sweep" in mixed.stderr and "--overwrite" in mixed.stderr
    report = run("sweep", "report", "out", cwd=tmp_path)
    assert report.returncode == 0 and "best of 6" in report.stdout
    assert "reference" in report.stdout  # the sensor's own bands survive a re-report
    assert json.loads((tmp_path / "out" / "summary.json").read_text())["reference"] == summary["reference"]


def test_paper_scene_prints_the_papers_values(tmp_path) -> None:
    scene = _small_sweep(tmp_path)
    text = scene.read_text().replace('name = "small"', 'name = "table4-b4"')
    text = text.replace("centres = [665, 675, 685], widths = [20, 30]", "centres = [665, 680], widths = [30]")
    scene.write_text(text.replace("B5 = { centre = 705, width = 15 }", "B5 = { centre = 710, width = 20 }"))
    out = run("optimise", str(scene), "-q", "-o", "out", cwd=tmp_path)
    assert out.returncode == 0, out.stderr
    assert "Table 4 (B4" in out.stdout and "(19.9)" in out.stdout and "paper best 680/30 (4.7)" in out.stdout
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert summary["paper"]["table"] == "table4" and summary["paper"]["cells"] == 2
    assert (tmp_path / "out" / "heatmap_B4_vs_paper.png").stat().st_size > 1000


@pytest.mark.parametrize(
    ("args", "message"),
    [(["simulate", "no-such-scene"], "no scene file"),
     (["simulate", "missing.toml"], "scene file not found"),
     (["sweep", "count", "default", "--bogus"], "No such option"),
     (["optimise", "bad.toml"], "effects.bits"),
     (["srf", "B99"], "no band 'B99'"),
     (["simulate", "--device", "no-such-device"], "no OpenCL device matches"),
     (["simulate", "device.toml"], "no OpenCL device matches"),
     (["sweep", "run", "device.toml"], "no OpenCL device matches")],
)
def test_errors_are_one_line_with_exit_code(tmp_path, args: list[str], message: str) -> None:
    (tmp_path / "bad.toml").write_text('[scene]\nname = "b"\n[surface]\nlibrary = "builtin:lib1"\n'
                                       "[effects]\nbits = 40\n")
    # [compute] device is the scene's choice of device: refused before anything is made, like --device
    default = find_scene("default").read_text(encoding="utf-8")
    assert '# device = "pocl"' in default
    (tmp_path / "device.toml").write_text(default.replace('# device = "pocl"', 'device = "no-such-device"'))
    out = run(*args, cwd=tmp_path)
    assert out.returncode == 2
    assert message in out.stderr
    assert "Traceback" not in out.stderr
    assert not (tmp_path / "s2cl-out").exists()


def test_failed_simulation_leaves_no_output(tmp_path) -> None:
    (tmp_path / "lib.csv").write_text("wavelength_nm,a\n400,0.1\n1000,0.2\n")
    (tmp_path / "s.toml").write_text('[scene]\nname = "s"\n[surface]\nlibrary = "lib.csv"\nquantity = "reflectance"\n'
                                     "[effects]\natmosphere = true\n")
    out = run("simulate", "s.toml", "-o", "out", cwd=tmp_path)
    assert out.returncode == 2 and "lib.csv" in out.stderr and "2500" in out.stderr
    assert not (tmp_path / "out").exists()


def test_a_reader_that_leaves_before_the_output_gets_no_traceback(tmp_path) -> None:
    """`s2cl scenes | head -1` where the reader has gone before the first line: status 1, nothing on stderr (no
    BrokenPipeError from the write, none from the interpreter's flush at exit)."""
    proc = subprocess.Popen([sys.executable, "-m", "s2cl", "scenes"], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            cwd=tmp_path)
    assert proc.stdout is not None and proc.stderr is not None
    proc.stdout.close()
    err = proc.stderr.read()
    proc.wait(timeout=300)
    assert proc.returncode == 1 and err == b"", err[-1500:]
