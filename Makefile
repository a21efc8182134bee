# tourbot: `make demo` serves the simulated crowded museum on the web (Ctrl-C stops it), `make test`
# runs lint, type check, the documentation build and every test (none skipped: the browser,
# PostgreSQL and speech tests get what they need from scripts/test-services.sh).
# Both create the virtual environment and install everything they need themselves.
# `make test-fast`: the same checks without the slow, browser and PostgreSQL tests (skips allowed).

PYTHON ?= python3
VENV ?= .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.tourbot-installed
NODE_STAMP := node_modules/.tourbot-installed
PEERS_STAMP := $(VENV)/.tourbot-peers-installed
KERNELS_STAMP := $(VENV)/.tourbot-kernels-compiled

.PHONY: setup demo test test-fast lint typecheck pytest pytest-fast docs docs-serve bench-setup clean

$(STAMP): pyproject.toml constraints.txt
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -c constraints.txt -e '.[dev,docs,cluster]'
	touch $(STAMP)

$(NODE_STAMP): package.json package-lock.json
	npm ci --no-audit --no-fund --loglevel=error
	touch $(NODE_STAMP)

# The peers tourbot is compared with (Nav2 AMCL's core, Stone Soup): benchmark extras, also
# installed for the tests so that the adapters are tested.
$(PEERS_STAMP): $(STAMP)
	$(BIN)/python -m pip install --quiet -c constraints.txt -e '.[dev,docs,cluster,peers]'
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

# Every test, none skipped (TOURBOT_NO_SKIPS=1 makes a skip fail the run): the script installs
# chromium, postgresql and espeak-ng when root with apt-get, or fails naming the command that does,
# and prints the URL of the PostgreSQL test database it started.
pytest: setup $(PEERS_STAMP)
	url=$$(bash scripts/test-services.sh) && \
	TOURBOT_TEST_DATABASE_URL="$$url" TOURBOT_NO_SKIPS=1 $(BIN)/python -m pytest -q

pytest-fast: setup
	$(BIN)/python -m pytest -q -m "not slow and not browser and not postgres"

# The documentation site, strict: a broken link, a missing page or a docstring mkdocstrings cannot
# read fails the build. Written to site/ (ignored by git); `make docs-serve` serves it live.
docs: setup
	NO_MKDOCS_2_WARNING=1 $(BIN)/mkdocs build --strict --quiet

docs-serve: setup
	NO_MKDOCS_2_WARNING=1 $(BIN)/mkdocs serve

test: lint typecheck docs pytest

test-fast: lint typecheck docs pytest-fast

bench-setup: setup $(PEERS_STAMP)

clean:
	rm -rf $(VENV) node_modules .mypy_cache .ruff_cache .pytest_cache site
