"""Builds of the C extension at git revisions, cached, and loaded side by side.

A revision is a commit of a git repository (anything ``git rev-parse`` resolves) or its
working tree (``None``). Its sources (``setup.py``, ``cext/``, ``algos/``) are exported
into a cache directory and built there once with ``setup.py build_ext --inplace``. The
cache key is the commit's tree of those sources (so commits that touch only other files
share one build; a hash of the files for the working tree), the compiler's version line, the
Python ABI, the NumPy version and the build switches (``HFTRACE_*``, ``CFLAGS``), so a build
is never reused across toolchains.

:func:`load` imports a build's ``algos`` package under a distinct top-level name
(``hftrace_rev_<role>_<key>``), so two builds live in one process: each package's
relative ``from . import _kernels`` finds its own shared object, whose init symbol
(``PyInit__kernels``) matches the last component of the module name.
"""
from __future__ import annotations

import hashlib
import importlib.util
import os
import platform
import shutil
import subprocess
import sys
import sysconfig
from dataclasses import dataclass

#: What a revision's build needs from its tree
BUILD_PATHS = ("setup.py", "pyproject.toml", "cext", "algos")
#: Environment switches that change the build (setup.py) and so its cache key
BUILD_SWITCHES = ("HFTRACE_DEBUG", "HFTRACE_SANITIZE", "HFTRACE_FUZZ", "CC", "CFLAGS", "LDSHARED")


class RevisionError(RuntimeError):
    """A revision that does not exist, or does not build: one line, the exit status 2."""


@dataclass(frozen=True)
class Build:
    """One built revision: ``label`` (what the user asked for), ``commit`` (the full sha,
    or ``"worktree"``), ``key`` (the cache key) and ``root`` (the directory holding the
    built ``algos`` package)."""

    label: str
    commit: str
    key: str
    root: str

    @property
    def short(self) -> str:
        """The first 10 hex digits of the commit (or ``worktree``)."""
        return self.commit[:10] if self.commit != "worktree" else "worktree"


def cache_dir() -> str:
    """Where builds go: ``$HFTRACE_BUILD_CACHE``, else ``$XDG_CACHE_HOME/hftrace/builds``
    (``~/.cache/hftrace/builds``)."""
    explicit = os.environ.get("HFTRACE_BUILD_CACHE")
    if explicit:
        return explicit
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return os.path.join(base, "hftrace", "builds")


def _first_line(cmd) -> str:
    try:
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=60)
    except (OSError, subprocess.TimeoutExpired):
        return ""
    text = (proc.stdout or proc.stderr).strip()
    return text.splitlines()[0].strip() if text else ""


def compiler() -> str:
    """The C compiler's version line (``$CC``, else Python's configured CC)."""
    cc = os.environ.get("CC") or (sysconfig.get_config_var("CC") or "cc")
    return _first_line(cc.split()[:1] + ["--version"]) or cc


def valgrind_version() -> str:
    """``valgrind --version`` (e.g. ``valgrind-3.19.0``), or ``""`` without valgrind."""
    return _first_line(["valgrind", "--version"]) if shutil.which("valgrind") else ""


def toolchain() -> dict:
    """What a build and a count depend on besides the sources: compiler, valgrind,
    Python and NumPy versions, the build switches set."""
    import numpy

    switches = {k: os.environ[k] for k in BUILD_SWITCHES if os.environ.get(k)}
    return dict(compiler=compiler(), valgrind=valgrind_version(),
                python=platform.python_version(), numpy=numpy.__version__,
                machine=platform.machine(), switches=switches)


def _toolchain_key() -> str:
    tc = toolchain()
    tc.pop("valgrind")  # counting, not building
    text = repr(sorted(tc.items())) + (sysconfig.get_config_var("EXT_SUFFIX") or "")
    return hashlib.sha256(text.encode()).hexdigest()[:10]


def _git(repo, *args, check=True) -> str:
    proc = subprocess.run(["git", "-C", repo, *args], capture_output=True, text=True)
    if check and proc.returncode != 0:
        last = (proc.stderr.strip().splitlines() or ["git failed"])[-1]
        raise RevisionError(f"git {' '.join(args)}: {last}")
    return proc.stdout.strip()


def repo_root(path: str) -> str:
    """The top of the git repository holding ``path`` (``RevisionError`` if none)."""
    if not os.path.isdir(path):
        raise RevisionError(f"repo: {path} is not a directory")
    proc = subprocess.run(["git", "-C", path, "rev-parse", "--show-toplevel"],
                          capture_output=True, text=True)
    if proc.returncode != 0:
        raise RevisionError(f"repo: {path} is not inside a git repository")
    return proc.stdout.strip()


def resolve(repo: str, revision: str) -> str:
    """The full sha of ``revision`` in ``repo`` (``RevisionError`` naming it if it is not a
    commit there)."""
    proc = subprocess.run(["git", "-C", repo, "rev-parse", "--verify", "--quiet",
                           f"{revision}^{{commit}}"], capture_output=True, text=True)
    if proc.returncode != 0 or not proc.stdout.strip():
        raise RevisionError(f"revision: {revision!r} is not a commit of {repo}")
    return proc.stdout.strip()


def is_clean(repo: str) -> bool:
    """True when ``repo``'s tracked files have no uncommitted change."""
    return _git(repo, "status", "--porcelain", "--untracked-files=no") == ""


def commits_between(repo: str, good: str, bad: str) -> list[str]:
    """The first-parent commits after ``good`` up to ``bad`` included, oldest first."""
    out = _git(repo, "rev-list", "--first-parent", "--reverse", f"{good}..{bad}")
    return out.split() if out else []


def _worktree_files(repo: str) -> list[str]:
    out = _git(repo, "ls-files", "-z", "--cached", "--others", "--exclude-standard", "--",
               *BUILD_PATHS)
    return sorted(p for p in set(out.split("\0")) if p and os.path.isfile(os.path.join(repo, p)))


def _export_commit(repo: str, sha: str, dest: str) -> None:
    paths = [p for p in BUILD_PATHS if _git(repo, "ls-tree", "--name-only", sha, "--", p)]
    archive = subprocess.run(["git", "-C", repo, "archive", "--format=tar", sha, "--", *paths],
                             capture_output=True)
    if archive.returncode != 0:
        raise RevisionError(f"revision {sha[:10]}: git archive failed: "
                            f"{archive.stderr.decode(errors='replace').strip()[-200:]}")
    subprocess.run(["tar", "-x", "-C", dest], input=archive.stdout, check=True)


def build(repo: str, revision: str | None, echo=print) -> Build:
    """Build ``revision`` of ``repo`` (``None``: its working tree) into the cache, or reuse
    the cached build; the :class:`Build`. ``RevisionError`` (one line) when the revision
    does not exist or its extension does not build."""
    repo = repo_root(repo)
    if revision is None:
        files = _worktree_files(repo)
        digest = hashlib.sha256()
        for rel in files:
            if "/_kernels" in rel or rel.endswith((".so", ".pyd", ".pyc")):
                continue
            digest.update(rel.encode() + b"\0")
            with open(os.path.join(repo, rel), "rb") as f:
                digest.update(f.read())
        commit, label, source_key = "worktree", "working tree", "wt-" + digest.hexdigest()[:16]
    else:
        commit, label = resolve(repo, revision), revision
        # the build's own sources name it: commits that change only other files share it
        listing = _git(repo, "ls-tree", commit, "--", *BUILD_PATHS)
        source_key = "src-" + hashlib.sha256(listing.encode()).hexdigest()[:16]
    key = f"{source_key}-{_toolchain_key()}"
    root = os.path.join(cache_dir(), key)
    marker = os.path.join(root, ".built")
    if os.path.isfile(marker):
        return Build(label, commit, key, root)
    shutil.rmtree(root, ignore_errors=True)
    os.makedirs(root)
    try:
        if revision is None:
            for rel in files:
                if rel.endswith((".so", ".pyd", ".pyc")):
                    continue
                os.makedirs(os.path.dirname(os.path.join(root, rel)) or root, exist_ok=True)
                shutil.copy2(os.path.join(repo, rel), os.path.join(root, rel))
        else:
            _export_commit(repo, commit, root)
        if not os.path.isfile(os.path.join(root, "setup.py")):
            raise RevisionError(f"revision {label}: has no setup.py (not an hftrace tree?)")
        echo(f"building {label} ({commit[:10]}) in {root} ...")
        env = {k: v for k, v in os.environ.items() if k != "LD_PRELOAD"}
        proc = subprocess.run([sys.executable, "setup.py", "-q", "build_ext", "--inplace"],
                              cwd=root, capture_output=True, text=True, env=env)
        if proc.returncode != 0:
            errors = [ln for ln in proc.stderr.splitlines() if "error" in ln.lower()]
            why = (errors or proc.stderr.strip().splitlines() or ["no output"])[0].strip()
            raise RevisionError(f"revision {label} ({commit[:10]}): the extension does not build: "
                                f"{why[:300]}")
    except BaseException:
        shutil.rmtree(root, ignore_errors=True)
        raise
    with open(marker, "w") as f:
        f.write(commit + "\n")
    return Build(label, commit, key, root)


def load(b: Build, role: str):
    """Import the ``algos`` package of build ``b`` as ``hftrace_rev_<role>_<key>`` and
    return it. Two roles may load the same build: the second gets a private copy of the
    package directory, so each shared object is opened once under its own name."""
    name = f"hftrace_rev_{role}_{b.key.replace('-', '_')}"
    if name in sys.modules:
        return sys.modules[name]
    package_dir = os.path.join(b.root, "algos")
    taken = {getattr(m, "__file__", None) for n, m in list(sys.modules.items())
             if n.startswith("hftrace_rev_") and n.count(".") == 0}
    init = os.path.join(package_dir, "__init__.py")
    if init in taken:
        copy = os.path.join(b.root, f"algos-{role}")
        if not os.path.isdir(copy):
            shutil.copytree(package_dir, copy)
        package_dir, init = copy, os.path.join(copy, "__init__.py")
    spec = importlib.util.spec_from_file_location(name, init,
                                                  submodule_search_locations=[package_dir])
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    try:
        spec.loader.exec_module(module)
    except Exception as exc:
        del sys.modules[name]
        raise RevisionError(f"revision {b.label} ({b.short}): its algos package does not import: "
                            f"{type(exc).__name__}: {exc}") from exc
    return module
