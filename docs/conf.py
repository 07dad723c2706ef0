"""Sphinx configuration of the glider-cosim documentation (MyST Markdown, myst-nb)."""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent / "_ext"))

project = "glider-cosim"
author = "glider-cosim contributors"
copyright = "2026, glider-cosim contributors"  # noqa: A001

extensions = [
    "myst_nb",
    "sphinx.ext.autodoc",
    "sphinx.ext.napoleon",
    "glider_docs",
]
# how-to/add-a-component/: the example component's files (its readme is not a page)
exclude_patterns = ["_build", "Thumbs.db", ".DS_Store", "**.ipynb_checkpoints", "jupyter_execute",
                    "how-to/add-a-component/**"]  # fmt: skip
source_suffix = {".md": "myst-nb"}
myst_enable_extensions = ["colon_fence", "deflist"]
myst_heading_anchors = 3
suppress_warnings = ["myst.header"]
# "--fmi" stays two hyphens (no en dash) and quotes stay straight, as typed in a shell
smartquotes = False

# the tutorials run at every build: their output cannot drift from the code
nb_execution_mode = "force"
nb_execution_raise_on_error = True
nb_execution_timeout = 180
nb_merge_streams = True

autodoc_member_order = "bysource"
autodoc_typehints = "description"
napoleon_numpy_docstring = True
napoleon_google_docstring = False

html_theme = "alabaster"
html_title = "glider-cosim"
html_static_path = ["_static"]
html_css_files = ["glider.css"]
html_theme_options = {
    "description": "Underwater-glider glide stabilisation as FMI co-simulation FMUs",
    "page_width": "1100px",
    "sidebar_width": "240px",
}
