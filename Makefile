# Two entry points (see README): `make demo` and `make test`.
# Each creates or refreshes the local virtual environment .venv, then runs.

PYTHON ?= python3.11
VENV   := .venv
BIN    := $(VENV)/bin
PIP    := $(BIN)/python -m pip
# The CPU build of torch must be installed before stable-baselines3, otherwise
# pip resolves an unpinned torch to a multi-GB CUDA build.
TORCH  := torch==2.13.0

.PHONY: demo wheel test test-avx2 test-ray figures bench lint clean setup setup-dev setup-ray

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

# Compile the numba kernels once, before any progress bar or test worker needs them,
# into the package's shipped kernels (aldm_gym/_kernels: generic x86-64, what a wheel
# carries; every later run loads them in about a second). Nothing to do when they match.
KERNEL_SOURCES := $(shell find aldm_gym -name '*.py')
$(VENV)/.stamp-kernels: $(KERNEL_SOURCES) | $(VENV)/.stamp-base
	MPLBACKEND=Agg SDL_VIDEODRIVER=dummy $(BIN)/python -m aldm_gym.warmup --store
	touch $@

setup: $(VENV)/.stamp-base $(VENV)/.stamp-kernels
setup-dev: $(VENV)/.stamp-dev $(VENV)/.stamp-kernels

## Main job: the naive-vs-ALDM comparison (quick default, a few minutes on 2 cores).
demo: $(VENV)/.stamp-base $(VENV)/.stamp-kernels
	MPLBACKEND=Agg $(BIN)/aldm-gym compare --quick --out out/demo

## A wheel that carries the shipped kernels (in dist/): its installs compile nothing.
## The store is checked again here: a numba upgrade or a deleted store does not touch
## the kernel stamp.
wheel: $(VENV)/.stamp-base $(VENV)/.stamp-kernels
	MPLBACKEND=Agg SDL_VIDEODRIVER=dummy $(BIN)/python -m aldm_gym.warmup --store
	$(BIN)/python -c "import sys; from aldm_gym._numba import store_status as s; \
		sys.exit(None if s() == 'current' else 'the shipped kernels are ' + s())"
	rm -rf build/lib/aldm_gym/_kernels
	$(PIP) wheel --quiet --no-deps --no-build-isolation -w dist .

## Test suite (lint, then pytest on both cores).
test: $(VENV)/.stamp-dev $(VENV)/.stamp-kernels
	$(BIN)/ruff check aldm_gym tests benchmarks scripts examples
	MPLBACKEND=Agg SDL_VIDEODRIVER=dummy $(BIN)/python -m pytest -n 2 -q

## The suite again on numpy's and OpenBLAS's AVX2 paths. On an AVX-512 CPU numpy's
## scalar math differs from libm's in last bits and the traffic engine's contract takes
## its other branch (docs/env.md, "The traffic engine"); this run takes the first one.
## On a CPU without AVX-512, `make test` already ran those paths.
AVX2_ENV = $(BIN)/python -c "from aldm_gym.envs.traffic.scalar import avx2_dispatch_env as e; \
	v = e(); print(' '.join(f'{k}=\'{x}\'' for k, x in v.items()) if v else '')"
test-avx2: $(VENV)/.stamp-dev $(VENV)/.stamp-kernels
	@vars="$$($(AVX2_ENV))"; \
	if [ -z "$$vars" ]; then \
		echo "no AVX-512 on this CPU: make test ran numpy's AVX2 paths already"; \
	else \
		echo "the test suite under $$vars"; \
		eval "env $$vars MPLBACKEND=Agg SDL_VIDEODRIVER=dummy $(BIN)/python -m pytest -n 2 -q"; \
	fi

# The [ray] extra in a venv of its own: ray[rllib] pins gymnasium 1.2.2 where the
# default install resolves the newest, so the package is tested under both.
RAY_VENV := .venv-ray
RAY_BIN  := $(RAY_VENV)/bin
$(RAY_VENV)/.stamp: pyproject.toml
	$(PYTHON) -m venv $(RAY_VENV)
	$(RAY_BIN)/python -m pip install --quiet --upgrade pip
	$(RAY_BIN)/python -m pip install --quiet $(TORCH)
	$(RAY_BIN)/python -m pip install --quiet -e ".[rl,ray,dev]"
	MPLBACKEND=Agg SDL_VIDEODRIVER=dummy $(RAY_BIN)/python -m aldm_gym.warmup
	touch $@

setup-ray: $(RAY_VENV)/.stamp

## The suite again under the [ray] extra's pins, then the RLlib tests (a two-node cluster).
test-ray: $(RAY_VENV)/.stamp
	MPLBACKEND=Agg SDL_VIDEODRIVER=dummy $(RAY_BIN)/python -m pytest -n 2 -q -m "not slow" \
		--ignore-glob='tests/training/test_rllib*.py'
	MPLBACKEND=Agg SDL_VIDEODRIVER=dummy $(RAY_BIN)/python -m pytest -n 2 -q \
		tests/training/test_rllib.py tests/training/test_rllib_cluster.py

## The numbers and figures of the docs, from seeded runs: the README's headline table,
## docs/results.md's naive-vs-ALDM tables and docs/img (scripts/figures.py; about 5 min).
figures: $(VENV)/.stamp-base $(VENV)/.stamp-kernels
	MPLBACKEND=Agg $(BIN)/python scripts/figures.py

## Speed benchmarks (figures go to BENCHMARKS.md by hand, with the machine noted).
bench: $(VENV)/.stamp-dev
	$(BIN)/python -m benchmarks

lint: $(VENV)/.stamp-dev
	$(BIN)/ruff check aldm_gym tests benchmarks scripts examples
	$(BIN)/ruff format --check aldm_gym tests benchmarks scripts examples

clean:
	rm -rf $(VENV) $(RAY_VENV) out .pytest_cache .ruff_cache
