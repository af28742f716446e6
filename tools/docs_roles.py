"""A griffe extension for the documentation site (mkdocs.yml): the docstrings' reST roles
(:class:`Runtime`, :func:`get_runtime`) shown as code, as Markdown cannot read them."""

from __future__ import annotations

import re
from typing import Any

import griffe

ROLE = re.compile(r":(?:py:)?[a-z]+:`~?([^`]+)`")


class ReSTRoles(griffe.Extension):
    """Rewrites ``:role:`target``` to ```target``` in every docstring as it is loaded."""

    def on_instance(self, *, obj: griffe.Object, **kwargs: Any) -> None:
        if obj.docstring is not None:
            obj.docstring.value = ROLE.sub(r"`\1`", obj.docstring.value)
