"""The fuzz harness (tests/fuzz/harness.py) without a fuzzer: the committed corpus, every finding
the fuzzer ever wrote (tests/data/fuzz_corpus/crashes/) and a fixed random batch are
replayed through the same invariant checks as in `make fuzz`."""
import os

import numpy as np
import pytest

from tests.fuzz import harness as fuzz

FILES = sorted(
    os.path.join(root, name)
    for root, _, names in os.walk(fuzz.CORPUS) for name in names)


def test_corpus_is_committed():
    assert any(os.path.basename(p).startswith("seed-") for p in FILES)
    assert len(FILES) >= 20


@pytest.mark.parametrize("path", FILES, ids=[os.path.relpath(p, fuzz.CORPUS) for p in FILES])
def test_corpus_input_holds_every_invariant(path):
    with open(path, "rb") as f:
        fuzz.check(f.read())


def test_random_inputs_hold_every_invariant():
    rng = np.random.Generator(np.random.PCG64(2026))
    for _ in range(1500):
        fuzz.check(rng.bytes(int(rng.integers(0, 600))))


def test_decoder_reaches_both_entry_points_and_errors():
    """The decoder is no dead end: random bytes reach both C entries, with valid calls
    and calls that must be refused."""
    rng = np.random.Generator(np.random.PCG64(7))
    seen = set()
    for _ in range(600):
        case = fuzz.decode(rng.bytes(300))
        try:
            fuzz._call(case)
            seen.add((case["op"], "ok"))
        except (ValueError, TypeError):
            seen.add((case["op"], "error"))
    assert seen == {(op, outcome) for op in ("traverse", "intersect", "horizon", "viewshed")
                    for outcome in ("ok", "error")}


def test_a_violation_is_reported(monkeypatch):
    """The checks can fail: an exact kernel that disagrees with another is caught."""
    import algos

    data = open(os.path.join(fuzz.CORPUS, "seed-traverse-small"), "rb").read()
    case = fuzz.decode(data)
    case.update(kernel="midpoint", output="cells", shape=(20, 20),
                origins=[[0.5, 0.5]], directions=[[1.0, 0.3]])
    monkeypatch.setattr(fuzz, "decode", lambda _: dict(case))
    real = algos.traverse

    def broken(name, *a, **k):
        out = real(name, *a, **k)
        if name == "runs":
            out.cells[-1] = out.cells[-1] + 1
        return out

    monkeypatch.setattr(algos, "traverse", broken)
    with pytest.raises(AssertionError):
        fuzz.check(b"")
