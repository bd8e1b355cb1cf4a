"""Sphinx configuration of geoddp's documentation (MyST Markdown, autodoc, sphinx-gallery).

Build (warnings are errors; the gallery runs every script in examples/):

    python -m sphinx -W --keep-going -b html docs docs/_build/html
"""
from __future__ import annotations

import os
import re
from pathlib import Path

import geoddp

ROOT = Path(__file__).resolve().parent.parent

project = "geoddp"
author = "the geoddp developers"
copyright = "the geoddp developers"
release = version = geoddp.__version__

extensions = [
    "myst_parser",
    "sphinx.ext.autodoc",
    "sphinx.ext.napoleon",
    "sphinx.ext.mathjax",
    "sphinx_gallery.gen_gallery",
]

source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
exclude_patterns = ["_build", "figures"]
root_doc = "index"

# MyST: $...$ math, ::: fences, and headings as link targets for cross-page links.
myst_enable_extensions = ["dollarmath", "colon_fence", "deflist"]
myst_heading_anchors = 3

# autodoc: Google-style docstrings, members in source order, type hints in the description.
napoleon_google_docstring = True
napoleon_numpy_docstring = False
autodoc_member_order = "bysource"
autodoc_typehints = "description"
autodoc_default_options = {"members": True, "show-inheritance": False}

html_theme = "furo"
html_title = f"geoddp {release}"
html_static_path: list[str] = []

# The gallery: every script in examples/ runs during the build (a failing example fails the
# build), and the matplotlib figures it draws are shown under its code. Scenes (*.toml) and the
# links to the package's scene folders in examples/ are not scripts and are left alone.
sphinx_gallery_conf = {
    "examples_dirs": str(ROOT / "examples"),
    "gallery_dirs": "auto_examples",
    "filename_pattern": r"\.py$",
    "abort_on_example_error": True,
    "within_subsection_order": "FileNameSortKey",
    "download_all_examples": False,
    "remove_config_comments": True,
    "image_scrapers": ("matplotlib",),
    "matplotlib_animations": False,
    "show_memory": False,
}

# The examples draw with matplotlib's file backend (no display on a build machine).
os.environ.setdefault("MPLBACKEND", "Agg")


# geoddp's docstrings write norms and absolute values as plain text (|J_i - J_(i-1)| <= tol,
# ||dJ/dU||); reStructuredText would read |...| as a substitution reference. They use no
# substitutions, so every bar outside inline literals is escaped before the docstring is parsed.
_LITERAL = re.compile(r"(``.+?``|`[^`]+`)")


def _escape_bars(line: str) -> str:
    parts = _LITERAL.split(line)
    return "".join(p if i % 2 else p.replace("|", "\\|") for i, p in enumerate(parts))


def _plain_text_bars(app, what, name, obj, options, lines: list[str]) -> None:
    lines[:] = [_escape_bars(line) for line in lines]


def setup(app):
    app.connect("autodoc-process-docstring", _plain_text_bars)
