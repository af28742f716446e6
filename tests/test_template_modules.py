"""Mako's modules of the kernel templates, kept in the user cache folder: named by the template's text, used by the
next lookup, and left in memory when the cache folder cannot be made."""

from __future__ import annotations

from pathlib import Path

import pytest

from s2cl.cl import templates
from s2cl.errors import InputError

SENSE_VARIABLES = {"args": [], "signature": lambda a, T: "", "n_bands": 1, "band_ids": [0], "stages": [],
                   "segments": [("band", [])], "site": None, "across": None, "deviates": False}


def _render(**extra) -> str:
    from s2cl.cl.vectypes import VecTypes

    return templates.render("sense.cl.mako", T=VecTypes(), **SENSE_VARIABLES, **extra)


@pytest.fixture
def fresh_lookup(tmp_path, monkeypatch):
    """A lookup made anew with the cache folder in ``tmp_path`` (and made anew again afterwards)."""
    monkeypatch.setenv("S2CL_CACHE", str(tmp_path))
    templates._lookup.cache_clear()
    yield tmp_path / "mako"
    templates._lookup.cache_clear()


def test_module_names_follow_the_template_text(tmp_path) -> None:
    template = tmp_path / "a.cl.mako"
    template.write_text("one ${x}")
    first = templates.module_path(tmp_path / "m", str(template), "/common/a.cl.mako")
    assert first == templates.module_path(tmp_path / "m", str(template), "/common/a.cl.mako")
    assert Path(first).parent == tmp_path / "m" and Path(first).name.startswith("common_a.cl.mako-")
    template.write_text("two ${x}")  # an edit, whatever the file times say: another module
    assert templates.module_path(tmp_path / "m", str(template), "/common/a.cl.mako") != first


def test_modules_are_written_and_the_next_lookup_renders_the_same(fresh_lookup) -> None:
    in_memory = _render()
    modules = sorted(p.name for p in fresh_lookup.glob("*.py"))
    assert any(name.startswith("sense.cl.mako-") for name in modules)
    templates._lookup.cache_clear()  # as a new process: the modules are read back
    assert _render() == in_memory
    assert sorted(p.name for p in fresh_lookup.glob("*.py")) == modules


def test_without_a_cache_folder_the_modules_stay_in_memory(fresh_lookup, monkeypatch) -> None:
    def refuse(*parts: str):
        raise InputError("cannot create the cache directory (Permission denied)", key="S2CL_CACHE")

    monkeypatch.setattr(templates, "cache_dir", refuse)
    assert "sense_bands" in _render()
    assert not fresh_lookup.exists()


def test_a_cache_folder_that_cannot_be_written_leaves_the_modules_in_memory(fresh_lookup, monkeypatch) -> None:
    """The folder exists (a read-only or shared home) but Mako cannot write a module into it: the templates render
    the same, compiled in memory (before: every render failed)."""
    import errno
    import tempfile

    expected = _render()
    templates._lookup.cache_clear()
    for module in fresh_lookup.glob("*.py"):
        module.unlink()  # nothing to read back: every module must be written again

    def refuse(*args, **kwargs):
        raise PermissionError(errno.EACCES, "Permission denied", kwargs.get("dir"))

    monkeypatch.setattr(tempfile, "mkstemp", refuse)  # what an existing, non-writable folder does to Mako's writes
    assert _render() == expected
    assert not list(fresh_lookup.glob("*.py"))
