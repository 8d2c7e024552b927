# `make bench` runs the benchmark, `make test` runs the tests; both set everything up first
# on a fresh machine (virtual environment, package, libLLVM, chromium) and skip the set-up
# when nothing changed.  The Python packages are the exact versions of requirements.lock;
# `make lock` refreshes it (docs/install.md).
VENV  ?= .venv
STAMP := $(VENV)/.setup-stamp
PY    := $(VENV)/bin/python
UV    := $(VENV)/bin/uv

.PHONY: bench test setup lint render clean-venv lock

$(STAMP): pyproject.toml setup.py requirements.lock scripts/setup.sh
	VENV=$(VENV) bash scripts/setup.sh
	touch $(STAMP)

setup: $(STAMP)

# --executor pool: the jobs in one worker process per core (the renders use every core anyway)
bench: $(STAMP)
	$(VENV)/bin/pbrbench run --quality standard --executor pool

# pyproject.toml's addopts: -ra (the summary of every test not passed, skips with their reasons; a
# skip not on tests/allowed_skips.txt fails the run) and -n auto (pytest-xdist, a worker per core).
# The run writes its bytecode caches even where PYTHONDONTWRITEBYTECODE is set: tests/conftest.py
test: $(STAMP)
	$(VENV)/bin/pytest -q

lint: $(STAMP)
	$(VENV)/bin/ruff check pbrbench tests

render: $(STAMP)
	$(VENV)/bin/pbrbench render --all --quality standard

# The lock: pyproject.toml's dependencies with the dev, distributed and peers extras, plus the set-up's
# own tools (uv, pip; setuptools and wheel, which build the editable pbrbench), resolved for the
# supported platform, every file's sha256 recorded.  `make lock` moves every package to the newest
# version pyproject.toml allows; `make lock LOCK_UPGRADE=` keeps the current pins where they still
# fit (after editing pyproject.toml); `make lock LOCK_UPGRADE="--upgrade-package numpy"` moves one.
LOCK_TOOLS    := uv pip 'setuptools>=77' wheel
LOCK_PYTHON   ?= 3.11
LOCK_PLATFORM ?= x86_64-unknown-linux-gnu
LOCK_UPGRADE  ?= --upgrade

lock:
	VENV=$(VENV) bash scripts/setup.sh --uv-only
	printf '%s\n' $(LOCK_TOOLS) | $(UV) pip compile --quiet pyproject.toml - --extra dev --extra distributed --extra peers \
	  --generate-hashes --python-version $(LOCK_PYTHON) --python-platform $(LOCK_PLATFORM) \
	  --custom-compile-command "make lock" $(LOCK_UPGRADE) -o requirements.lock

clean-venv:
	rm -rf $(VENV)
