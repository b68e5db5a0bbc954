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
# `make test` runs the tests on the wall clock (marked realtime, not browser) in one
# process beside them: a real-time test mostly waits on the clock (its emulator's physics,
# a served lab's loop), and those workers compute meanwhile, at a lower priority (nice),
# so that the real-time tests keep the margin they have alone
ON_CLOCK := -m "realtime and not browser"
NICE := nice -n 10
# the browser tests run last, in one process: each page drawn in software takes most of
# a 2-core machine (PARALLEL="-n 2 --dist loadfile --no-loadscope-reorder" runs them on
# two workers, each module whole on one)
BROWSER := -m browser
PARALLEL ?=

# everything: the tests on the clock (their report printed when they end) beside those off
# it, then the browser tests; any part failing fails the run (the others run anyway, so
# one run reports every failure)
test: $(DEVSTAMP)
	clock_log=$$(mktemp); \
	$(PYTEST) $(ON_CLOCK) > $$clock_log 2>&1 & clock_pid=$$!; \
	$(TESTENV) $(NICE) $(BIN)/python -m pytest -q $(FAST_PARALLEL) $(OFF_CLOCK); off=$$?; \
	wait $$clock_pid; clock=$$?; \
	echo "--- the tests on the wall clock (run beside those above):"; \
	cat $$clock_log; rm -f $$clock_log; \
	$(PYTEST) $(PARALLEL) $(BROWSER); page=$$?; \
	test $$off -eq 0 && test $$clock -eq 0 && test $$page -eq 0

# the edit-test loop: the tests off the clock that take under a second each (`make test`
# runs the slow ones: long simulations, a lab or a class served)
test-fast: $(DEVSTAMP)
	$(PYTEST) $(FAST_PARALLEL) -m "$(OFF_CLOCK_TESTS) and not slow"

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
