"""Engines name the key; the application layer adds the scene's file (:func:`s2cl.errors.errors_in`)."""

from __future__ import annotations

import pytest

from s2cl.errors import InputError, ResourceError, errors_in


def test_an_error_without_a_file_gets_the_scene_file() -> None:
    with pytest.raises(InputError) as info, errors_in("scene.toml"):
        raise InputError("must be positive", key="run.copies")
    assert str(info.value) == "scene.toml: run.copies: must be positive"
    assert (info.value.source, info.value.key, info.value.detail) == ("scene.toml", "run.copies", "must be positive")


def test_an_error_naming_its_own_file_keeps_it() -> None:
    with pytest.raises(InputError) as info, errors_in("scene.toml"):
        raise InputError("bad header", source="lib.hdr", key="wavelength")
    assert str(info.value) == "lib.hdr: wavelength: bad header"


def test_a_subclass_keeps_its_class_and_no_source_changes_nothing() -> None:
    err = ResourceError("too big", key="sweep.chunk")
    with pytest.raises(ResourceError) as info, errors_in("scene.toml"):
        raise err
    assert str(info.value) == "scene.toml: sweep.chunk: too big"
    with pytest.raises(InputError) as plain, errors_in(None):
        raise InputError("x", key="k")
    assert str(plain.value) == "k: x"


def test_other_errors_pass_through() -> None:
    with pytest.raises(KeyError), errors_in("scene.toml"):
        raise KeyError("k")
