"""Sphinx configuration of the copdea-fem documentation.

Build: ``pip install -e ".[docs]" && python -m sphinx -W -b html docs docs/_build/html``.
Pages are MyST Markdown (``docs/<topic>.md``); the tutorials in ``docs/tutorials/`` are
Python scripts run by sphinx-gallery at every build (a failing tutorial fails the build);
the study-key table is generated from the schema (:mod:`copdea_fem.study`).
"""

import os
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(ROOT))
# off-screen rendering without a display (as copdea_fem.output does for its PNGs)
if sys.platform.startswith("linux") and not (os.environ.get("DISPLAY")
                                             or os.environ.get("WAYLAND_DISPLAY")):
    os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import pyvista  # noqa: E402

import copdea_fem  # noqa: E402
from copdea_fem.study import reference_table  # noqa: E402

pyvista.OFF_SCREEN = True
pyvista.BUILDING_GALLERY = True

# -- the study keys, from the schema: new keys appear by themselves --------------------------
generated = HERE / "_generated"
generated.mkdir(exist_ok=True)
table = reference_table() + "\n"
target = generated / "study-keys.md"
if not target.exists() or target.read_text() != table:
    target.write_text(table)

project = "copdea-fem"
author = "copdea-fem contributors"
release = version = copdea_fem.__version__

extensions = [
    "myst_parser",
    "sphinx.ext.autodoc",
    "sphinx.ext.napoleon",
    "sphinx.ext.mathjax",
    "sphinx_gallery.gen_gallery",
]
source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
exclude_patterns = ["_build", "_generated", "tutorials/README.rst", "Thumbs.db", ".DS_Store"]
myst_enable_extensions = ["dollarmath", "amsmath", "colon_fence"]
myst_heading_anchors = 3

autodoc_member_order = "bysource"
autodoc_typehints = "description"
autodoc_default_options = {"members": True, "show-inheritance": False}
napoleon_numpy_docstring = True
napoleon_google_docstring = False
# the API's docstrings name types by their short names (Study, StudyError, ...)
nitpicky = False

sphinx_gallery_conf = {
    "examples_dirs": "tutorials",
    "gallery_dirs": "auto_tutorials",
    "filename_pattern": r"/plot_",
    "within_subsection_order": "FileNameSortKey",
    "image_scrapers": ("matplotlib", "pyvista"),
    "abort_on_example_error": True,
    "download_all_examples": False,
    "remove_config_comments": True,
    "run_stale_examples": False,
    "reset_modules": ("matplotlib",),
}

html_theme = "alabaster"
html_title = "copdea-fem"
html_static_path = []
