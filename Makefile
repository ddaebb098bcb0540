# Set-up and entry points. Everything installs into .venv from pyproject.toml + constraints.txt.
PYTHON ?= python3
VENV   ?= .venv
BIN     = $(VENV)/bin
export MUJOCO_GL ?= egl

.PHONY: setup demo test lint perf clean

$(BIN)/kgn-bench: pyproject.toml constraints.txt
	$(PYTHON) -m venv $(VENV)
	$(BIN)/pip install --upgrade pip
	$(BIN)/pip install -c constraints.txt -e '.[test]'
	touch $@

setup: $(BIN)/kgn-bench

# The main job (until the benchmark lands): a small multi-object PS dataset and a preview of one view.
demo: setup
	$(BIN)/kgn-bench data generate --mode multi --scenes 20 --seed 0 --workers 2 --out runs/ps_multi_demo
	$(BIN)/kgn-bench data show runs/ps_multi_demo --scene 0 --view 0 --out runs/ps_multi_demo/preview.png

test: setup
	$(BIN)/ruff check kgn_bench tests
	$(BIN)/pytest -q

perf: setup
	$(BIN)/kgn-bench perf data --scenes 40 --workers 2

clean:
	rm -rf $(VENV) runs .pytest_cache
