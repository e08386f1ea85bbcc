"""Committed baselines of the exact gates, their provenance, and the rule for a mismatch.

A baseline records what its numbers depend on: the commit it was counted at (written only
from a clean tree, so the commit *is* the code), the toolchain (compiler, valgrind,
Python, NumPy: :func:`bench.regress.revisions.toolchain`) and the SHA-256 prefixes of the
field and the rays. When any of them differs from this machine's, the snapshot is not
compared at all: the gate says what differs, builds the baseline's commit here
(:mod:`bench.regress.revisions`), counts it on this machine's inputs, and compares with
that. So a fresh build of unchanged code meets its own counts and cannot fail.
"""
from __future__ import annotations

import json
import os

from . import revisions

#: This checkout's top directory (the gates count the ``algos`` found there)
ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


class BaselineError(RuntimeError):
    """A baseline that cannot be read, written or rebuilt: exit status 2, one line."""


def provenance(root: str = ROOT) -> str:
    """The commit of ``root``'s clean tree; ``BaselineError`` when it is not a git
    checkout or has uncommitted changes (a baseline of a dirty tree names no code)."""
    try:
        repo = revisions.repo_root(root)
        commit = revisions.resolve(repo, "HEAD")
        clean = revisions.is_clean(repo)
    except revisions.RevisionError as exc:
        raise BaselineError(f"baseline: cannot name the code counted ({exc})") from exc
    if not clean:
        raise BaselineError(f"baseline: {repo} has uncommitted changes; commit or stash them "
                            "first, so the baseline names the code it counted")
    return commit


def write(path: str, metric: str, cases: dict, inputs, toolchain: dict, commit: str,
          tolerance: float, note: str) -> None:
    """Write a baseline of ``metric`` to ``path``."""
    from ..timing import write_json

    write_json(path, dict(metric=metric, cases=cases, tolerance=tolerance, commit=commit,
                          toolchain=toolchain, input=inputs.spec, hashes=inputs.hashes,
                          note=note))


def read(path: str, metric: str) -> dict:
    """The baseline of ``metric`` at ``path`` (``BaselineError`` if absent or another
    kind)."""
    if not os.path.isfile(path):
        raise BaselineError(f"baseline: {path} does not exist (create it with --update)")
    with open(path) as f:
        base = json.load(f)
    if base.get("metric") != metric or not isinstance(base.get("cases"), dict):
        raise BaselineError(f"baseline: {path} is not a {metric} baseline")
    return base


def mismatches(base: dict, inputs, toolchain: dict, keys) -> list[str]:
    """What differs between the baseline and this machine: each toolchain entry in
    ``keys`` and the input hashes; one text per difference (empty: comparable)."""
    out = []
    recorded = base.get("toolchain") or {}
    for k in keys:
        if recorded.get(k) != toolchain.get(k):
            out.append(f"{k} {recorded.get(k) or 'unrecorded'!r} here {toolchain.get(k) or 'none'!r}")
    hashes = inputs.hashes
    for k in ("field", "rays"):
        if (base.get("hashes") or {}).get(k) != hashes[k]:
            out.append(f"{k} hash {(base.get('hashes') or {}).get(k) or 'unrecorded'} here {hashes[k]}")
    return out


def rebuilt_base(base: dict, path: str, echo=print) -> revisions.Build:
    """The baseline's commit built on this machine (``BaselineError`` when the baseline
    names none or this checkout's repository does not hold it)."""
    commit = base.get("commit")
    if not commit:
        raise BaselineError(f"baseline: {path} records no commit to rebuild; regenerate it "
                            "with --update from a clean tree")
    try:
        repo = revisions.repo_root(ROOT)
        return revisions.build(repo, commit, echo=echo)
    except revisions.RevisionError as exc:
        raise BaselineError(f"baseline: cannot rebuild its commit {commit[:10]} here: {exc}") from exc
