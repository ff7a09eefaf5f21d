# hubbeam-ctrl: the two commands of the README, plus helpers.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
STAMP_TEST := $(VENV)/.installed-test
export MPLBACKEND := Agg

.PHONY: demo test test-fast lint bench notebooks clean

$(BIN)/python:
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip

$(STAMP): $(BIN)/python pyproject.toml
	$(BIN)/python -m pip install --quiet -e .
	touch $@

$(STAMP_TEST): $(BIN)/python pyproject.toml
	$(BIN)/python -m pip install --quiet -e ".[test]"
	touch $@ $(STAMP)

demo: $(STAMP)
	$(BIN)/python -m hubbeam_ctrl.cli.demo --out demo_out

test: lint
	$(BIN)/python -m pytest -q

# everyday tier: everything but the tests marked slow (under 2 minutes on 2 cores)
test-fast: lint
	$(BIN)/python -m pytest -q -m "not slow"

# ruff and the import contracts of the layers (pyproject.toml [tool.importlinter])
lint: $(STAMP_TEST)
	$(BIN)/ruff check .
	$(BIN)/lint-imports --no-cache

bench: $(STAMP)
	$(BIN)/python benchmarks/bench_plant.py
	$(BIN)/python benchmarks/bench_mpc.py
	$(BIN)/python benchmarks/bench_compiled.py

notebooks: $(STAMP_TEST)
	$(BIN)/python -m pip install --quiet nbconvert
	mkdir -p docs
	$(BIN)/jupyter nbconvert --to html --execute --output-dir docs notebooks/*.ipynb

clean:
	rm -rf $(VENV) demo_out docs
