"""Options a user gets slightly wrong on `hftrace compare` and `hftrace reproduce`: each
is refused in one line naming the option, before anything is built or measured."""
import os

import pytest

from bench.cli import main

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def _run(capsys, *argv):
    status = main(list(argv))
    out, err = capsys.readouterr()
    return status, out, err


@pytest.fixture
def no_builds(monkeypatch):
    """compare must refuse before any revision is built."""
    from bench.regress import revisions

    monkeypatch.setattr(revisions, "build", lambda *a, **k: pytest.fail("built a revision"))


@pytest.mark.parametrize("kernels", [",", " , ,"])
def test_compare_kernels_naming_no_kernel_is_refused(no_builds, capsys, kernels):
    """An empty list (a script's unset variable) measured the default kernels instead."""
    status, out, err = _run(capsys, "compare", "HEAD", "--repo", ROOT, "--kernels", kernels,
                            "--metric", "counters")
    assert status == 2
    assert err.strip().splitlines() == [
        f"hftrace: error: --kernels: {kernels!r} names no kernel (give comma-separated "
        "first-hit kernels, or leave --kernels out for the default set)"]


@pytest.mark.skipif(not os.path.isdir("/proc/self"), reason="needs Linux's /proc")
def test_compare_json_in_a_folder_that_takes_no_files_is_refused_first(no_builds, capsys):
    """/proc passes an access() check as root, and the verdict was lost after the measure
    when the file could not be created; a trial file is now made before any build."""
    status, out, err = _run(capsys, "compare", "HEAD", "--repo", ROOT, "--json",
                            "/proc/hftrace-verdicts.json", "--metric", "counters")
    assert status == 2
    line = err.strip().splitlines()[-1]
    assert line.startswith("hftrace: error: --json: cannot create a file in /proc")


def test_resume_on_a_binary_results_file_names_the_file(tmp_path):
    """A results.csv that is not UTF-8 text (binary garbage) raised a bare
    UnicodeDecodeError without the path; it is now the 'other version' refusal."""
    from bench.report import RowWriter

    path = tmp_path / "results.csv"
    path.write_bytes(b"\x00\x01garbage\xff\n")
    with pytest.raises(ValueError, match=rf"{path}: its columns .* differ from this version's"):
        RowWriter(str(path), ["algorithm", "speedup"], append=True)


def test_reproduce_empty_out_is_refused(capsys):
    status, out, err = _run(capsys, "reproduce", "--out", "", "--kernels", "dda,runs",
                            "--no-counts", "--no-progress")
    assert status == 2
    assert err.strip().splitlines()[-1] == "hftrace: error: --out: an empty path; give a directory"


def test_reproduce_first_line_follows_the_preset_kernels_and_precision():
    """The first line promised "about 3 min" whatever --kernels asked; it now says at most
    how long the groups asked take, each spending the budget the run uses (nothing is
    measured here)."""
    from bench.studies import reproduce as R

    head = R.preset()
    line = R.start_line(head, "headline", True, "results/reproduce")
    # 24 groups of 6 s and 0.6 s of set-up, the counts of the kernels shown but Embree
    assert line.startswith(f"hftrace reproduce (headline preset): 24 groups on 4 datasets, "
                           f"{len(head.algorithms)} kernels; at most about 3 min on a quiet "
                           "2-core machine (each group until every ratio is within ±2 % or "
                           "its 6 s budget is spent;"), line
    assert line.endswith("(phases: measure, counts, reports) -> results/reproduce"), line
    two = R.preset(name="standard", kernels=["dda", "runs"], precision=0.05)
    line = R.start_line(two, "standard", False, "out")
    # 144 groups of 3 s and 0.6 s of set-up, then the parallel rays part: 773 s
    assert R.estimate_seconds(two, "standard", counts=False) == pytest.approx(144 * 3.6 + 240 + 15)
    assert line.startswith("hftrace reproduce (standard preset): 144 groups on 4 datasets, "
                           "2 kernels; at most about 13 min on a quiet 2-core machine (each "
                           "group until every ratio is within ±5 % or its 3 s budget is "
                           "spent;"), line
    assert "(phases: measure, parallel rays, reports) -> out" in line


def test_render_diff_names_its_own_option(tmp_path, capsys):
    """An unknown kernel on the --diff side was reported under --algorithm."""
    status, out, err = _run(capsys, "render", "fbm", "--size", "16", "--width", "4",
                            "--height", "2", "--diff", "runs", "nope",
                            "--out", str(tmp_path / "x"))
    assert status == 2
    assert err.strip().splitlines()[-1].startswith("hftrace: error: --diff: unknown renderer 'nope'")


def test_render_negative_fog_is_refused(tmp_path, capsys):
    status, out, err = _run(capsys, "render", "fbm", "--size", "16", "--width", "4",
                            "--height", "2", "--fog", "-1", "--out", str(tmp_path / "x"))
    assert status == 2
    assert "fog: expected a density >= 0" in err.strip().splitlines()[-1]
    assert not list(tmp_path.iterdir())


@pytest.mark.parametrize("r", ["nan", "inf", "1e400", "abc", "0", "-1", "0.5"])
def test_profile_run_length_names_its_option(capsys, monkeypatch, r):
    """`hftrace profile runs --r nan` (or inf, abc) printed int()'s "invalid literal for
    int() with base 10: 'nan'", naming no option; it is refused as --r, before any count."""
    from bench import profile

    monkeypatch.setattr(profile, "profile", lambda *a, **k: pytest.fail("counted"))
    status, out, err = _run(capsys, "profile", "runs", "--r", r)
    assert status == 2
    assert err.strip() == f"hftrace: error: --r: expected a number >= 1 or 'random', got '{r}'"


def test_profile_run_length_accepts_numbers_and_random():
    from bench.cli.profile import _run_length

    assert _run_length("25") == 25 and isinstance(_run_length("25"), int)
    assert _run_length("2.5") == 2.5 and _run_length("1e3") == 1000.0
    assert _run_length("random") == "random"


@pytest.mark.skipif("libasan" in os.environ.get("LD_PRELOAD", ""),
                    reason="AddressSanitizer aborts on a failed allocation instead of raising")
def test_a_sweep_too_big_for_memory_is_one_line(tmp_path, capsys):
    """`rays = 10000000000` in a sweep config ended in numpy's _ArrayMemoryError traceback
    (74.5 GiB for one array): user errors are one line, never a traceback."""
    config = tmp_path / "big.toml"
    config.write_text('rays = 10000000000\nworkloads = ["visit"]\nrun_lengths = [1]\n'
                      'algorithms = ["runs"]\n[[datasets]]\nname = "flat"\nsize = 8\n')
    status, out, err = _run(capsys, "sweep", str(config), "--out", str(tmp_path / "out"),
                            "--no-progress")
    assert status == 2
    last = err.strip().splitlines()[-1]
    assert last.startswith("hftrace: error: out of memory") and "Traceback" not in err
