# The two commands of README.md: `make demo` and `make test`; both set up .venv/ first when needed.
PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.setup-done

CHROMIUM := /usr/bin/chromium

.PHONY: setup demo test bench clean browser

setup: $(STAMP)

$(STAMP): setup.py package.xml requirements.txt
	$(PYTHON) -c 'import sys; assert sys.version_info >= (3, 11), "Python 3.11+ needed"'
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -r requirements.txt
	$(PY) -m pip install --quiet --no-deps -e .
	touch $(STAMP)

demo: setup
	$(VENV)/bin/demo

# test/test_rigday.py renders the HTML report in Debian's chromium: installed here when missing and
# we are root (CI on a fresh machine); otherwise a note, and that test fails saying what is missing.
browser:
	@if [ -x $(CHROMIUM) ]; then :; \
	elif [ "$$(id -u)" = 0 ]; then \
	  echo "installing chromium (Debian package) for the report test"; \
	  { DEBIAN_FRONTEND=noninteractive apt-get update -qq && \
	    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq chromium >/dev/null; } || \
	  echo "note: installing chromium failed: test/test_rigday.py will fail"; \
	else \
	  echo "note: $(CHROMIUM) is missing and this is not root: install it (sudo apt-get install chromium)," \
	       "else test/test_rigday.py fails"; \
	fi

# one BLAS thread per process: the tests run in this process and the heavy simulations of some
# modules in one background worker on the second core (test/conftest.py; RIG_TEST_WORKERS=N sets how many, 0: none)
# lint (ruff.toml: import order, unused names, lines ≤ 120, function size) and types (setup.cfg [mypy]: the whole
# package, strict on io/, model/ and estimation/), then the tests
test: setup browser
	$(VENV)/bin/ruff check rig_identification test bench
	$(VENV)/bin/mypy rig_identification
	OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 $(PY) -m pytest -q test

bench: setup
	for b in bench/*.py; do $(PY) $$b || exit 1; done

clean:
	rm -rf $(VENV) build install log *.egg-info
