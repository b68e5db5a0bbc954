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

# the tests keep compiled bytecode (and pytest its rewritten test modules) even where the
# environment says not to write it: each of the suite's child processes (emulators, the
# class's worker, the CLI) would otherwise compile armlab again, and collection take twice
TESTENV := PYTHONDONTWRITEBYTECODE=
PYTEST := $(TESTENV) $(BIN)/python -m pytest -q
# the tests off the wall clock and out of the browser run side by side, one pytest-xdist
# worker per core (at most four), each module whole on one worker, so that its lab or
# class starts once; FAST_PARALLEL= runs them in one process
OFF_CLOCK_TESTS := not browser and not realtime
OFF_CLOCK := -m "$(OFF_CLOCK_TESTS)"
FAST_PARALLEL ?= -n auto --maxprocesses 4 --dist loadfile --no-loadscope-reorder
# the browser tests run in one process: a page drawn in software takes most of a
# 2-core machine, and what ran beside it would take margin from both
BROWSER := -m "browser"
# then the real-time tests, two side by side (each module whole on one worker): they
# mostly wait on the clock (an emulator's physics, a served lab's loop), so two take
# half the time on two cores and leave each emulator a core's share; REALTIME_PARALLEL=
# runs them in one process
REALTIME := -m "realtime and not browser"
REALTIME_PARALLEL ?= -n 2 --dist loadfile --no-loadscope-reorder

# everything: the tests off the clock, the browser tests, then the real-time tests; any
# part failing fails the run (the others run anyway, so one run reports every failure)
test: $(DEVSTAMP)
	$(PYTEST) $(FAST_PARALLEL) $(OFF_CLOCK); off=$$?; \
	$(PYTEST) $(BROWSER); browser=$$?; \
	$(PYTEST) $(REALTIME_PARALLEL) $(REALTIME); realtime=$$?; \
	test $$off -eq 0 && test $$browser -eq 0 && test $$realtime -eq 0

# the edit-test loop: the tests off the clock that take under a second each (`make test`
# runs the slow ones: long simulations, a lab or a class served)
test-fast: $(DEVSTAMP)
	$(PYTEST) $(FAST_PARALLEL) -m "$(OFF_CLOCK_TESTS) and not slow"

# ruff, then mypy on the whole package (pyproject.toml's [tool.mypy])
lint: $(DEVSTAMP)
	$(BIN)/ruff check .
	$(BIN)/mypy

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
