# Quick start:  make demo   |   make test
PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed
DOCS_STAMP := $(VENV)/.docs-installed

.PHONY: demo test test-all docs generated closed-forms bench lint clean

# pip as the venv brings it unless it is too old for an editable install from pyproject.toml
# (PEP 660: pip 21.3); the dependencies installed without bytecode, which is then written on
# both cores and not for their own test suites (sympy/**/tests, pandas/tests, ...: a third of
# their source, never imported here): measured 70 -> 48 s CPU for the whole setup.  The
# bytecode is written at all because the tests' processes may be told to write none
# (PYTHONDONTWRITEBYTECODE) and would then compile what they import, each time.
$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet 'pip>=21.3'
	$(PY) -m pip install --quiet --no-compile -e '.[test]'
	$(PY) -m compileall -q -j 0 -x '/tests?/' $$($(PY) -c 'import sysconfig; print(sysconfig.get_path("purelib"))')
	$(PY) -m symgroupoid cache templates || echo 'kernel templates not precompiled: each process compiles them once'
	touch $(STAMP)

$(DOCS_STAMP): $(STAMP)
	$(PY) -m pip install --quiet -e '.[test,docs]'
	touch $(DOCS_STAMP)

demo: $(STAMP)
	$(PY) -m symgroupoid demo

# the tests on every core (pytest-xdist), a test file per worker at a time (their shared
# systems are derived once per worker), the files in collection order: the longest first
# (tests/conftest.py, LONG_FIRST), not xdist's order by number of tests
XDIST := -n auto --dist loadfile --no-loadscope-reorder

# the package's bytecode is written first: the tests' many child processes (command line,
# cache and sweep tests, the examples, the docs script) then import it compiled, also where
# Python is told to write none (PYTHONDONTWRITEBYTECODE); measured: a fifth of the CPU time
# of tests/test_cache.py
BYTECODE := $(PY) -m compileall -q symgroupoid

test: $(STAMP)
	$(BYTECODE)
	$(PY) -m pytest -q -m "not slow" $(XDIST)

test-all: $(STAMP) $(DOCS_STAMP)
	$(BYTECODE)
	$(PY) -m pytest -q $(XDIST)

# the API reference from the docstrings (Sphinx, warnings are errors): build/docs/index.html
docs: $(DOCS_STAMP)
	$(PY) -m sphinx -W --keep-going -q -b html docs/api build/docs
	@echo "API reference: build/docs/index.html"

generated: $(STAMP)
	$(PY) -m symgroupoid generate generated

# the stored templates of the matrix groups (after a change of their maps or of SymPy)
closed-forms: $(STAMP)
	$(PY) -m symgroupoid.groupoids._closed_forms_build

bench: $(STAMP)
	$(PY) benchmarks/derive.py

lint: $(STAMP)
	$(PY) -m pip install --quiet ruff
	$(VENV)/bin/ruff check symgroupoid tests examples benchmarks

clean:
	rm -rf $(VENV) build *.egg-info .pytest_cache
