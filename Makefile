# tourbot: `make demo` serves the simulated crowded museum on the web (Ctrl-C stops it), `make test`
# runs lint, type check and all tests.
# Both create the virtual environment and install everything they need themselves.

PYTHON ?= python3
VENV ?= .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.tourbot-installed
NODE_STAMP := node_modules/.tourbot-installed
PEERS_STAMP := $(VENV)/.tourbot-peers-installed
KERNELS_STAMP := $(VENV)/.tourbot-kernels-compiled

.PHONY: setup demo test lint typecheck pytest bench-setup clean

$(STAMP): pyproject.toml constraints.txt
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -c constraints.txt -e '.[dev]'
	touch $(STAMP)

$(NODE_STAMP): package.json package-lock.json
	npm ci --no-audit --no-fund --loglevel=error
	touch $(NODE_STAMP)

# The peers tourbot is compared with (Nav2 AMCL's core, Stone Soup): benchmark extras, also
# installed for the tests so that the adapters are tested.
$(PEERS_STAMP): $(STAMP)
	$(BIN)/python -m pip install --quiet -c constraints.txt -e '.[dev,peers]'
	touch $(PEERS_STAMP)

setup: $(STAMP) $(NODE_STAMP)

# numba compiles the kernels on first use and caches them beside the sources: a short headless tour
# does that once, so that the served demo runs (and localizes) at full speed from its first second.
$(KERNELS_STAMP): $(STAMP)
	@echo "compiling the numerical kernels once (a short headless tour, about 30 s)..."
	$(BIN)/tourbot demo --record --duration 5 --no-animation --out $(VENV)/kernel-warm-up > /dev/null
	touch $(KERNELS_STAMP)

demo: setup $(KERNELS_STAMP)
	$(BIN)/tourbot demo

lint: setup
	$(BIN)/ruff check src tests
	$(BIN)/ruff format --check src tests
	$(BIN)/lint-imports

typecheck: setup
	$(BIN)/mypy

pytest: setup $(PEERS_STAMP)
	$(BIN)/python -m pytest -q

test: lint typecheck pytest

bench-setup: setup $(PEERS_STAMP)

clean:
	rm -rf $(VENV) node_modules .mypy_cache .ruff_cache .pytest_cache
