# `make bench` runs the benchmark, `make test` runs the tests; both set everything up first
# on a fresh machine (virtual environment, package, libLLVM, chromium) and skip the set-up
# when nothing changed.
VENV  ?= .venv
STAMP := $(VENV)/.setup-stamp
PY    := $(VENV)/bin/python

.PHONY: bench test setup lint render clean-venv

$(STAMP): pyproject.toml scripts/setup.sh
	VENV=$(VENV) bash scripts/setup.sh
	touch $(STAMP)

setup: $(STAMP)

bench: $(STAMP)
	$(VENV)/bin/pbrbench run --quality standard

test: $(STAMP)
	$(VENV)/bin/pytest -q

lint: $(STAMP)
	$(VENV)/bin/ruff check pbrbench tests

render: $(STAMP)
	$(VENV)/bin/pbrbench render --all --quality standard

clean-venv:
	rm -rf $(VENV)
