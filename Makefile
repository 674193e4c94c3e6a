# Two entry points (see README): `make demo` and `make test`.
# Each creates or refreshes the local virtual environment .venv, then runs.

PYTHON ?= python3.11
VENV   := .venv
BIN    := $(VENV)/bin
PIP    := $(BIN)/python -m pip
# The CPU build of torch must be installed before stable-baselines3, otherwise
# pip resolves an unpinned torch to a multi-GB CUDA build.
TORCH  := torch==2.13.0

.PHONY: demo test bench lint clean setup setup-dev

$(BIN)/python:
	$(PYTHON) -m venv $(VENV)
	$(PIP) install --quiet --upgrade pip

# Base install: enough for the environment, the sensor, the ALDM and `compare`.
$(VENV)/.stamp-base: pyproject.toml | $(BIN)/python
	$(PIP) install --quiet -e .
	touch $@

# Everything: the [rl] extra (CPU torch first) and the [dev] tools.
$(VENV)/.stamp-dev: pyproject.toml | $(BIN)/python
	$(PIP) install --quiet $(TORCH)
	$(PIP) install --quiet -e ".[rl,dev]"
	touch $@ $(VENV)/.stamp-base

# Compile the numba kernels once, before any progress bar or test worker needs them
# (numba caches them on disk; later runs load them in well under a second).
KERNEL_SOURCES := $(shell find aldm_gym -name '*.py')
$(VENV)/.stamp-kernels: $(KERNEL_SOURCES) | $(VENV)/.stamp-base
	MPLBACKEND=Agg SDL_VIDEODRIVER=dummy $(BIN)/python -m aldm_gym.warmup
	touch $@

setup: $(VENV)/.stamp-base $(VENV)/.stamp-kernels
setup-dev: $(VENV)/.stamp-dev $(VENV)/.stamp-kernels

## Main job: the naive-vs-ALDM comparison (quick default, a few minutes on 2 cores).
demo: $(VENV)/.stamp-base $(VENV)/.stamp-kernels
	MPLBACKEND=Agg $(BIN)/aldm-gym compare --quick --out out/demo

## Test suite (lint, then pytest on both cores).
test: $(VENV)/.stamp-dev $(VENV)/.stamp-kernels
	$(BIN)/ruff check aldm_gym tests benchmarks
	MPLBACKEND=Agg SDL_VIDEODRIVER=dummy $(BIN)/python -m pytest -n 2 -q

## Speed benchmarks (figures go to BENCHMARKS.md by hand, with the machine noted).
bench: $(VENV)/.stamp-dev
	$(BIN)/python -m benchmarks

lint: $(VENV)/.stamp-dev
	$(BIN)/ruff check aldm_gym tests benchmarks
	$(BIN)/ruff format --check aldm_gym tests benchmarks

clean:
	rm -rf $(VENV) out .pytest_cache .ruff_cache
