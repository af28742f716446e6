"""Atomic outputs: complete or absent, and with the permissions the user's umask asks for."""

from __future__ import annotations

import os

import numpy as np
import pytest

from s2cl.io.cache import write_npz_atomic
from s2cl.io.output import write_atomic


@pytest.fixture
def umask_027():
    """A umask other than the usual 022, so that a hard-coded 0o644 would show."""
    old = os.umask(0o027)
    yield
    os.umask(old)


def test_atomic_outputs_follow_the_umask(tmp_path, umask_027) -> None:
    """mkstemp creates 0600 files; outputs get 0666 & ~umask like any other file."""
    path = write_atomic(tmp_path / "a.txt", lambda p: p.write_text("x"))
    assert (path.stat().st_mode & 0o777) == 0o640
    assert path.read_text() == "x"
    assert not list(tmp_path.glob(".a.txt.*"))


def test_npz_writer_is_atomic_deterministic_and_follows_the_umask(tmp_path, umask_027) -> None:
    arrays = {"a": np.arange(5.0), "b": np.ones((2, 3), np.float32)}
    one = write_npz_atomic(tmp_path / "one.npz", arrays)
    two = write_npz_atomic(tmp_path / "two.npz", arrays)
    assert one.read_bytes() == two.read_bytes()
    assert (one.stat().st_mode & 0o777) == 0o640
    with np.load(one) as z:
        assert np.array_equal(z["a"], arrays["a"]) and z["b"].dtype == np.float32
    assert sorted(p.name for p in tmp_path.iterdir()) == ["one.npz", "two.npz"]


def test_failed_write_leaves_nothing(tmp_path) -> None:
    def boom(p):
        p.write_text("half")
        raise RuntimeError("killed")

    with pytest.raises(RuntimeError):
        write_atomic(tmp_path / "b.txt", boom)
    assert list(tmp_path.iterdir()) == []


def test_cache_follows_the_platform_and_the_override(tmp_path, monkeypatch) -> None:
    """$S2CL_CACHE wins; otherwise the platform's user cache folder ($XDG_CACHE_HOME on Linux)."""
    import sys

    from s2cl.io.cache import CACHE_ENV, cache_dir

    monkeypatch.setenv(CACHE_ENV, str(tmp_path / "mine"))
    assert cache_dir("prosail") == tmp_path / "mine" / "prosail" and (tmp_path / "mine" / "prosail").is_dir()
    monkeypatch.delenv(CACHE_ENV)
    if sys.platform.startswith("linux"):
        monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
        assert cache_dir("x") == tmp_path / "xdg" / "s2cl" / "x"
