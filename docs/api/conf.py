"""Sphinx configuration of the symgroupoid API reference (``make docs``)."""

from __future__ import annotations

import pathlib
import sys

ROOT = pathlib.Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

project = "symgroupoid"
author = "the symgroupoid authors"
copyright = "the symgroupoid authors"  # noqa: A001 - Sphinx's setting name
extensions = ["sphinx.ext.autodoc", "sphinx.ext.napoleon"]
root_doc = "index"
exclude_patterns: list[str] = []
html_theme = "alabaster"
autodoc_member_order = "bysource"
autodoc_typehints = "none"
autodoc_default_options = {"members": True, "show-inheritance": True}
napoleon_numpy_docstring = True
napoleon_google_docstring = False
nitpicky = False
suppress_warnings: list[str] = []
napoleon_use_ivar = True  # "Attributes" sections as fields (properties are documented once)


def _escape_bars(text: str) -> str:
    """``|x|`` (an absolute value, a norm) outside inline literals, as text rather than an
    RST substitution reference."""
    parts = text.split("``")
    for i in range(0, len(parts), 2):
        parts[i] = parts[i].replace("|", r"\|")
    return "``".join(parts)


def _process_docstring(app, what, name, obj, options, lines) -> None:
    lines[:] = [_escape_bars(line) for line in lines]


def setup(app) -> None:
    app.connect("autodoc-process-docstring", _process_docstring)
