# Set-up and entry points. Everything installs into .venv from pyproject.toml, pinned by the lock file
# constraints.txt (every package at the version that produced results/).
PYTHON ?= python3
VENV   ?= .venv
BIN     = $(VENV)/bin
export MUJOCO_GL ?= egl

.PHONY: setup demo data benchmark test regression ci-baselines perf wheel-check lock clean docs

$(BIN)/kgn-bench: pyproject.toml constraints.txt
	$(PYTHON) -m venv $(VENV)
	$(BIN)/pip install --upgrade pip
	$(BIN)/pip install -c constraints.txt -e '.[test,ray]'
	touch $@

setup: $(BIN)/kgn-bench

# The main job: the closed-loop benchmark (tasks/benchmark.toml: primitives, household objects, the real-object
# set, imported on first use, and pile and packed rounds) with the shipped KGNv2 weights, then the report table
# (runs/benchmark/benchmark.md); the plan's viewpoint study (camera sweeps, about 3 min a detector) and GIGA's
# rounds (the calibration table, about 4 min a detector) are left to the full run, to keep this job under
# 15 min. `kgn-bench benchmark --out results` runs every detector and all of it.
MAIN_TASKS = single_object single_household multi_object multi_household single_real multi_real \
	pile pile@assisted packed packed@assisted
benchmark: setup
	$(BIN)/kgn-bench benchmark tasks/benchmark.toml --detectors kgnv2 --tasks $(MAIN_TASKS) --workers 2 \
	  --runs runs/benchmark --no-viewpoints

# A small multi-object PS dataset and a preview of one view.
demo: setup
	$(BIN)/kgn-bench data generate --mode multi --scenes 20 --seed 0 --workers 2 --out runs/ps_multi_demo
	$(BIN)/kgn-bench data show runs/ps_multi_demo --scene 0 --view 0 --out runs/ps_multi_demo/preview.png

test: setup
	$(BIN)/ruff check kgn_bench tests docs/hooks results/architecture
	$(BIN)/pytest -q

# Every dataset the shipped weights were trained on, made again in data/ (each command resumes what is on disk
# and skips what is done). The PS splits take about 4 min each on 2 cores and come out byte-identical to the
# datasets of the cached evaluations (results/vision/). data/ps_mesh imports its 300 pybullet train meshes first
# (about 40 s an object a core, cached in the object library), then renders its scenes; data/vgn is VGN's
# first 600 scenes (about 4 core-hours). In all about 5 hours on 2 cores.
DATA_WORKERS ?= 2
data: setup
	$(BIN)/kgn-bench data generate --mode multi --scenes 1000 --views 5 --seed 0 --workers $(DATA_WORKERS) \
	  --quiet --out data/ps_multi
	$(BIN)/kgn-bench data generate --mode single --scenes 1000 --views 5 --seed 0 --workers $(DATA_WORKERS) \
	  --quiet --out data/ps_single
	$(BIN)/kgn-bench data generate --mode multi --scenes 1000 --views 5 --seed 0 --workers $(DATA_WORKERS) \
	  --objects primitives pybullet_train:300 --appearance random --depth-noise 1 --quiet --out data/ps_mesh
	$(BIN)/kgn-bench data vgn --scenes 600 --workers $(DATA_WORKERS) --quiet --out data/vgn

# The regression checks that the test suite runs (tests/test_ci_regression.py), with their tables printed:
# task:baseline:detectors for the fixed-seed clearance task, the fixed-seed pile task (raw mode) and 4 rounds of
# GIGA's pile protocol, against results/<baseline>.json.
CI_CHECKS = ci_regression:ci_baseline:kgnv2,oracle ci_pile:ci_baseline_pile:kgnv2,oracle \
	ci_giga_pile:ci_baseline_giga_pile:kgnv2,oracle,vgn
regression: setup
	for t in $(CI_CHECKS); do task=$${t%%:*}; rest=$${t#*:}; base=$${rest%%:*}; \
	  for d in $$(echo $${rest#*:} | tr , ' '); do rm -rf runs/$${task}_$$d; \
	  $(BIN)/kgn-bench run tasks/$$task.toml --detector $$d --workers 2 --quiet --out runs/$${task}_$$d \
	    > /dev/null && $(BIN)/kgn-bench check runs/$${task}_$$d --baseline results/$$base.json || exit 1; \
	done; done

# Write the CI baselines anew (after a change that is meant to change records): the same runs as `regression`,
# each written as its detector's baseline (rates and the records' fingerprint).
ci-baselines: setup
	for t in $(CI_CHECKS); do task=$${t%%:*}; rest=$${t#*:}; base=$${rest%%:*}; \
	  for d in $$(echo $${rest#*:} | tr , ' '); do rm -rf runs/$${task}_$$d; \
	  $(BIN)/kgn-bench run tasks/$$task.toml --detector $$d --workers 2 --quiet --out runs/$${task}_$$d \
	    > /dev/null && $(BIN)/kgn-bench check runs/$${task}_$$d --baseline results/$$base.json --update-baseline \
	    || exit 1; \
	done; done

# Build the wheel, install it into a separate venv and run one oracle and one kgnv2 trial from a folder
# outside the clone (what `pip install .` gives a user; .ci/run calls it).
wheel-check:
	bash .ci/wheel_check

# Refresh the lock file: a new venv from pyproject.toml's ranges (torch kept at the CPU 2.13.0 build), then
# pip freeze. Afterwards run `make benchmark` and re-measure results/ if a figure moved.
lock:
	rm -rf .lock-venv
	$(PYTHON) -m venv .lock-venv
	.lock-venv/bin/pip install --upgrade pip
	.lock-venv/bin/pip install 'torch==2.13.0' -e '.[test,ray,docs]'
	{ sed -n '/^#/p' constraints.txt; .lock-venv/bin/pip freeze --exclude-editable | grep -v '^#' \
	  | sed 's/^torch==2.13.0+cpu$$/torch==2.13.0/'; } > constraints.txt.new
	mv constraints.txt.new constraints.txt
	rm -rf .lock-venv

# The documentation site (mkdocs.yml, docs/) into site/, strict: a broken link, a missing page or a docstring
# mkdocstrings cannot render fails the build. Installs the docs extra from the lock file the first time.
$(VENV)/.docs-installed: $(BIN)/kgn-bench pyproject.toml constraints.txt
	$(BIN)/pip install -c constraints.txt -e '.[docs]'
	touch $@

docs: $(VENV)/.docs-installed
	$(BIN)/mkdocs build --strict --site-dir site

perf: setup
	$(BIN)/kgn-bench perf data --scenes 40 --workers 2
	$(BIN)/kgn-bench perf run tasks/single_object.toml --trials 5 --workers 2

clean:
	rm -rf $(VENV) runs site .pytest_cache build dist
