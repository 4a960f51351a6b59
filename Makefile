# `make demo`: set up everything and run the bundled default. `make test`: set up and run the tests.
VENV := .venv
export NUMBA_CACHE_DIR ?= $(CURDIR)/.cache/numba
export OMP_NUM_THREADS ?= 2

.PHONY: setup demo test test-all bench

setup:
	@bash scripts/setup.sh

demo: setup
	$(VENV)/bin/garment demo

test: setup
	$(VENV)/bin/python -m pytest -q

test-all: setup
	$(VENV)/bin/python -m pytest -q -m ""

bench: setup
	$(VENV)/bin/garment bench plate
