# The README's two commands: `make demo` (main job) and `make test` (lint, then the whole suite).
# Both create the virtual environment they need, idempotently: torch first (the local
# CPU wheel; a loose torch requirement would pull GBs of CUDA packages), then the package.
SHELL := /bin/bash
PYTHON ?= python3
VENV ?= .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed-$(shell cat pyproject.toml | sha1sum | cut -c1-12)
export OMP_NUM_THREADS ?= 1
# hanabi-learning-environment builds with CMake and needs this under CMake 4.
export CMAKE_POLICY_VERSION_MINIMUM := 3.5
export PIP_DISABLE_PIP_VERSION_CHECK := 1

.PHONY: demo test test-fast lint venv bench clean chromium

demo: $(STAMP)
	$(BIN)/rllib-conv demo

# Two pytest workers (pytest-xdist), one per core: a training test keeps about one core busy (one torch thread,
# sampling and learning in one process), so two side by side take about half the wall time (22 -> 10.5 min). Tests
# sharing a session-trained ego run on one worker (`--dist loadgroup`, tests/conftest.py). The slowest 25
# tests are listed at the end of every run: the suite is to stay under 20 minutes.
test: $(STAMP) chromium lint
	$(BIN)/python -m pytest -q -n 2 --dist loadgroup --durations=25

# The inner loop: every test that does not train (`-m "not slow"`; see tests/conftest.py), in
# under 2 minutes on 2 cores. `make test` runs these and the training ones.
test-fast: $(STAMP) chromium
	$(BIN)/python -m pytest -q -n 2 -m "not slow"

# ruff's rules and format, as configured in pyproject.toml ([tool.ruff]); CI runs it through `make test`.
lint: $(STAMP)
	$(BIN)/ruff check .
	$(BIN)/ruff format --check .

venv: $(STAMP)

# The browser tests (tests/play) drive Debian's chromium headless; Playwright's own browser
# download needs the internet, Debian's package does not. Idempotent: skipped when installed.
chromium:
	command -v chromium >/dev/null || (apt-get update && DEBIAN_FRONTEND=noninteractive apt-get install -y chromium)

# The quickest benchmark (about a minute); every script and its latest result: benchmarks/README.md.
bench: $(STAMP)
	$(BIN)/python -m benchmarks.env_throughput

$(STAMP): pyproject.toml
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install -q --upgrade pip wheel setuptools
	$(BIN)/python -m pip install -q torch==2.13.0
	$(BIN)/python -m pip install -q -e ".[test]"
	rm -f $(VENV)/.installed-*
	touch $@

clean:
	rm -rf $(VENV) build *.egg-info
