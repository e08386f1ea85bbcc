"""Results files that never blend: every row names its run, readers keep runs apart, a row
a kill cut short is found by its line number and measured again, and every workload's
table carries its intervals. Every sweep here is tiny (40 rays, 3 repeats, 64^2 fields)."""
import re
import socket

import numpy as np
import pytest

from bench import analysis, sweep
from bench.cli import main
from bench.report import RowWriter, scan_csv

TINY = {"name": "runs", "rays": 40, "repeats": 3, "seed": 3, "workloads": ["visit"],
        "run_lengths": [2, "random"], "algorithms": ["dda", "midpoint", "runs"],
        "datasets": [{"name": "fbm", "size": 64, "seed": 1}]}


@pytest.fixture(autouse=True)
def quiet_flush(monkeypatch):
    monkeypatch.setenv("HFTRACE_FLUSH_MB", "0")


def measure(out_dir, **changes):
    """A tiny sweep into ``out_dir``; (config, rows, echoed lines)."""
    cfg = sweep.load_config({**TINY, **changes})
    lines = []
    rows = sweep.run_sweep(cfg, str(out_dir), progress=False, echo=lines.append)
    return cfg, rows, lines


def test_every_row_names_its_run(tmp_path):
    cfg, rows, _ = measure(tmp_path)
    assert len(rows) == 6
    assert {r["run_id"] for r in rows} == {rows[0]["run_id"]}
    assert re.fullmatch(r"[0-9a-f]{12}", rows[0]["run_id"])
    assert {r["machine"] for r in rows} == {socket.gethostname()}
    assert {r["config_hash"] for r in rows} == {sweep.config_hash(cfg)}
    assert re.fullmatch(r"\d{4}-\d\d-\d\dT\d\d:\d\d:\d\d\.\d{6}Z", rows[0]["started"])
    assert all(r["commit"] == rows[0]["commit"] for r in rows)
    # another config, another hash; the same config, another run
    assert sweep.config_hash(sweep.load_config({**TINY, "seed": 4})) != sweep.config_hash(cfg)
    assert sweep.new_run(cfg, "c")["run_id"] != sweep.new_run(cfg, "c")["run_id"]


def test_truncated_row_is_reported_and_measured_again_on_resume(tmp_path, capsys):
    """A kill mid-write leaves half a row: ``plot`` says which line and leaves it out,
    ``--resume`` sets it aside and measures its group again (not "config changed")."""
    cfg, rows, _ = measure(tmp_path)
    path = tmp_path / "results.csv"
    text = path.read_text()
    lines = text.splitlines(keepends=True)
    cut = "".join(lines[:-1]) + lines[-1][: len(lines[-1]) // 2]
    path.write_text(cut)
    header, whole, bad = scan_csv(str(path), sweep.REQUIRED)
    assert len(whole) == 5 and bad[0][0] == 7 and "truncated" in bad[0][1]
    assert main(["plot", str(path)]) == 0
    out = capsys.readouterr()
    assert "line 7 of" in out.out + out.err and "left out" in out.out + out.err
    echoed = []
    again = sweep.run_sweep(cfg, str(tmp_path), resume=True, progress=False, echo=echoed.append)
    assert any("line 7 of" in e and "measured again" in e for e in echoed), echoed
    assert len(again) == 6 and scan_csv(str(path), sweep.REQUIRED)[2] == []
    assert {sweep.row_key(r) for r in again} == {sweep.row_key(r) for r in rows}
    assert {r["run_id"] for r in again} == {rows[0]["run_id"]}  # the resumed run stays one
    rejected = (tmp_path / "results.csv.rejected").read_text()
    assert "line 7" in rejected and lines[-1][: len(lines[-1]) // 2].strip() in rejected
    # without --resume the damaged file is refused, naming the line
    path.write_text(cut)
    with pytest.raises(ValueError, match="damaged line.*line 7: truncated.*--resume"):
        sweep.run_sweep(cfg, str(tmp_path), progress=False, echo=None)


def test_malformed_row_in_the_middle_is_found(tmp_path):
    measure(tmp_path)
    path = tmp_path / "results.csv"
    lines = path.read_text().splitlines(keepends=True)
    lines[3] = ",".join(lines[3].split(",")[:10]) + "\r\n"
    path.write_text("".join(lines))
    warnings = []
    df = analysis.load(str(path), echo=warnings.append)
    assert len(df) == 5 and df.attrs["bad_lines"][0][0] == 4
    assert warnings == [f"warning: results: line 4 of {path}: malformed: 10 fields, the header "
                        f"has {len(sweep.COLUMNS)}; left out"]


def test_edited_and_repeated_rows_are_found_and_measured_again(tmp_path, capsys):
    """A hand-edited row (a speedup of text, a negative one, a run length that is no run
    length) and a row present twice (a file appended to itself) are reported by line
    number and left out by ``plot``, not averaged in; ``--resume`` measures them again."""
    cfg, rows, _ = measure(tmp_path)
    path = tmp_path / "results.csv"
    lines = path.read_text().splitlines(keepends=True)
    header = lines[0].rstrip("\r\n").split(",")

    def edit(line, column, value):
        fields = line.rstrip("\r\n").split(",")
        fields[header.index(column)] = value
        return ",".join(fields) + "\r\n"

    lines[2] = edit(lines[2], "speedup", "fast")
    lines[3] = edit(lines[3], "speedup", "-5")
    lines[4] = edit(lines[4], "run_length", "abc")
    lines.append(lines[5])  # line 8 repeats line 6
    path.write_text("".join(lines))
    warnings = []
    df = analysis.load(str(path), echo=warnings.append)
    assert len(df) == 3
    assert [n for n, _ in df.attrs["bad_lines"]] == [3, 4, 5, 8]
    assert "speedup 'fast' is not a number" in warnings[0]
    assert "speedup '-5' is out of range" in warnings[1]
    assert "run_length 'abc' is neither a positive number nor 'random'" in warnings[2]
    assert "line 8" in warnings[3] and "repeats line 6" in warnings[3]
    assert main(["plot", str(path), "--out", str(tmp_path / "p")]) == 0
    out = capsys.readouterr()
    said = out.out + out.err
    assert "line 3 of" in said and "line 8 of" in said and "3 rows" in out.out
    again = sweep.run_sweep(cfg, str(tmp_path), resume=True, progress=False, echo=None)
    assert len(again) == 6 and scan_csv(str(path), sweep.REQUIRED)[2] == []
    assert {sweep.row_key(r) for r in again} == {sweep.row_key(r) for r in rows}
    assert analysis.load(str(path), echo=None).attrs["bad_lines"] == []


def test_spreadsheet_saved_files(tmp_path, capsys):
    """A results file saved by a spreadsheet: its byte-order mark is read past (it hid
    the first column), and one whose numbers all use a decimal comma is refused in one
    line rather than plotted as an empty report."""
    measure(tmp_path)
    path = tmp_path / "results.csv"
    text = path.read_text()
    bom = tmp_path / "bom.csv"
    bom.write_bytes(b"\xef\xbb\xbf" + text.encode())
    assert len(analysis.load(str(bom), echo=None)) == 6
    header, *rows = text.splitlines()
    column = header.split(",").index("speedup")

    def comma(line):
        fields = line.split(",")
        fields[column] = '"' + fields[column].replace(".", ",") + '"'
        return ",".join(fields)

    decimal = tmp_path / "comma.csv"
    decimal.write_text("\n".join([header] + [comma(r) for r in rows]) + "\n")
    assert main(["plot", str(decimal), "--out", str(tmp_path / "p")]) == 2
    err = capsys.readouterr().err
    assert "has no whole row: all 6 lines are damaged" in err and "is not a number" in err


def test_plot_of_two_runs_refuses_then_plots_the_chosen_one(tmp_path, capsys):
    """``cat a.csv b.csv``: plot says it found 2 runs and refuses; ``--run`` picks one,
    whose table is that run's alone."""
    measure(tmp_path / "a")
    measure(tmp_path / "b", seed=5)
    both = tmp_path / "both.csv"
    both.write_text((tmp_path / "a" / "results.csv").read_text() +
                    (tmp_path / "b" / "results.csv").read_text())
    assert main(["plot", str(both)]) == 2
    err = capsys.readouterr().err
    first = sweep.read_rows(str(tmp_path / "a" / "results.csv"))[0]["run_id"]
    second = sweep.read_rows(str(tmp_path / "b" / "results.csv"))[0]["run_id"]
    assert err.count("\n") == 1 and "holds 2 runs" in err and first in err and second in err
    assert "--run" in err
    assert main(["plot", str(both), "--run", second[:6], "--out", str(tmp_path / "p")]) == 0
    out = capsys.readouterr()
    assert f"read run {second}" in out.out and "line 8" in out.out + out.err  # the seam
    assert f"run {second}" in (tmp_path / "p" / "speedup.md").read_text()
    chosen = analysis.load(str(both), run=second[:6], echo=None)
    alone = analysis.load(str(tmp_path / "b" / "results.csv"), echo=None)
    np.testing.assert_array_equal(analysis.pivot(chosen, "visit", "-").values,
                                  analysis.pivot(alone, "visit", "-").values)
    with pytest.raises(ValueError, match="--run: 'zzz' names none of the 2 run"):
        analysis.load(str(both), run="zzz", echo=None)


def test_resume_refuses_rows_of_another_machine_or_two_runs(tmp_path):
    cfg, rows, _ = measure(tmp_path)
    path = tmp_path / "results.csv"
    text = path.read_text()
    path.write_text(text.replace(rows[0]["machine"], "elsewhere"))
    with pytest.raises(ValueError, match="measured on elsewhere"):
        sweep.run_sweep(cfg, str(tmp_path), resume=True, progress=False, echo=None)
    path.write_text(text.replace(rows[-1]["run_id"] + ",", "0" * 12 + ",", 1))
    with pytest.raises(ValueError, match="holds 2 runs"):
        sweep.run_sweep(cfg, str(tmp_path), resume=True, progress=False, echo=None)


def test_every_workload_table_has_intervals(tmp_path):
    """The visit table of speedup.md gives each ratio with its 95 % interval's half-width
    and, unless it is a finding, why not (``bench.analysis.finding``)."""
    measure(tmp_path)
    text = open(analysis.write_reports(str(tmp_path / "results.csv"), echo=None)["speedup"]).read()
    section = text[text.index("## Workload: visit"):].split("\n## ")[0]
    cells = [line for line in section.splitlines() if line.startswith("| 2 ") or
             line.startswith("| random ")]
    assert len(cells) == 2
    for line in cells:
        ratios = [c.strip() for c in line.strip("|").split("|")[1:]]
        assert ratios[0].startswith("1 (baseline)")
        for ratio in ratios[1:]:
            assert re.fullmatch(r"\d+\.\d\d ±\d+\.\d %( \((same|contended|budget spent|"
                                r"too few repeats)\))?", ratio), line


def test_row_writer_sets_damaged_lines_aside_before_appending(tmp_path):
    path = tmp_path / "rows.csv"
    path.write_text("a,b\r\n1,2\r\n3,")
    with RowWriter(str(path), ["a", "b"], append=True) as writer:
        assert writer.rejected[0][0] == 3 and "truncated" in writer.rejected[0][1]
        writer.write({"a": 5, "b": 6})
    assert path.read_bytes() == b"a,b\r\n1,2\r\n5,6\r\n"
    assert "3," in (tmp_path / "rows.csv.rejected").read_text()


def test_files_without_run_identifiers_are_kept_apart_by_commit(tmp_path):
    """Rows written before runs were identified (no run_id) are told apart by commit: the
    issue's case of two commits' rows in one file, 0.653 and 0.327, is never one 0.46."""
    head = "algorithm,workload,surface,dataset,run_length,speedup,speedup_ci_low," \
           "speedup_ci_high,ns_per_ray,agree,commit\n"
    rows = "".join(f"runs,first_hit,triangles,fbm,2,{s},{s * 0.9},{s * 1.1},10,1.0,{c}\n"
                   for s, c in ((0.653, "a" * 40), (0.327, "b" * 40)))
    path = tmp_path / "old.csv"
    path.write_text(head + rows)
    with pytest.raises(ValueError, match=r"holds 2 runs.*commit aaaa.*commit bbbb.*--run"):
        analysis.load(str(path), echo=None)
    df = analysis.load(str(path), run="bbb", echo=None)
    assert analysis.pivot(df, "first_hit", "triangles").loc["2", "runs"] == pytest.approx(0.327)
