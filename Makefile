# Two commands on a fresh clone: `make demo` and `make test`. Both bootstrap .venv.
PYTHON ?= $(shell command -v python3.11 || command -v python3)
VENV := .venv
BIN := $(VENV)/bin
PACKAGES := protocol trackdb onboard trackside deploy

# Tests use PostgreSQL when a server answers on 127.0.0.1:5432 (database `test`).
PG_URL := postgresql+psycopg://postgres@127.0.0.1:5432/test
PG_UP = $(shell $(BIN)/python -c "import socket; s=socket.socket(); s.settimeout(0.5); print('yes' if s.connect_ex(('127.0.0.1', 5432)) == 0 else '')" 2>/dev/null)

.PHONY: demo test check lint typecheck pytest pytest-quick bench clean

$(BIN)/python:
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip

$(VENV)/.installed: pyproject.toml | $(BIN)/python
	$(BIN)/python -m pip install --quiet -e .
	touch $@

$(VENV)/.installed-test: pyproject.toml | $(BIN)/python
	$(BIN)/python -m pip install --quiet -e '.[test]'
	touch $(VENV)/.installed $@

demo: $(VENV)/.installed
	$(BIN)/ato demo $(if $(LINE),--line $(LINE))

lint: $(VENV)/.installed-test
	$(BIN)/ruff check .
	$(BIN)/ruff format --check .

typecheck: $(VENV)/.installed-test
	$(BIN)/mypy $(PACKAGES) tests

# The suite runs on PYTEST_WORKERS processes (pytest-xdist; idle workers take tests queued on
# busy ones). The lockstep scenario tests dominate and are independent; 1 runs it serially.
PYTEST_WORKERS ?= 2

pytest: $(VENV)/.installed-test
	ATO_TEST_DATABASE_URL=$${ATO_TEST_DATABASE_URL:-$(if $(PG_UP),$(PG_URL),)} \
		$(BIN)/python -m pytest $(if $(filter-out 1,$(PYTEST_WORKERS)),-n $(PYTEST_WORKERS) --dist worksteal,)

test: lint typecheck pytest

# The inner loop: lint, types and the tests not marked e2e, browser, scenario or slow (no
# processes started, no simulated minutes; fewer hypothesis examples), in under two minutes on
# two cores. CI runs `test`.
pytest-quick: $(VENV)/.installed-test
	ATO_HYPOTHESIS_PROFILE=ato-quick $(BIN)/python -m pytest -q -n $(PYTEST_WORKERS) --dist worksteal \
		-m "not e2e and not browser and not scenario and not slow"

check: lint typecheck pytest-quick

bench: $(VENV)/.installed-test
	$(BIN)/ato bench zenoh
	$(BIN)/ato bench trackdb
	$(BIN)/ato bench plant
	$(BIN)/ato bench adf
	$(BIN)/ato bench vc
	$(BIN)/ato bench sfa
	$(BIN)/ato bench run
	# 500 generated scenarios from the ring's space, seed 1 (docs/scenarios.md, "Generated
	# scenarios"); exit 1 on an invariant violated.
	$(BIN)/ato campaign --generate 500 --seed 1 --json .ato/bench/generated.json

clean:
	rm -rf $(VENV) .ato .mypy_cache .pytest_cache .ruff_cache
