# Two commands a newcomer needs: `make demo` and `make test`.
PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
PIP    := $(PY) -m pip -q --disable-pip-version-check
RUNS   ?= 100
SEED   ?= 1
OUT    ?= results/seed000

.PHONY: demo test test-all lint bench clean browser

$(VENV)/.installed: pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PIP) install --upgrade pip
	$(PIP) install -e '.[test]'
	touch $@

demo: $(VENV)/.installed
	$(VENV)/bin/ftnav run seed000 --runs $(RUNS) --seed $(SEED) --out $(OUT)
	@echo "Results are in $(OUT)/ (report.html, metrics.json, figures *.png, report.md)"

# Debian's chromium for the report.html test (tests/cli/test_html_report.py); where it
# cannot be installed (no root, no apt) the test is skipped and says why
browser:
	@command -v chromium >/dev/null 2>&1 || { [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null \
	  && (apt-get install -y -q chromium >/dev/null 2>&1 || \
	      (apt-get update -q >/dev/null 2>&1 && apt-get install -y -q chromium >/dev/null 2>&1)) \
	  || echo "make: chromium not installed: the report.html browser test will be skipped"; }

test: $(VENV)/.installed browser
	$(VENV)/bin/ruff check src tests benchmarks
	$(VENV)/bin/ruff format --check src tests benchmarks
	$(PY) -m mypy
	$(PY) -m pytest -n 2 -m "not slow"

# every test, the slow oracles included (tests/conftest.py SLOW): about 30 min on 2 cores
test-all: $(VENV)/.installed
	$(PY) -m pytest -n 2

lint: $(VENV)/.installed
	$(VENV)/bin/ruff check src tests benchmarks
	$(VENV)/bin/ruff format --check src tests benchmarks
	$(PY) -m mypy

bench: $(VENV)/.installed
	$(PY) benchmarks/bench_federated.py
	$(PY) benchmarks/bench_mechanization.py
	$(PY) benchmarks/bench_learned.py
	$(PY) benchmarks/bench_integrated.py

clean:
	rm -rf $(VENV) results build *.egg-info src/*.egg-info
