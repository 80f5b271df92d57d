# mapassoc: every target sets up its own virtual environment first.
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed-stamp
OUT    ?= demo-out

.PHONY: setup demo test bench bench-reprocess lint notebooks clean

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[dev]'
	touch $(STAMP)

setup: $(STAMP)

demo: $(STAMP)
	$(BIN)/mapassoc demo --out $(OUT) --overwrite

# Every test, slow ones included (-m ""), on every core (pytest-xdist; an idle worker
# takes tests queued for another, so no worker trails alone at the end).
test: $(STAMP)
	$(BIN)/python -m pytest -q -m "" -n auto --dist worksteal

bench: $(STAMP)
	$(BIN)/mapassoc bench

bench-reprocess: $(STAMP)
	$(BIN)/mapassoc bench-reprocess

notebooks: $(STAMP)
	$(BIN)/python -m pip install --quiet -e '.[dev,notebooks]'
	$(BIN)/python notebooks/execute.py

lint: $(STAMP)
	$(BIN)/python -m pytest -q -m "" tests/test_static_checks.py

clean:
	rm -rf $(VENV) $(OUT) .pytest_cache .ruff_cache
