# wsn-motion: `make figures` regenerates every figure and table, `make test` runs lint and tests,
# `make book` (after `make figures`) renders the executed notebooks as HTML in build/book/.
# They bootstrap .venv from environment.lock on first use (only python3 is needed).

PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
KERNEL := wsn-motion
STAMP := $(VENV)/.installed

# The BROAD trials: a checkout next to ../shared/ (as on CI) reads them from there unless
# WSNLIB_BROAD_DIR says otherwise; without either, the loader downloads into data/raw/broad/.
SHARED_BROAD := $(abspath ../shared/data/broad)
ifneq ($(wildcard $(SHARED_BROAD)/*.mat),)
export WSNLIB_BROAD_DIR ?= $(SHARED_BROAD)
endif
# The PABR BLE subset likewise; without either, the loader downloads the files it needs
# (verified against wsnlib/registry/pabr.tsv) into data/raw/pabr/.
SHARED_PABR := $(abspath ../shared/data/pabr)
ifneq ($(wildcard $(SHARED_PABR)/cnf),)
export WSNLIB_PABR_DIR ?= $(SHARED_PABR)
endif

.PHONY: figures quick test lint lock clean-outputs book lab browser book-test lab-test

# Notebooks run two at a time (one per core): each is independent of the others.
JOBS ?= 2

figures: $(STAMP)
	$(PY) -m wsnlib.reproduce --jobs $(JOBS)

quick: $(STAMP)
	$(PY) -m wsnlib.reproduce --quick --jobs $(JOBS)

# The quick batch's tests first and alone (the batch runs $(JOBS) notebooks at a time, and no other
# test compiles kernels meanwhile, which would void its run-time check); then the rest in $(JOBS)
# processes, a test file per process (its fixtures are built once).
test: $(STAMP)
	$(VENV)/bin/ruff check .
	$(PY) -m pytest tests/test_notebooks.py -m notebook
	$(PY) -m pytest -n $(JOBS) --dist loadfile --no-loadscope-reorder -m "not notebook and not browser and not lab"

lint: $(STAMP)
	$(VENV)/bin/ruff check .

# A static HTML site from the executed notebooks in build/executed/ (run `make figures` first):
# build/book/index.html.  Renders what is there; it does not run the notebooks again.
book: $(STAMP)
	$(PY) -m wsnlib.book

# JupyterLab from the venv, on the notebooks (pick the "Python (wsn-motion)" kernel).
lab: $(STAMP)
	$(VENV)/bin/jupyter lab --notebook-dir=notebooks

# Headless Chromium and its WebDriver from Debian's packages, for the browser test of the
# book; installed here (a set-up step, root needed), never downloaded by the tests.
browser:
	@if [ -x /usr/bin/chromium ] && [ -x /usr/bin/chromedriver ]; then \
		echo "chromium and chromedriver are installed"; \
	elif [ "$$(id -u)" = 0 ]; then \
		apt-get update && DEBIAN_FRONTEND=noninteractive apt-get install -y chromium chromium-driver; \
	else \
		echo "make browser: /usr/bin/chromium or /usr/bin/chromedriver is missing; as root run" >&2; \
		echo "  apt-get update && apt-get install -y chromium chromium-driver" >&2; \
		exit 1; \
	fi

# The browser test of build/book/ (run `make book` first): every page reachable from the
# index loads without a broken link, a missing image or a console error; screenshots go to
# build/book-screenshots/.
book-test: $(STAMP) browser
	$(PY) -m pytest -m browser tests/test_book_browser.py

# The student's path in a real browser: JupyterLab from the venv (on a temporary quick-mode copy of
# the notebooks, outputs to a temporary folder) runs every notebook in headless Chromium, Run → Run
# All Cells, one kernel at a time per process: two processes (each its own JupyterLab and Chromium)
# share the notebooks, then notebook 11 runs alone (its live view must keep its frame rate, which
# another notebook on the two cores would take from it); screenshots go to build/lab-screenshots/.
LIVE_TEST := test_notebook_runs_all_cells_cleanly_in_jupyterlab and 11_live_receiver
lab-test: $(STAMP) browser
	$(PY) -m pytest -m lab -n $(JOBS) --dist load tests/test_lab_browser.py -k "not ($(LIVE_TEST))"
	$(PY) -m pytest -m lab tests/test_lab_browser.py -k "$(LIVE_TEST)"

# The environment: exact pinned versions with hashes, then wsnlib itself (editable), then a
# named Jupyter kernel inside the venv (--sys-prefix), which papermill finds by name.
# uv (pinned, hashed in installer.lock) installs the lock: it downloads, unpacks and byte-compiles on
# every core (on the 2-core development VM ~30 s, where pip took ~2 min).
$(STAMP): environment.lock installer.lock pyproject.toml
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --require-hashes --no-deps -r installer.lock
	$(VENV)/bin/uv pip install --quiet --python $(PY) --require-hashes --no-deps --compile-bytecode -r environment.lock
	$(PY) -m pip install --quiet --no-deps --no-build-isolation -e .
	$(PY) -m ipykernel install --sys-prefix --name $(KERNEL) --display-name "Python (wsn-motion)"
	touch $(STAMP)

# Regenerate environment.lock from requirements.in (needs uv: `python3 -m pip install uv`).
lock:
	uv pip compile requirements.in --generate-hashes --python-version 3.11 --universal \
		--output-file environment.lock
	echo "uv==$$(uv --version | cut -d' ' -f2)" | uv pip compile - --generate-hashes --python-version 3.11 \
		--universal --output-file installer.lock

clean-outputs:
	rm -rf build figures/*.png figures/*.pdf data/processed/*.csv data/processed/manifest.json data/raw/sim
