"""Resources and crash safety: memory estimated before every large step (heatmaps and
reports stream the results; libraries and LUTs are sized from their headers), nothing created by a run
that fails, a killed sweep resumed by the same command whatever the budget, no stale or leftover files.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
import zipfile
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow.parquet as pq
import pytest
from sweep_fixtures import SMALL_SWEEP_TOML, gvmi_job, numpy_evaluator

from s2cl.errors import InputError, ResourceError
from s2cl.grid import DEFAULT_GRID
from s2cl.io.budget import Budget

SMALL = SMALL_SWEEP_TOML.format(copies=2)


def run(*args: str, cwd: Path, env: dict[str, str] | None = None) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "s2cl", *args], cwd=cwd, capture_output=True, text=True,
                          timeout=600, env={**os.environ, **(env or {})})


def one_line_error(out: subprocess.CompletedProcess, *parts: str) -> str:
    assert out.returncode == 2, (out.returncode, out.stdout, out.stderr)
    lines = out.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), out.stderr
    for part in parts:
        assert part in lines[0], (part, lines[0])
    return lines[0]


def scene(tmp_path: Path, text: str = SMALL, **replace: str) -> Path:
    for old, new in replace.items():
        assert old in text, old
        text = text.replace(old, new)
    path = tmp_path / "s.toml"
    path.write_text(text)
    return path


# -- V2.1: the report streams the results; heatmaps are bounded; the estimate holds the report -------------

def _results_frame(n_centres: int, n_widths: int, seed: int = 0) -> pd.DataFrame:
    rng = np.random.default_rng(seed)
    c = np.repeat(600.0 + 0.1 * np.arange(n_centres), n_widths)
    w = np.tile(10.0 + 0.1 * np.arange(n_widths), n_centres)
    n = c.size
    return pd.DataFrame({"config": np.arange(n), "B4_centre_nm": c, "B4_width_nm": w,
                         "B5_centre_nm": np.full(n, 705.0), "B5_width_nm": np.full(n, 15.0),
                         "rms": rng.random(n), "robust_rms": rng.random(n), "failed_fraction": np.zeros(n),
                         "bound_fraction": np.zeros(n), "underdetermined": rng.random(n) < 0.1})


def test_heatmap_grid_is_binned_to_a_bounded_size(tmp_path) -> None:
    from PIL import Image

    from s2cl.sweep.digest import HEATMAP_CENTRES, HEATMAP_WIDTHS, Digest
    from s2cl.sweep.report import heatmap

    df = _results_frame(301, 151)
    d = Digest.of_frame(df, {"underdetermined": "keep"})
    centres, widths, values, (gc, gw) = d.binned_grid("B4")
    assert values.shape == (len(centres), len(widths))
    assert values.shape[0] <= HEATMAP_CENTRES and values.shape[1] <= HEATMAP_WIDTHS and (gc, gw) == (6, 4)
    assert np.nanmin(values) == df["rms"].min()  # the best pair is in the best cell
    assert centres[0] == "600–600.5" and widths[-1] == "24.8–25"
    png = heatmap(d, "B4", tmp_path / "h.png")
    assert max(Image.open(png).size) < 2200  # the figure does not grow with the variants


def test_the_digest_streams_and_equals_the_in_memory_summary(tmp_path, monkeypatch) -> None:
    import s2cl.sweep.digest as digest
    import s2cl.sweep.folder as folder
    from s2cl.sweep.engine import run_sweep
    from s2cl.sweep.report import Digest, open_results, summarise

    monkeypatch.setattr(folder, "ROW_GROUP_ROWS", 50)
    monkeypatch.setattr(digest, "BATCH_ROWS", 37)
    job = gvmi_job(chunk=64)
    path, meta = open_results(run_sweep(job, tmp_path / "out", evaluator=numpy_evaluator(job)))
    assert pq.ParquetFile(path).metadata.num_row_groups == -(-job.n_configs // 50)
    seen: list[int] = []
    real = digest._batches

    def batches(p):
        for b in real(p):
            seen.append(len(b))
            yield b

    monkeypatch.setattr(digest, "_batches", batches)
    monkeypatch.setattr(pq, "read_table", lambda *a, **k: pytest.fail("the report read the whole table"))
    reference = {"B8_centre_nm": 842.0, "B8_width_nm": 115.0, "B11_centre_nm": 1610.0, "B11_width_nm": 90.0,
                 "rms": 0.002}
    streamed = summarise(Digest.of_file(path, meta, reference=reference), meta, reference)
    assert max(seen) <= 37 and sum(seen) == job.n_configs
    monkeypatch.undo()
    df = pq.read_table(path).to_pandas()
    whole = summarise(df, meta, reference)
    assert json.dumps(streamed, sort_keys=True) == json.dumps(whole, sort_keys=True)
    assert streamed["configurations"] == job.n_configs and streamed["reference"]["configurations_better"] >= 0
    by_pair = df.groupby(["B11_centre_nm", "B11_width_nm"])["rms"].min()
    d = Digest.of_frame(df, meta)
    (c, w), best = next(iter(by_pair.items()))
    assert d.value("B11", c, w) == best and d.variants("B11") == len(by_pair)


def test_the_sweep_estimate_holds_the_report_and_refuses_what_does_not_fit(tmp_path) -> None:
    from s2cl.app.checks import check_sweep
    from s2cl.app.sweep_budget import HEATMAP_BYTES, sweep_resources
    from s2cl.scene.scene import Scene

    fine = scene(tmp_path, **{"B4 = { centres = [665, 675, 685], widths = [20, 30] }":
                              "B4 = { left = 640, right = 700, min_width = 10, max_width = 40 }",
                              "[sweep]": "[sweep]\nstep_nm = 0.5"})
    checked = check_sweep(Scene.load(fine))
    plan = sweep_resources(checked, budget=Budget(10**10, "test"))
    assert plan.memory_bytes > 350e6 + HEATMAP_BYTES
    out = run("sweep", "count", "-q", str(fine), "--max-memory", "500M", cwd=tmp_path)
    one_line_error(out, "s.toml: ", "more than 500 MB")
    assert list(tmp_path.iterdir()) == [fine]


# -- V2.2: libraries are sized from their metadata before they are parsed ---------------------------------

def test_a_csv_library_is_refused_from_its_header_before_parsing(tmp_path, monkeypatch) -> None:
    import s2cl.libraries.files as files

    names = ",".join(f"s{i}" for i in range(3000))
    rows = "".join(f"{w}," + ",".join(["0.1"] * 3000) + "\n" for w in range(400, 2501, 20))
    (tmp_path / "wide.csv").write_text(f"wavelength_nm,{names}\n{rows}")
    monkeypatch.setattr(files, "_csv_values", lambda *a, **k: pytest.fail("parsed before the budget check"))
    # by hand: 350 MB baseline, the values as read (106 rows × 3,001 columns × 8 bytes = 2,544,848), the spectra on
    # the 1 nm grid (3,000 × 2,101 × 8 = 50,424,000) and their finiteness test (3,000 × 2,101 × 1 = 6,303,000):
    # 409.3 MB; under 400 MB, (400 - 350 - 6.303) MB over 2,101 · 8 + 2,544,848 / 3,000 bytes a spectrum: 2,474 fit
    with pytest.raises(ResourceError, match=r"wide.csv: reading its 3,000 spectra onto the grid .* more than "
                                            r"400 MB \(test\); at most 2,474 spectra fit") as err:
        files.load_csv_library(tmp_path / "wide.csv", DEFAULT_GRID, budget=Budget(400_000_000, "test"))
    assert err.value.key is None and str(err.value).startswith(str(tmp_path / "wide.csv"))
    monkeypatch.undo()
    lib = files.load_csv_library(tmp_path / "wide.csv", DEFAULT_GRID, budget=Budget(10**9, "test"))
    assert lib.size == 3000 and np.allclose(lib.spectra, 0.1)


def test_an_envi_library_is_refused_from_its_header(tmp_path) -> None:
    from s2cl.libraries.files import load_envi_library

    (tmp_path / "big.hdr").write_text(
        "ENVI\nfile type = ENVI Spectral Library\nsamples = 2101\nlines = 100000\nbands = 1\nheader offset = 0\n"
        "data type = 1\ninterleave = bsq\nbyte order = 0\nwavelength units = Nanometers\nwavelength = {"
        + ",".join(str(w) for w in range(400, 2501)) + "}\n")
    with open(tmp_path / "big.sli", "wb") as f:  # sparse: 210 MB declared, nothing on disk
        f.truncate(2101 * 100000)
    with pytest.raises(ResourceError, match=r"big.hdr: reading its 100,000 spectra .* more than 1.0 GB"):
        load_envi_library(tmp_path / "big.hdr", DEFAULT_GRID, budget=Budget(10**9, "test"))


def test_only_libraries_stream_and_large_tables_are_refused(tmp_path, monkeypatch) -> None:
    import s2cl.io.tables as tables
    from s2cl.libraries.files import load_csv_library
    from s2cl.sensor.sensor import Sensor

    (tmp_path / "lib.csv").write_text("wavelength_nm,a,b\n" + "".join(f"{w},0.1,0.2\n" for w in range(400, 2501, 20)))
    monkeypatch.setattr(tables, "read_csv_rows", lambda *a, **k: pytest.fail("a library read whole"))
    assert load_csv_library(tmp_path / "lib.csv", DEFAULT_GRID).size == 2
    monkeypatch.undo()
    with open(tmp_path / "sensor.csv", "wb") as f:
        f.truncate(tables.MAX_TABLE_BYTES + 1)
    with pytest.raises(InputError, match="larger than 16 MiB"):
        Sensor.from_csv(tmp_path / "sensor.csv")


# -- V2.3: a LUT's arrays are checked from their .npy headers before anything is loaded -------------------

def _lut_with(tmp_path: Path, name: str, shape: tuple[int, ...], descr: str = "<f4") -> Path:
    """The shipped LUT with member ``name`` replaced by a header declaring ``shape`` and 16 bytes of data."""
    from s2cl.atmos.atmosphere import default_lut_path

    path = tmp_path / "bomb.npz"
    with zipfile.ZipFile(default_lut_path()) as src, zipfile.ZipFile(path, "w") as dst:
        for info in src.infolist():
            if info.filename != f"{name}.npy":
                dst.writestr(info.filename, src.read(info))
                continue
            with dst.open(info.filename, "w", force_zip64=True) as f:
                np.lib.format.write_array_header_2_0(f, {"descr": descr, "fortran_order": False, "shape": shape})
                f.write(b"\0" * 16)
    return path


@pytest.mark.parametrize(("name", "shape", "message"), [
    ("wavelength_nm", (1_250_000_000,), "wavelength_nm: must be a list of 1 to 3,751 values"),
    ("t_down", (2, 7, 12, 2101 * 10**5), "t_down: expected float array of shape (2, 7, 12, 2101)"),
    ("provenance", (), "provenance: must be text of at most"),
])
def test_a_lut_zip_bomb_is_refused_before_loading(tmp_path, monkeypatch, name, shape, message) -> None:
    import s2cl.atmos.atmosphere as atmosphere

    descr = "<U100000000" if name == "provenance" else "<f4"
    path = _lut_with(tmp_path, name, shape, descr)
    monkeypatch.setattr(atmosphere.np, "load", lambda *a, **k: pytest.fail("loaded before the headers were checked"))
    with pytest.raises(InputError, match="bomb.npz: " + message.replace("(", r"\(").replace(")", r"\)")):
        atmosphere.AtmosphereLUT.load(path)


def test_a_lut_over_the_size_limit_or_with_objects_is_refused(tmp_path, monkeypatch) -> None:
    import s2cl.atmos.lut_format as lut_format
    from s2cl.atmos.atmosphere import AtmosphereLUT, default_lut_path

    monkeypatch.setattr(lut_format, "MAX_LUT_BYTES", 1_000_000)
    with pytest.raises(InputError, match=r"its arrays declare 4,\d{3},\d{3} bytes \(at most 1,000,000\)"):
        AtmosphereLUT.load(default_lut_path())
    path = _lut_with(tmp_path, "e0", (2101,), "|O")
    with pytest.raises(InputError, match="e0: holds an array of Python objects"):
        AtmosphereLUT.load(path)


def test_lut_bomb_through_the_command_line(tmp_path) -> None:
    path = _lut_with(tmp_path, "path_reflectance_scattering", (2, 7, 12, 10**9))
    text = SMALL.replace("[effects]", f'[atmosphere]\nlut = "{path.name}"\n[effects]')
    for command in (["simulate", "-q"], ["sweep", "count", "-q"]):
        one_line_error(run(*command, str(scene(tmp_path, text)), cwd=tmp_path), "bomb.npz: path_reflectance")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bomb.npz", "s.toml"]


# -- V5: a run that fails creates nothing -------------------------------------------------------------------

def test_a_bad_cube_creates_no_folder(tmp_path) -> None:
    text = ('[scene]\nname = "cube"\n[surface]\ncube = "missing.nc"\ngsd_m = 10\nquantity = "reflectance"\n'
            "[effects]\natmosphere = true\n")
    one_line_error(run("simulate", "-q", str(scene(tmp_path, text)), cwd=tmp_path), "missing.nc")
    (tmp_path / "zero.nc").write_bytes(b"\0" * 4096)
    one_line_error(run("simulate", "-q", str(scene(tmp_path, text.replace("missing", "zero"))), cwd=tmp_path),
                   "zero.nc")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s.toml", "zero.nc"]


def test_an_unreachable_scheduler_is_refused_before_anything_is_created(tmp_path) -> None:
    """Refused in one line that bounds the wait (no wall-clock assertion: a hang ends at run()'s time limit)."""
    pytest.importorskip("dask.distributed")
    for address, why in (("tcp://127.0.0.1:1", "cannot connect to the Dask scheduler 'tcp://127.0.0.1:1'"),
                         ("bogus", "'bogus' is not a scheduler address")):
        line = one_line_error(run("optimise", "-q", str(scene(tmp_path)), "--scheduler", address, "-o", "out",
                                  cwd=tmp_path), "--scheduler: " + why)
        assert address == "bogus" or "waited at most" in line
    assert not (tmp_path / "out").exists()


def test_a_device_that_cannot_compile_creates_nothing(tmp_path, monkeypatch, capsys) -> None:
    """A listed device whose compiler builds no probe width (the wheel's PoCL on a CPU its LLVM does not know)
    is refused in one line before anything is created."""
    import importlib

    import s2cl.cl.runtime as runtime
    import s2cl.sweep.engine as engine

    monkeypatch.setattr(runtime, "builds_at_all", lambda info: "error: unknown target CPU 'generic'")
    monkeypatch.setattr(runtime, "_RUNTIMES", {})
    monkeypatch.setattr(engine, "_EVALUATORS", {})
    cli_main = importlib.import_module("s2cl.cli.main")
    monkeypatch.setattr(cli_main, "_on_sigterm", lambda: None)  # pytest keeps its own SIGTERM handling
    monkeypatch.chdir(tmp_path)
    path = scene(tmp_path)
    for command in ("simulate", "optimise"):
        with pytest.raises(SystemExit) as code:
            cli_main.main([command, "-q", str(path), "-o", "out"])
        assert code.value.code == 2
        said = capsys.readouterr().err.strip().splitlines()
        assert len(said) == 1 and "cannot compile s2cl's kernels (error: unknown target CPU 'generic')" in said[0]
    assert not (tmp_path / "out").exists()


def test_a_failed_run_removes_the_folder_it_created(tmp_path) -> None:
    from s2cl.io.outdir import claim

    with pytest.raises(RuntimeError), claim(tmp_path / "a" / "b") as out:
        (out / "manifest.json").write_text("{}")
        (out / "chunks").mkdir()
        raise RuntimeError("failed before any result")
    assert not (tmp_path / "a").exists()
    (tmp_path / "kept").mkdir()
    with pytest.raises(RuntimeError), claim(tmp_path / "kept" / "out") as out:
        (out / "results.parquet").write_text("a result")
        raise RuntimeError("failed after a result")
    assert (tmp_path / "kept" / "out" / "results.parquet").exists()
    assert not (tmp_path / "kept" / "out" / ".s2cl.lock").exists()


# -- V7: a killed sweep resumes with the same command ---------------------------------------------------------

def test_an_empty_chunks_folder_without_manifest_is_a_fresh_folder(tmp_path) -> None:
    from s2cl.sweep.engine import MANIFEST, run_sweep

    out = tmp_path / "out"
    (out / "chunks").mkdir(parents=True)  # killed after mkdir, before the manifest (older versions)
    (out / ".manifest.json.abcd1234.tmp").write_text('{"half": ')  # killed while writing it
    job = gvmi_job()
    run_sweep(job, out, evaluator=numpy_evaluator(job))
    assert (out / MANIFEST).exists() and (out / "results.parquet").exists()


def test_metrics_and_results_do_not_depend_on_the_chunk(tmp_path) -> None:
    from s2cl.sweep.engine import evaluate_chunk, run_sweep

    job = gvmi_job(chunk=1)
    ev = numpy_evaluator(job)
    n = job.n_configs
    whole = evaluate_chunk(job, 0, n, evaluator=ev)
    for size in (1, 7):
        parts = [evaluate_chunk(job, a, min(a + size, n), evaluator=ev) for a in range(0, n, size)]
        for k, v in whole.items():
            assert np.array_equal(np.concatenate([p[k] for p in parts]), v, equal_nan=True), (size, k)
    files = [run_sweep(gvmi_job(chunk=c), tmp_path / f"c{c}", evaluator=ev).read_bytes() for c in (3, 100)]
    assert files[0] == files[1]


def test_a_sweep_resumes_in_its_own_chunks_under_another_budget(tmp_path) -> None:
    path = scene(tmp_path)
    first = run("optimise", "-q", str(path), "-o", "out", "--chunk", "2", cwd=tmp_path)
    assert first.returncode == 0, first.stderr
    out = tmp_path / "out"
    reference = (out / "results.parquet").read_bytes()
    (out / "results.parquet").unlink()
    (out / "chunks" / "part-0000000002.parquet").unlink()
    again = run("sweep", "run", str(path), "-o", "out", "--max-memory", "3G", cwd=tmp_path)
    assert again.returncode == 0, again.stderr
    assert "4 configurations already done, 2 to go" in again.stdout and "chunks of 2" in again.stdout
    assert (out / "results.parquet").read_bytes() == reference
    line = one_line_error(run("sweep", "run", "-q", str(path), "-o", "out", "--chunk", "3", cwd=tmp_path), "--chunk")
    assert "runs in chunks of 2" in line


# -- V8: no stale or leftover files ---------------------------------------------------------------------------

def test_sigterm_removes_the_temporary_file_and_exits_143(tmp_path) -> None:
    path = scene(tmp_path, **{"copies = 2": "copies = 5000"})
    proc = subprocess.Popen([sys.executable, "-m", "s2cl", "simulate", "-q", str(path), "-o", "out"], cwd=tmp_path,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.time() + 120
    while time.time() < deadline and not list((tmp_path / "out").glob(".simulation.nc.*.tmp")):
        time.sleep(0.01)
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=120)
    if proc.returncode == 0:
        pytest.skip("the run finished before SIGTERM arrived")
    assert proc.returncode == 143 and err.strip() == "terminated", err
    assert not (tmp_path / "out").exists()  # no temporary file, and the folder it had created is gone


def test_a_failed_run_removes_a_temporary_file_its_writer_had_not_guarded_yet(tmp_path) -> None:
    """A signal handled between an atomic write's creating its temporary file and guarding it (seen once in 20
    SIGTERMs on a loaded machine) left the file, and so the folder: the claim removes its run's temporaries on any
    failure, and the folder where it holds no result (a result stays)."""
    from s2cl.io.outdir import claim

    with pytest.raises(KeyboardInterrupt), claim(tmp_path / "out") as out:
        (out / ".simulation.nc.k3x9q2ab.tmp").write_bytes(b"partial")
        raise KeyboardInterrupt
    assert not (tmp_path / "out").exists()
    with pytest.raises(KeyboardInterrupt), claim(tmp_path / "kept") as out:
        (out / "simulation.nc").write_bytes(b"finished")
        (out / ".simulation.json.k3x9q2ab.tmp").write_bytes(b"partial")
        raise KeyboardInterrupt
    assert sorted(p.name for p in (tmp_path / "kept").iterdir()) == ["simulation.nc"]


def test_overwrite_removes_the_previous_sweeps_derived_files(tmp_path) -> None:
    from s2cl.sweep.engine import run_sweep

    out = tmp_path / "out"
    job = gvmi_job()
    run_sweep(job, out, evaluator=numpy_evaluator(job))
    for stale in ("heatmap_B6.png", "summary.json"):
        (out / stale).write_text("from the previous sweep")
    (out / "simulation.json").write_text("not a sweep file")
    other = gvmi_job(b11_max_width=100.0)
    run_sweep(other, out, evaluator=numpy_evaluator(other), overwrite=True)
    assert sorted(p.name for p in out.iterdir()) == ["chunks", "manifest.json", "results.parquet", "simulation.json"]


def test_the_lock_file_lives_only_while_a_run_holds_the_folder(tmp_path) -> None:
    from s2cl.errors import OutputError
    from s2cl.io.outdir import LOCK_NAME, claim

    with claim(tmp_path / "out") as out:
        assert (out / LOCK_NAME).exists()
        with pytest.raises(OutputError, match="another s2cl run"), claim(out):
            pass
    assert not (tmp_path / "out" / LOCK_NAME).exists()
    with claim(tmp_path / "out"):  # the next run takes the folder
        pass
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == []


@pytest.mark.slow
def test_a_local_dask_cluster_keeps_its_scratch_in_the_output_folder(tmp_path, monkeypatch) -> None:
    pytest.importorskip("dask.distributed")
    import dask.distributed

    from s2cl.sweep.cluster import DASK_SCRATCH
    from s2cl.sweep.engine import run_sweep

    used: list[str] = []
    real = dask.distributed.LocalCluster

    def cluster(*args, **kwargs):
        used.append(kwargs["local_directory"])
        return real(*args, **kwargs)

    monkeypatch.setattr(dask.distributed, "LocalCluster", cluster)
    job = gvmi_job(chunk=200)
    run_sweep(job, tmp_path / "out", evaluator=numpy_evaluator(job), workers=1)
    assert used == [str(tmp_path / "out" / DASK_SCRATCH)]
    assert not (tmp_path / "out" / DASK_SCRATCH).exists()
