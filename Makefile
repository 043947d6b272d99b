# `make demo` runs the main scenario, `make test` runs the tests; both create .venv when missing.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin

.PHONY: demo test bench clean-venv

$(BIN)/impactqp: pyproject.toml
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[test,bench,franka,panda]'
	touch $@

demo: $(BIN)/impactqp
	$(BIN)/impactqp demo

# --dist worksteal: a worker that has run its share takes tests queued on the other (the default
# schedule leaves the last tests sent to one worker there while the other waits).
test: $(BIN)/impactqp
	$(BIN)/lint-imports
	$(BIN)/python -m pytest -n 2 --dist worksteal tests

bench: $(BIN)/impactqp
	$(BIN)/impactqp bench
