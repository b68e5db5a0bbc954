# armlab: `make run` starts the lab on the simulated arm, `make test` runs the tests.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
DEVSTAMP := $(VENV)/.installed-dev

.PHONY: run test test-fast lint bench bench-peers screenshots clean

$(BIN)/python:
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip

$(STAMP): pyproject.toml | $(BIN)/python
	$(BIN)/python -m pip install --quiet -e .
	touch $@

$(DEVSTAMP): pyproject.toml | $(BIN)/python
	$(BIN)/python -m pip install --quiet -e '.[dev]'
	touch $(STAMP) $@

run: $(STAMP)
	$(BIN)/armlab serve

# one process by default: beside a second worker, the real-time tests of a 2-core machine
# lose their margin. `make test PARALLEL="-n 2 --dist loadfile --no-loadscope-reorder"`
# runs two pytest-xdist workers, each module whole on one of them, the slowest first.
PARALLEL ?=
# the tests keep compiled bytecode (and pytest its rewritten test modules) even where the
# environment says not to write it: each of the suite's child processes (emulators, the
# class's worker, the CLI) would otherwise compile armlab again, and collection take twice
TESTENV := PYTHONDONTWRITEBYTECODE=

test: $(DEVSTAMP)
	$(TESTENV) $(BIN)/python -m pytest -q $(PARALLEL)

# the edit-test loop: no browser, nothing on the wall clock (make test runs everything)
test-fast: $(DEVSTAMP)
	$(TESTENV) $(BIN)/python -m pytest -q $(PARALLEL) -m "not browser and not realtime"

lint: $(DEVSTAMP)
	$(BIN)/ruff check .

bench: $(STAMP)
	$(BIN)/armlab bench

# armlab's figures beside MuJoCo's and Pinocchio's (installs the optional bench extra)
bench-peers: $(STAMP)
	$(BIN)/python -m pip install --quiet -e '.[bench]'
	$(BIN)/armlab bench --peers

# the README's pictures of every lesson, from the real page in Chromium (docs/img)
screenshots: $(DEVSTAMP)
	$(BIN)/python docs/screenshots.py

clean:
	rm -rf $(VENV) .pytest_cache .ruff_cache
