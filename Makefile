# One-command set-up: every target creates .venv and installs coons with its dev extra
# from pyproject.toml on first use (needs only python3 >= 3.11 and the package registry).
PYTHON ?= python3
VENV ?= .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed

.PHONY: demo validate test test-slow bench lint clean

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[dev]'
	touch $(STAMP)

validate: $(STAMP)
	$(VENV)/bin/coons validate --jobs 2 --report validation-report

demo: $(STAMP)
	$(VENV)/bin/coons demo --out demo-output

test: $(STAMP)
	$(VENV)/bin/lint-imports
	$(PY) -m pytest -n 2 -m "not slow" --hypothesis-profile=ci

test-slow: $(STAMP)
	$(PY) -m pytest -n 2 -m slow --hypothesis-profile=ci

bench: $(STAMP)
	$(PY) benchmarks/run.py

clean:
	rm -rf $(VENV) demo-output validation-report .pytest_cache .hypothesis
