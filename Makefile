# hubbeam-ctrl: the two commands of the README, plus helpers.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
STAMP_TEST := $(VENV)/.installed-test
export MPLBACKEND := Agg

.PHONY: demo test bench notebooks clean

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
	$(BIN)/python -m hubbeam_ctrl.demo --out demo_out

test: $(STAMP_TEST)
	$(BIN)/python -m pytest -q

bench: $(STAMP)
	$(BIN)/python benchmarks/bench_plant.py
	$(BIN)/python benchmarks/bench_mpc.py

notebooks: $(STAMP_TEST)
	$(BIN)/python -m pip install --quiet nbconvert
	mkdir -p docs
	$(BIN)/jupyter nbconvert --to html --execute --output-dir docs notebooks/*.ipynb

clean:
	rm -rf $(VENV) demo_out docs
