# mapassoc: every target sets up its own virtual environment first.
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed-stamp
OUT    ?= demo-out

.PHONY: setup demo test docs bench bench-reprocess lint notebooks clean

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[dev,docs]'
	touch $(STAMP)

setup: $(STAMP)

demo: $(STAMP)
	$(BIN)/mapassoc demo --out $(OUT) --overwrite

# The documentation first (warnings are errors), then every test, slow ones included
# (-m ""), on every core (pytest-xdist; an idle worker takes tests queued for another).
test: docs
	$(BIN)/python -m pytest -q -m "" -n auto --dist worksteal

# The HTML site, offline (no notebook execution, no intersphinx): docs/_build/html/index.html.
docs: $(STAMP)
	$(BIN)/python -m sphinx -b html -W --keep-going -q docs docs/_build/html

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
	rm -rf $(VENV) $(OUT) .pytest_cache .ruff_cache docs/_build docs/jupyter_execute
