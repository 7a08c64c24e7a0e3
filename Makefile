# servodesk: one-command setup, demo and test on a fresh machine (Python 3.11, Node 20, root).
#
#   make demo   set everything up and serve the UI with simulated drives on http://127.0.0.1:8000
#   make test   set everything up and run the whole suite (lint, types, unit, integration, browser)
#   make check  the fast tier while developing (< 1 min on 2 cores): lint, layer rules, Python
#               types and the pure tests (no bus, no browser, no wall clock; docs/testing.md)

PYTHON ?= python3.11
UV_VERSION := 0.13.9
TOOLS := .tools
UV := $(TOOLS)/bin/uv
VENV := .venv
PY := $(VENV)/bin/python
FRONTEND := frontend
WEB_DIST := backend/servodesk/web/dist
HOST ?= 127.0.0.1
PORT ?= 8000

export UV_PYTHON_DOWNLOADS := never
export UV_PROJECT_ENVIRONMENT := $(VENV)

.PHONY: setup demo test check check-tests lint typecheck unit wheel build clean chromium netutils postgres bench openapi

setup: $(VENV)/.synced $(WEB_DIST)/index.html

$(UV):
	@command -v $(PYTHON) >/dev/null 2>&1 || { echo "servodesk needs $(PYTHON) (set PYTHON=...)"; exit 2; }
	$(PYTHON) -m venv $(TOOLS)
	$(TOOLS)/bin/pip install --quiet --disable-pip-version-check uv==$(UV_VERSION)

# The Python environment, exactly as pinned in uv.lock (dev tools included).
$(VENV)/.synced: $(UV) pyproject.toml uv.lock
	$(UV) sync --frozen --python $(PYTHON)
	@touch $@

# The browser UI, exactly as pinned in frontend/package-lock.json, built into the package.
# `npm install --no-save` rather than `npm ci`: npm 11 writes lock files without other
# platforms' optional packages (rollup's native builds) and its `npm ci` then refuses them
# (npm/cli#8320). With a lock file present, install takes exactly the locked versions and
# integrity hashes, and --no-save leaves the lock file untouched.
$(FRONTEND)/node_modules/.package-lock.json: $(FRONTEND)/package.json $(FRONTEND)/package-lock.json
	cd $(FRONTEND) && npm install --no-save --no-audit --no-fund --loglevel=error

# vite alone: `npm run build` also type-checks, which `make typecheck` does (beside lint, in
# make test) and `make demo` need not wait for.
$(WEB_DIST)/index.html: $(FRONTEND)/node_modules/.package-lock.json $(shell find $(FRONTEND)/src $(FRONTEND)/public $(FRONTEND)/index.html $(FRONTEND)/vite.config.ts -type f 2>/dev/null)
	cd $(FRONTEND) && npx --no-install vite build

build: $(WEB_DIST)/index.html

# Debian's Chromium for the browser tests (never a downloaded browser build).
chromium:
	@command -v chromium >/dev/null 2>&1 || command -v chromium-browser >/dev/null 2>&1 || \
	  { apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends chromium >/dev/null; }

# iproute2 (ip: the veth pairs of the EtherCAT tests) and util-linux (setpriv: the tests that
# run as an unprivileged user), where a minimal image lacks them.
netutils:
	@command -v ip >/dev/null 2>&1 || [ -x /usr/sbin/ip ] || [ -x /sbin/ip ] || \
	  { apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends iproute2 >/dev/null; }
	@command -v setpriv >/dev/null 2>&1 || \
	  { apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends util-linux >/dev/null; }

# Debian's PostgreSQL for the store's tests (tests/store/conftest.py starts a throw-away
# server with its initdb and pg_ctl; nothing is started or enabled as a service here).
postgres:
	@ls /usr/lib/postgresql/*/bin/initdb >/dev/null 2>&1 || command -v initdb >/dev/null 2>&1 || \
	  { apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends postgresql >/dev/null; }

demo: setup
	$(VENV)/bin/servodesk serve --sim --single-user --host $(HOST) --port $(PORT)

lint: $(VENV)/.synced
	$(VENV)/bin/ruff check backend tests bench scripts
	$(VENV)/bin/ruff format --check backend tests bench scripts
	$(VENV)/bin/lint-imports --no-cache  # The layer rules (pyproject.toml, docs/architecture.md).
	$(VENV)/bin/pytest -q -p no:cacheprovider tests/unit/test_openapi_contract.py  # openapi.json is the code's

typecheck: $(VENV)/.synced $(FRONTEND)/node_modules/.package-lock.json
	$(VENV)/bin/mypy
	@cd $(FRONTEND) && npm run --silent check:api || \
	  { echo "frontend/src/api/schema.ts is stale against backend/openapi.json: run make openapi"; exit 1; }
	$(VENV)/bin/python scripts/gen_scope_wire.py --check
	cd $(FRONTEND) && npm run --silent typecheck

unit: setup
	cd $(FRONTEND) && npm test --silent

# The wheel a user would pip install: it must carry the built UI and every profile.
wheel: setup
	rm -rf dist && $(UV) build --wheel -q -o dist
	$(PY) scripts/check_wheel.py dist

# The fast tier: no frontend, no browser, no bus. The pure tests are the paths of
# tests/conftest.py CHECK_PATHS, on both cores (measured: docs/testing.md).
check: lint
	$(VENV)/bin/mypy
	$(MAKE) --no-print-directory check-tests

check-tests: $(VENV)/.synced
	$(VENV)/bin/pytest -q -p no:cacheprovider -m check -n 2 \
	  $$($(PY) -c "from tests.conftest import CHECK_PATHS; print(*CHECK_PATHS)")

# The suite in two parts: the tests on simulated time on every core, then the rest one at a
# time (scripts/run_tests.sh, tests/conftest.py).
# The static checks, the UI's unit tests and the wheel two at a time (each target's output
# kept together), then the suite.
test: setup chromium netutils postgres
	$(MAKE) --no-print-directory -j2 --output-sync=target lint typecheck unit wheel
	scripts/run_tests.sh

bench: setup
	$(PY) bench/bench_sdo.py --json
	$(PY) bench/bench_sim.py --json
	$(PY) bench/bench_pdo.py --json
	$(PY) bench/bench_tuning_design.py --json
	$(PY) bench/bench_replay.py --json
	$(PY) bench/bench_tuning_loop.py --json
	$(VENV)/bin/servodesk bench scope --json
	$(PY) bench/bench_gateways.py --json

# The wire contract (docs/architecture.md): the OpenAPI of the code, and the UI's types from it.
# Both files are committed; `make lint` and `make typecheck` fail when either is stale.
openapi: $(VENV)/.synced $(FRONTEND)/node_modules/.package-lock.json
	$(VENV)/bin/servodesk openapi > backend/openapi.json.tmp && mv backend/openapi.json.tmp backend/openapi.json
	cd $(FRONTEND) && npm run --silent gen:api
	$(VENV)/bin/python scripts/gen_scope_wire.py  # The scope stream's binary layout.

clean:
	rm -rf $(VENV) $(TOOLS) $(FRONTEND)/node_modules $(WEB_DIST)
