"""Sphinx configuration of hftrace's documentation (``make docs``).

The pages are the Markdown files of docs/ (read by myst-parser), an API reference that
autosummary generates from the numpydoc docstrings of every name in ``algos.__all__`` and
``datasets_gen.__all__``, and a gallery (sphinx-gallery) of the scripts in
examples/gallery/, which run at build time.
"""
import inspect
import os
import shutil
import sys

DOCS = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(DOCS)
sys.path.insert(0, ROOT)

import algos  # noqa: E402
import datasets_gen  # noqa: E402

project = "hftrace"
author = "hftrace developers"
copyright = "hftrace developers"

extensions = [
    "myst_parser",
    "numpydoc",
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.mathjax",
    "sphinx_gallery.gen_gallery",
]

source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
root_doc = "index"
templates_path = ["_templates"]
exclude_patterns = ["_build", "api/generated/*.md", "auto_examples/*.ipynb",
                    "auto_examples/*.py", "auto_examples/*.zip", "auto_examples/*.md5",
                    "auto_examples/*.json"]

# Markdown: heading anchors for in-page links ([text](#section)), dollar maths.
myst_heading_anchors = 3
myst_enable_extensions = ["dollarmath"]

# The Markdown pages also read well on a repository browser, so they link to source files,
# reports and the README by relative path; those targets are not pages of this site (their
# existence is checked by tests/test_docs.py instead).
suppress_warnings = ["myst.xref_missing"]

autosummary_generate = True
autodoc_default_options = {"members": False}
autodoc_typehints = "none"
numpydoc_show_class_members = False
numpydoc_class_members_toctree = False
numpydoc_validation_checks = set()

html_theme = "pydata_sphinx_theme"
html_title = "hftrace"
html_theme_options = {"navigation_with_keys": False, "show_toc_level": 2}
html_static_path = []

sphinx_gallery_conf = {
    "examples_dirs": [os.path.join(ROOT, "examples", "gallery")],
    "gallery_dirs": ["auto_examples"],
    "filename_pattern": r"/plot_",
    "download_all_examples": False,
    "remove_config_comments": True,
    "abort_on_example_error": True,
    "within_subsection_order": "FileNameSortKey",
    "image_scrapers": ("matplotlib",),
}


def _api_page():
    """Write api/index.rst: one autosummary table per package, listing every name of its
    ``__all__`` through the package (``algos.X``), so that moving a module inside a package
    changes nothing here."""
    sections = []
    # id of a class or function -> the one public name that documents it: the first name
    # equal to its own __name__ (algos.HeightField rather than its alias algos.Field)
    documented = {}
    for package in (algos, datasets_gen):
        for name in package.__all__:
            obj = getattr(package, name)
            if inspect.isclass(obj) or inspect.isfunction(obj):
                if id(obj) not in documented or (name == obj.__name__ and not documented[id(obj)][1]):
                    documented[id(obj)] = (f"{package.__name__}.{name}", name == obj.__name__)
    for package in (algos, datasets_gen):
        names = list(package.__all__)
        kinds = {"Functions and classes": [], "Modules": [], "Constants and tables": []}
        aliases = []
        for name in names:
            obj = getattr(package, name)
            full = f"{package.__name__}.{name}"
            if (inspect.isclass(obj) or inspect.isfunction(obj)) and documented[id(obj)][0] != full:
                aliases.append(f"- ``{full}`` is :py:obj:`{documented[id(obj)][0]}`.")
                continue
            if inspect.ismodule(obj):
                kinds["Modules"].append(name)
            elif inspect.isclass(obj) or callable(obj):
                kinds["Functions and classes"].append(name)
            else:
                kinds["Constants and tables"].append(name)
        title = f"``{package.__name__}``"
        body = [title, "=" * len(title), "", f".. automodule:: {package.__name__}",
                "   :no-members:", "", f".. currentmodule:: {package.__name__}", ""]
        for kind, members in kinds.items():
            if not members:
                continue
            body += [kind, "-" * len(kind), "", ".. autosummary::", "   :toctree: generated",
                     "   :nosignatures:", ""]
            body += [f"   {name}" for name in members]
            body.append("")
        if aliases:
            body += ["Other names", "-----------", "", "The same objects, also public under these names:",
                     ""] + aliases + [""]
        sections.append("\n".join(body))
    header = ("API reference\n=============\n\n"
              "Every public name of ``algos`` and ``datasets_gen`` (their ``__all__``), "
              "documented from its docstring.\n\n.. toctree::\n   :maxdepth: 1\n\n"
              "   algos\n   datasets_gen\n")
    shutil.rmtree(os.path.join(DOCS, "api", "generated"), ignore_errors=True)  # no stale stubs
    os.makedirs(os.path.join(DOCS, "api"), exist_ok=True)
    pages = {"index.rst": header, "algos.rst": sections[0], "datasets_gen.rst": sections[1]}
    for page, text in pages.items():
        path = os.path.join(DOCS, "api", page)
        old = open(path).read() if os.path.exists(path) else None
        if old != text:  # unchanged pages keep their time stamp (no needless rebuild)
            with open(path, "w") as f:
                f.write(text)


_api_page()
# the gallery is rebuilt from its sources every time: no page of a removed example remains
shutil.rmtree(os.path.join(DOCS, "auto_examples"), ignore_errors=True)
