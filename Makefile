# hubbeam-ctrl: the two commands of the README, plus helpers.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
STAMP_TEST := $(VENV)/.installed-test
STAMP_BENCH := $(VENV)/.installed-bench
STAMP_DOCS := $(VENV)/.installed-docs
export MPLBACKEND := Agg

.PHONY: demo test test-fast lint coverage bench bench-notebooks notebooks docs clean bytecode

$(BIN)/python:
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip

$(STAMP): $(BIN)/python pyproject.toml
	$(BIN)/python -m pip install --quiet -e .
	touch $@

$(STAMP_TEST): $(BIN)/python pyproject.toml
	$(BIN)/python -m pip install --quiet -e ".[test]"
	touch $@ $(STAMP)

$(STAMP_BENCH): $(BIN)/python pyproject.toml
	$(BIN)/python -m pip install --quiet -e ".[bench]"
	touch $@ $(STAMP)

$(STAMP_DOCS): $(BIN)/python pyproject.toml
	$(BIN)/python -m pip install --quiet -e ".[docs]"
	touch $@ $(STAMP)

# the package's bytecode, written even where PYTHONDONTWRITEBYTECODE is set (this project's machines set it): every
# process then reads it instead of compiling 150 modules (0.35 s of each hubbeam command and test process)
bytecode: $(BIN)/python
	$(BIN)/python -m compileall -q hubbeam_ctrl controllers > /dev/null

demo: $(STAMP) bytecode
	$(BIN)/python -m hubbeam_ctrl.cli.demo --out demo_out

# the suite runs on 2 processes (pytest-xdist; PYTEST_WORKERS=1 for one): under 10 minutes on 2 cores
PYTEST_WORKERS ?= 2
PYTEST_PAR := -n $(PYTEST_WORKERS) --dist worksteal

test: lint bytecode
	$(BIN)/python -m pytest -q $(PYTEST_PAR)

# everyday tier: everything but the tests marked slow (under 2 minutes on 2 cores)
test-fast: lint bytecode
	$(BIN)/python -m pytest -q $(PYTEST_PAR) -m "not slow"

# the whole suite with line coverage of hubbeam_ctrl and controllers (report in build/coverage.json);
# functions that no test runs are candidates for removal (CLI code run in subprocesses is not counted)
coverage: $(STAMP_TEST)
	$(BIN)/python -m pytest -q $(PYTEST_PAR) --cov=hubbeam_ctrl --cov=controllers \
		--cov-report=term:skip-covered --cov-report=json:build/coverage.json

# ruff and the import contracts of the layers (pyproject.toml [tool.importlinter])
lint: $(STAMP_TEST)
	$(BIN)/ruff check .
	$(BIN)/lint-imports --no-cache

bench: $(STAMP_BENCH)
	$(BIN)/python benchmarks/bench_plant.py
	$(BIN)/python benchmarks/bench_mpc.py
	$(BIN)/python benchmarks/bench_sweep.py
	$(BIN)/python benchmarks/bench_compiled.py

# the notebooks' time budget (90 s each on an idle 2-core machine): kernel vs plain script
bench-notebooks: $(STAMP_TEST)
	$(BIN)/python benchmarks/bench_notebooks.py --out build/bench_notebooks.json

# the notebooks' only sources are notebooks/NN_*.py (jupytext percent format): convert each to
# build/notebooks/NN_*.ipynb, execute it there and write build/notebooks/NN_*.html with the outputs
NOTEBOOK_SOURCES := $(sort $(wildcard notebooks/[0-9]*.py))
NOTEBOOK_OUT := build/notebooks

notebooks: $(STAMP_TEST)
	$(BIN)/python -m pip install --quiet "nbconvert>=7"
	mkdir -p $(NOTEBOOK_OUT)
	set -e; for src in $(NOTEBOOK_SOURCES); do \
		nb=$(NOTEBOOK_OUT)/$$(basename $$src .py).ipynb; \
		$(BIN)/jupytext --quiet --to ipynb --output $$nb $$src; \
		$(BIN)/jupyter nbconvert --to html --execute --output-dir $(NOTEBOOK_OUT) $$nb; \
	done

# the documentation site in build/docs/html (open build/docs/html/index.html): Sphinx with numpydoc,
# MyST and myst-nb, the API reference from __all__, warnings as errors. The notebooks are executed
# and rendered with their outputs (DOCS_EXECUTE=off renders them without running them, as the
# suite's quick build does: tests/test_docs_site.py)
DOCS_EXECUTE ?= force
DOCS_JOBS ?= 2

docs: $(STAMP_DOCS)
	HUBBEAM_DOCS_EXECUTE=$(DOCS_EXECUTE) $(BIN)/python -m sphinx -b html -W --keep-going -q -j $(DOCS_JOBS) \
		-c docs . build/docs/html

clean:
	rm -rf $(VENV) demo_out build
