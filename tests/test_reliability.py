"""Every bad input a one-line error, every fault survived, no run can exhaust the machine.

Each test runs the real command line in a subprocess (as a user would) and checks the exit code, that
stderr is one ``error: FILE: KEY: ...`` line without a traceback, and what was (not) written.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from sweep_fixtures import SMALL_SWEEP_TOML

DEFAULT_SCENE = Path(__file__).resolve().parents[1] / "scenes" / "default.toml"
DATA = Path(__file__).resolve().parent / "data"

SMALL = SMALL_SWEEP_TOML.format(copies=2)


def run(*args: str, cwd: Path, env: dict[str, str] | None = None) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "s2cl", *args], cwd=cwd, capture_output=True, text=True,
                          timeout=600, env={**os.environ, **(env or {})})


def peak_rss_mb(*args: str, cwd: Path) -> tuple[subprocess.CompletedProcess, float]:
    """Run the CLI in a fresh child of a fresh Python: its outcome and its peak resident set (MB)."""
    probe = ("import json, resource, subprocess, sys; p = subprocess.run(sys.argv[1:], capture_output=True, "
             "text=True); print(json.dumps([resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024, "
             "p.returncode, p.stdout, p.stderr]))")
    out = subprocess.run([sys.executable, "-c", probe, sys.executable, "-m", "s2cl", *args], cwd=cwd,
                         capture_output=True, text=True, timeout=600, check=True)
    mb, rc, stdout, stderr = json.loads(out.stdout)
    return subprocess.CompletedProcess(args, rc, stdout, stderr), mb


def one_line_error(out: subprocess.CompletedProcess, *parts: str) -> str:
    """Assert rc 2 and a single ``error:`` line on stderr holding every one of ``parts``."""
    assert out.returncode == 2, (out.returncode, out.stdout, out.stderr)
    lines = out.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), out.stderr
    assert "Traceback" not in out.stderr
    for part in parts:
        assert part in lines[0], (part, lines[0])
    return lines[0]


def files_under(root: Path) -> set[str]:
    return {str(p.relative_to(root)) for p in root.rglob("*")}


def scene(tmp_path: Path, text: str = SMALL, name: str = "s.toml", **replace: str) -> Path:
    for old, new in replace.items():
        assert old in text, old
        text = text.replace(old, new)
    path = tmp_path / name
    path.write_text(text)
    return path


@contextmanager
def read_only(path: Path) -> Iterator[None]:
    """``path`` read-only for this process: permissions for a normal user, a read-only bind mount for
    root (which permissions do not stop); skipped where neither is possible."""
    if os.geteuid() != 0:
        mode = path.stat().st_mode
        for p in [path, *path.rglob("*")]:
            if p.is_dir():
                p.chmod(0o555)
        try:
            yield
        finally:
            for p in [path, *path.rglob("*")]:
                if p.is_dir():
                    p.chmod(mode)
        return
    bind = subprocess.run(["mount", "--bind", str(path), str(path)], capture_output=True)
    if bind.returncode:
        pytest.skip("cannot make a read-only folder here (root without mount rights)")
    try:
        subprocess.run(["mount", "-o", "remount,ro,bind", str(path)], check=True, capture_output=True)
        yield
    finally:
        subprocess.run(["umount", str(path)], capture_output=True)


@contextmanager
def small_filesystem(path: Path, size: str = "200k") -> Iterator[Path]:
    """A tiny tmpfs at ``path`` (root only; skipped elsewhere)."""
    path.mkdir()
    if subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={size}", "tmpfs", str(path)],
                      capture_output=True).returncode:
        pytest.skip("cannot mount a small filesystem here (needs root)")
    try:
        yield path
    finally:
        subprocess.run(["umount", str(path)], capture_output=True)


@pytest.fixture(scope="module")
def finished_sweep(tmp_path_factory) -> Path:
    """A finished small sweep: the folder of `s2cl optimise` (6 configurations)."""
    root = tmp_path_factory.mktemp("sweep")
    out = run("optimise", str(scene(root)), "-q", "-o", "out", cwd=root)
    assert out.returncode == 0, out.stderr
    return root / "out"


# -- escapes and leaks ------------------------------------------------------------------------------

@pytest.mark.parametrize("name", ["../../X", "/tmp/s2cl-escape", ".hidden", "a/b", ""])
def test_scene_name_cannot_leave_the_output_folder(tmp_path, name: str) -> None:
    work = tmp_path / "w" / "v"
    work.mkdir(parents=True)
    path = scene(work, **{'name = "small"': f"name = {json.dumps(name)}"})
    before = files_under(tmp_path)
    one_line_error(run("simulate", "-q", str(path), cwd=work), "s.toml: scene.name:")
    assert files_under(tmp_path) == before and not Path("/tmp/s2cl-escape").exists()


def test_errors_never_echo_the_content_of_a_linked_file(tmp_path) -> None:
    secret = tmp_path / "secret.txt"
    secret.write_text("TOPSECRET-password-1234567890,second\n1,2\n3,4\n")
    (tmp_path / "lib.csv").symlink_to(secret)
    path = scene(tmp_path, **{'library = "builtin:lib1"': 'library = "lib.csv"'})
    line = one_line_error(run("simulate", "-q", str(path), cwd=tmp_path), "lib.csv")
    assert "TOPSECRET" not in line and "password" not in line
    (tmp_path / "lib2.csv").write_text("wavelength_nm,a\n400,TOPSECRET-password-1234567890\n2500,0.1\n")
    path = scene(tmp_path, **{'library = "builtin:lib1"': 'library = "lib2.csv"'})
    line = one_line_error(run("simulate", "-q", str(path), cwd=tmp_path), "lib2.csv", "not a number")
    assert "password-1234567890" not in line  # a short, cut token at most


# -- crashes that became one-line errors -------------------------------------------------------------

def test_full_filesystem_is_refused_before_the_run(tmp_path) -> None:
    path = scene(tmp_path, **{"copies = 2": "copies = 10"})
    with small_filesystem(tmp_path / "tiny") as tiny:
        one_line_error(run("simulate", "-q", str(path), "-o", str(tiny / "out"), cwd=tmp_path), "disk")
        one_line_error(run("optimise", "-q", str(path), "-o", str(tiny / "opt"), cwd=tmp_path), "disk")
        assert files_under(tiny) == set()


def test_disk_filling_during_the_write_is_an_output_error(tmp_path) -> None:
    """Another process fills the disk after the check: the streamed write fails in one error, no temp file."""
    from s2cl.app.checks import check_simulate
    from s2cl.app.simulate import simulate_to_netcdf
    from s2cl.errors import OutputError
    from s2cl.scene.scene import Scene

    checked = check_simulate(Scene.load(scene(tmp_path, **{"copies = 2": "copies = 200"})))
    with small_filesystem(tmp_path / "small", "3m") as small:
        with pytest.raises(OutputError, match=r"sim.nc: cannot write \(No space left on device\)"):
            simulate_to_netcdf(checked, small / "sim.nc")
        assert files_under(small) == set()


@pytest.mark.parametrize("damage", ["corrupt", "truncated", "foreign", "unfinished", "band"])
def test_sweep_report_refuses_what_it_cannot_read(finished_sweep, tmp_path, damage: str) -> None:
    folder = tmp_path / "out"
    folder.mkdir()
    good = (finished_sweep / "results.parquet").read_bytes()
    args = ["sweep", "report", "out"]
    if damage == "corrupt":
        (folder / "results.parquet").write_bytes(b"PAR1" + os.urandom(3000))
        expected = "not a readable Parquet file"
    elif damage == "truncated":
        (folder / "results.parquet").write_bytes(good[: len(good) // 2])
        expected = "not a readable Parquet file"
    elif damage == "foreign":
        pq.write_table(pa.table({"x": [1, 2], "rms": [0.1, 0.2]}), folder / "results.parquet")
        expected = "not an s2cl sweep result"
    elif damage == "unfinished":
        (folder / "manifest.json").write_text("{}")
        (folder / "chunks").mkdir()
        expected = "did not finish"
    else:
        (folder / "results.parquet").write_bytes(good)
        args += ["--band", "B99"]
        expected = "--band: 'B99' is not a band of these results"
    before = files_under(folder)
    one_line_error(run(*args, cwd=tmp_path), expected)
    assert files_under(folder) == before


def test_deeply_nested_scene_is_an_input_error(tmp_path) -> None:
    path = tmp_path / "deep.toml"
    path.write_text("[a]\nx = " + "[" * 2000 + "]" * 2000 + "\n")
    one_line_error(run("simulate", str(path), cwd=tmp_path), "deep.toml", "nested too deeply")


@pytest.mark.parametrize("command", ["simulate", "optimise", "sweep count"])
def test_missing_library_parameter_is_refused_by_every_command(tmp_path, command: str) -> None:
    path = scene(tmp_path, **{'parameter = "cab"': 'parameter = "x"'})
    one_line_error(run(*command.split(), str(path), cwd=tmp_path), "s.toml: analysis.parameter:", "'x'")
    (tmp_path / "lib.csv").write_text("wavelength_nm,a\n" + "".join(f"{w},0.3\n" for w in range(400, 2501, 10)))
    path = scene(tmp_path, **{'parameter = "cab"\n': "", 'library = "builtin:lib1"': 'library = "lib.csv"'})
    one_line_error(run(*command.split(), str(path), cwd=tmp_path), "analysis.parameter")
    assert files_under(tmp_path) == {"s.toml", "lib.csv"}


@pytest.mark.parametrize("command", ["simulate", "optimise"])
def test_unusable_output_folders(tmp_path, command: str) -> None:
    path = scene(tmp_path, **{"[scene]": '[output]\ndirectory = "/proc/self"\n[scene]'})
    one_line_error(run(command, "-q", str(path), cwd=tmp_path), "/proc/self", "virtual filesystem",
                   "output.directory")
    (tmp_path / "file").write_text("")
    one_line_error(run(command, "-q", str(scene(tmp_path)), "-o", "file/out", cwd=tmp_path), "file/out",
                   "not a folder")


def test_read_only_folders(finished_sweep, tmp_path) -> None:
    ro = tmp_path / "ro"
    ro.mkdir()
    shutil.copytree(finished_sweep, ro / "resume")
    before = files_under(ro)
    path = scene(tmp_path)
    with read_only(ro):
        one_line_error(run("optimise", "-q", str(path), "-o", "ro/new", cwd=tmp_path), "ro/new", "read-only")
        one_line_error(run("optimise", "-q", str(path), "-o", "ro/resume", cwd=tmp_path), "ro/resume", "read-only")
        one_line_error(run("srf", "B4", "--platform", "none", "--plot", "ro/b4.png", cwd=tmp_path), "read-only",
                       "--plot")
    assert files_under(ro) == before


def test_a_second_run_into_a_claimed_folder_refuses_and_the_claim_ends_with_the_run(finished_sweep, tmp_path) -> None:
    from filelock import FileLock

    out = tmp_path / "out"
    shutil.copytree(finished_sweep, out)
    (out / ".results.parquet.abcd1234.tmp").write_bytes(b"left by a killed run")
    path = scene(tmp_path)
    with FileLock(out / ".s2cl.lock", timeout=0):  # another run holds the folder
        for args in (["optimise", "-q", str(path), "-o", "out", "--overwrite"], ["simulate", "-q", str(path),
                                                                                  "-o", "out"]):
            one_line_error(run(*args, cwd=tmp_path), "out: another s2cl run is writing into this folder")
    assert (out / ".results.parquet.abcd1234.tmp").exists()
    again = run("sweep", "run", str(path), "-q", "-o", "out", cwd=tmp_path)
    assert again.returncode == 0 and "6 configurations already done, 0 to go" in again.stdout, again.stderr
    assert not list(out.rglob("*.tmp"))  # the stale temp file is gone


# -- memory and time ----------------------------------------------------------------------------------

def test_the_documented_maximum_copies_is_refused_quickly_in_one_line(tmp_path) -> None:
    path = scene(tmp_path, DEFAULT_SCENE.read_text(), **{"copies = 100 ": "copies = 1000000 "})
    for command in ("simulate", "optimise"):
        out, mb = peak_rss_mb(command, "-q", str(path), "-o", "out", cwd=tmp_path)
        line = one_line_error(out, "s.toml: surface.copies:", "copies fit")
        assert mb < 1000, (command, mb, line)
    assert not (tmp_path / "out").exists()
    out = run("simulate", "-q", str(path), "--max-memory", "lots", cwd=tmp_path)
    one_line_error(out, "--max-memory", "4G")


def test_a_cube_too_large_for_memory_is_refused_before_loading(tmp_path) -> None:
    import h5netcdf
    import numpy as np

    # declared 100 × 50,000 × 211, stored as fill values: the kernel reads its 211 bands as they are (at least the
    # samples as read, mapped and copied as float64, 2 · 8 · 211 = 3,376 bytes a pixel of a block), so one block of 6
    # rows takes more than 1.0 GB beside the 350 MB baseline
    with h5netcdf.File(tmp_path / "big.nc", "w") as f:
        f.dimensions = {"y": 100, "x": 50000, "wavelength": 211}
        f.create_variable("wavelength", ("wavelength",), float, data=np.linspace(400, 2500, 211))
        f.create_variable("reflectance", ("y", "x", "wavelength"), np.float32, chunks=(100, 100, 211))
    text = ('[scene]\nname = "cube"\n[surface]\ncube = "big.nc"\ngsd_m = 10\nquantity = "reflectance"\n'
            "[effects]\natmosphere = true\n")
    out, mb = peak_rss_mb("simulate", "-q", str(scene(tmp_path, text)), "-o", "out", "--max-memory", "1G",
                          cwd=tmp_path)  # a file streams by rows: refused when not even one block of rows fits
    one_line_error(out, "s.toml: surface.cube:", "5,000,000 pixels × 211 wavelengths in blocks of 6 rows",
                   "crop the cube")
    assert mb < 1000 and not (tmp_path / "out").exists()


@pytest.mark.slow
def test_the_documented_maximum_copies_streams_in_bounded_memory(tmp_path) -> None:
    """10^6 copies × 2 spectra × 13 bands (380 MB of NetCDF): written chunk by chunk, peak about 1 GB."""
    out, mb = peak_rss_mb("simulate", "-q", str(DATA / "max_copies.toml"), "-o", "out", cwd=tmp_path)
    assert out.returncode == 0, out.stderr
    assert mb < 2000, mb
    record = json.loads((tmp_path / "out" / "simulation.json").read_text())
    assert record["pixels"] == 2_000_000 and len(record["bands"]) == 13
    import xarray as xr

    with xr.open_dataset(tmp_path / "out" / "simulation.nc", engine="h5netcdf") as ds:
        assert ds["dn"].shape == (13, 2, 1_000_000)
        assert int(ds["dn"][3, 1, -1]) > 0 and int(ds["pixel_spectrum"][1, -1]) == 1


def test_counting_never_enumerates_variants(tmp_path) -> None:
    out, mb = peak_rss_mb("sweep", "count", "-q", str(DATA / "fine_step.toml"), cwd=tmp_path)
    assert mb < 1000
    assert out.stdout == "92289537813761446563441568056001\n"  # -q: the count only
    line = one_line_error(out, "fine_step.toml: sweep.step_nm:", "392,056,004 band variants")
    assert "GB of memory" in line
    out = run("sweep", "count", "-q", str(scene(tmp_path)), cwd=tmp_path)
    assert out.returncode == 0 and out.stdout.strip() == "6"


# -- silently wrong results now warned or refused ------------------------------------------------------

def test_one_bit_is_warned_and_recorded(tmp_path) -> None:
    path = scene(tmp_path, **{"correct = true": "correct = true\nbits = 1"})
    out = run("simulate", "-q", str(path), "-o", "out", cwd=tmp_path)
    assert out.returncode == 0, out.stderr
    assert "WARNING: effects.bits: 1 bits: quantisation noise exceeds the sensor noise" in out.stderr
    record = json.loads((tmp_path / "out" / "simulation.json").read_text())
    assert record["warnings"] and record["warnings"][0].startswith("effects.bits: 1 bits")


def test_coarse_grids_are_refused_or_warned(tmp_path) -> None:
    path = scene(tmp_path, **{"[effects]": "[grid]\nstep_nm = 50\n[effects]"})
    one_line_error(run("simulate", "-q", str(path), cwd=tmp_path), "s.toml: grid.step_nm:", "band B5",
                   "at most half")
    path = scene(tmp_path, **{"[effects]": "[grid]\nstep_nm = 5\n[effects]"})
    out = run("optimise", "-q", str(path), "-o", "out", cwd=tmp_path)
    assert out.returncode == 0 and "WARNING: grid.step_nm: 5 nm samples band(s)" in out.stderr, out.stderr
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert summary["warnings"][0].startswith("grid.step_nm: 5 nm")


def test_a_sweep_over_tabulated_srfs_says_it_uses_the_model(tmp_path) -> None:
    """A measured SRF describes only its band's own centre and width: a sweep warns that every variant
    (and the reference row) uses the model SRF; simulate, which uses the table, does not."""
    from s2cl.app.checks import check_simulate, check_sweep
    from s2cl.scene.scene import Scene

    path = scene(tmp_path, **{"[effects]": '[sensor]\nsrf = "measured-S2A"\n[effects]'})
    swept = [str(c) for c in check_sweep(Scene.load(path)).caveats]
    assert any(c.startswith("sensor.srf: the sweep uses the model SRF") for c in swept), swept
    assert not [c for c in check_simulate(Scene.load(path)).caveats if str(c).startswith("sensor.srf")]


def test_radiance_libraries_from_csv(tmp_path) -> None:
    rows = "\n".join(f"{w},{50 + w / 100:.2f},{20 + w / 200:.2f}" for w in range(400, 2501, 10))
    (tmp_path / "toa.csv").write_text("wavelength_nm,bright,dark\n" + rows + "\n")
    text = '[scene]\nname = "toa"\n[surface]\nlibrary = "toa.csv"\nquantity = "radiance"\ncopies = 3\n'
    out = run("simulate", "-q", str(scene(tmp_path, text)), "-o", "out", cwd=tmp_path)
    assert out.returncode == 0, out.stderr
    assert json.loads((tmp_path / "out" / "simulation.json").read_text())["pixels"] == 6
    text = text.replace('quantity = "radiance"', 'quantity = "reflectance"') + "[effects]\natmosphere = true\n"
    line = one_line_error(run("simulate", "-q", str(scene(tmp_path, text)), cwd=tmp_path), "toa.csv: bright:")
    assert 'surface.quantity = "radiance"' in line and "scale=" not in line


# -- errors name the file and the full key ---------------------------------------------------------------

@pytest.mark.parametrize("command", ["simulate", "optimise", "sweep count"])
@pytest.mark.parametrize(("replace", "key"), [
    ({"[effects]": "[atmosphere]\nwater_vapour = 50\n[effects]"}, "atmosphere.water_vapour"),
    ({'parameter = "cab"': 'parameter = "cab"\nbands = ["B99", "B4", "B5", "B6"]'}, "analysis.bands"),
    ({'parameter = "cab"': 'parameter = "cab"\nigrm = { bogus = 1 }'}, "analysis.igrm.bogus"),
    ({'parameter = "cab"': 'parameter = "cab"\nigrm = { max_iter = 0 }'}, "analysis.igrm.max_iter"),
])
def test_errors_name_the_scene_file_and_the_full_key(tmp_path, command: str, replace: dict, key: str) -> None:
    path = scene(tmp_path, **replace)
    one_line_error(run(*command.split(), str(path), "-q", cwd=tmp_path), f"s.toml: {key}:")
    assert files_under(tmp_path) == {"s.toml"}  # validated before anything was created


def test_study_keys_name_the_scene_file(tmp_path) -> None:
    text = (DEFAULT_SCENE.parent / "study-water-vapour.toml").read_text()
    path = scene(tmp_path, text, **{"water_vapour = [1.0, 2.0] }": "water_vapour = [-1.0] }"})
    one_line_error(run("study", str(path), "--quick", "-q", "-o", "out", cwd=tmp_path),
                   "s.toml: study.water_vapour:")
    assert not (tmp_path / "out").exists()


def test_device_names_are_strict_and_devices_survives_a_bogus_pyopencl_ctx(tmp_path) -> None:
    one_line_error(run("simulate", "-q", "--device", "0:0:0", "-o", "out", cwd=tmp_path), "'0:0:0'", "available")
    assert not (tmp_path / "out").exists()
    out = run("devices", cwd=tmp_path, env={"PYOPENCL_CTX": "bogus"})
    assert out.returncode == 0 and "\n* " in "\n" + out.stdout, out.stderr
    assert "$PYOPENCL_CTX='bogus' matches no device" in out.stderr
    one_line_error(run("simulate", "-q", "-o", "o", cwd=tmp_path, env={"PYOPENCL_CTX": "bogus"}),
                   "'bogus' ($PYOPENCL_CTX)")


# -- nothing lost, nothing left -----------------------------------------------------------------------------

def test_simulate_and_optimise_into_one_folder_keep_each_others_results(finished_sweep, tmp_path) -> None:
    out = tmp_path / "out"
    shutil.copytree(finished_sweep, out)
    before = (out / "summary.json").read_bytes()
    sim = run("simulate", "-q", str(scene(tmp_path)), "-o", "out", cwd=tmp_path)
    assert sim.returncode == 0, sim.stderr
    assert (out / "summary.json").read_bytes() == before  # the ranking summary is still the sweep's
    assert json.loads((out / "simulation.json").read_text())["pixels"] == 240
    assert "reference" in json.loads(before)


def test_every_command_has_quiet() -> None:
    import click

    from s2cl.cli.main import cli

    def commands(group: click.Group, prefix: str = "") -> Iterator[tuple[str, click.Command]]:
        for name, cmd in group.commands.items():
            yield prefix + name, cmd
            if isinstance(cmd, click.Group):
                yield from commands(cmd, prefix + name + " ")

    for name, cmd in commands(cli):
        if isinstance(cmd, click.Group):
            continue
        flags = {opt for p in cmd.params for opt in getattr(p, "opts", [])}
        assert {"-q", "--quiet"} <= flags, name
