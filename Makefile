# Every target sets itself up: the first call creates .venv and installs cosim with its pinned
# dependencies (SUMO, MuJoCo ... all from PyPI wheels); later calls reuse it.
PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed-stamp
# cosim's bytecode, written once: with PYTHONDONTWRITEBYTECODE set (as on CI) every process of a run (the
# radio, the log writer, each participant, each CLI call of the tests) would compile cosim anew (~0.5 CPU s)
BYTECODE := $(PY) -m compileall -q cosim

.PHONY: test test-fast experiment bench lint clean

$(STAMP): pyproject.toml
	@$(PYTHON) -c 'import sys; sys.exit(0 if sys.version_info >= (3, 11) else "cosim needs Python >= 3.11")'
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install -q --upgrade pip
	$(PY) -m pip install -q -e '.[dev]'
	touch $@

# one worker per core (both targets), each test file whole on one worker (its module fixtures build a map
# once); the workers share one scenario cache (tests/conftest.py)
test: $(STAMP)
	$(BYTECODE)
	$(PY) -m pytest -q -ra -n auto --dist loadfile

test-fast: $(STAMP)
	$(BYTECODE)
	$(PY) -m pytest -q -ra -m 'not slow' -n auto --dist loadfile

# --force: a second `make experiment` replaces results/paper (cosim refuses to overwrite a run without it)
experiment: $(STAMP)
	$(BYTECODE)
	$(VENV)/bin/cosim experiment configs/experiment.yaml --clip --force

bench: $(STAMP)
	$(BYTECODE)
	$(PY) -m bench.run_all

lint: $(STAMP)
	$(VENV)/bin/ruff check cosim tests bench examples
	$(VENV)/bin/ruff format --check cosim tests bench examples

clean:
	rm -rf $(VENV) .cache results .pytest_cache
