"""The API reference of the documentation, generated from ``algos.__all__`` and
``datasets_gen.__all__`` (docs/conf.py writes it before Sphinx reads the sources)."""
import inspect
import os
import shutil

import algos
import datasets_gen


def pages():
    """The API reference's pages, {file name: reStructuredText}: an index and one page per
    package with an autosummary table of every name of its ``__all__``, written through
    the package (``algos.X``), so that moving a module inside a package changes nothing."""
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
    return {"index.rst": header, "algos.rst": sections[0], "datasets_gen.rst": sections[1]}


def write(docs):
    """Write the pages into ``docs/api/`` (git-ignored); autosummary's stubs are made anew."""
    shutil.rmtree(os.path.join(docs, "api", "generated"), ignore_errors=True)  # no stale stubs
    os.makedirs(os.path.join(docs, "api"), exist_ok=True)
    for page, text in pages().items():
        path = os.path.join(docs, "api", page)
        old = open(path).read() if os.path.exists(path) else None
        if old != text:  # unchanged pages keep their time stamp (no needless rebuild)
            with open(path, "w") as f:
                f.write(text)
