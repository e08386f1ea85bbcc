"""The Python blocks of the documents that promise a runnable example run as written, in
a fresh namespace and an empty working folder: every name they use is defined in the
block (a snippet that leaves ``field`` or ``position`` undefined fails here).

Left out, each for its reason: docs/CONVENTIONS.md (the API's signatures, shared word for
word with outside scripts), docs/gis.md (reads the user's own ``dem.tif``),
docs/layout.md (one line of an API listing), docs/terrain.md (the whole of Jacksboro
2048: its calls are tested in tests/terrain); docs/plugins.md's blocks run in
tests/project/test_docs.py."""
import os
import re

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
RUNNABLE = ("docs/plane.md", "docs/pitched.md", "docs/ring.md", "docs/getting-started.md")


def _blocks(path):
    with open(os.path.join(ROOT, path), encoding="utf-8") as f:
        return re.findall(r"```python\n(.*?)```", f.read(), re.S)


@pytest.mark.parametrize("path", RUNNABLE)
def test_the_documents_python_blocks_run_as_written(path, tmp_path, monkeypatch):
    blocks = _blocks(path)
    assert blocks, f"{path}: no python block"
    monkeypatch.chdir(tmp_path)
    for k, block in enumerate(blocks):
        namespace = {"__name__": "__snippet__"}
        exec(compile(block, f"{path}, python block {k}", "exec"), namespace)
        if "hits" in namespace:  # an intersect example: it found something
            assert namespace["hits"].t.size and (namespace["hits"].t < float("inf")).any()
