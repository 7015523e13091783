# The two commands a newcomer needs: `make run` and `make test`.
PYTHON ?= $(shell command -v python3.11 2>/dev/null || echo python3.11)
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
# The JavaScript clients the tests drive (roslibjs, Foxglove's ws-protocol), from the lock file
JS := tests/js
JS_STAMP := $(JS)/node_modules/.installed

.PHONY: install run test lint bench docs clean

# The ROS interface packages PyPI lacks (interfaces/) are built into the venv; a no-op when
# nothing changed, and only the changed package is rebuilt (tools/build_interfaces.py). Then
# the RMW gate for foreign programs and the C test programs (tools/build_native.py).
install: $(STAMP) $(JS_STAMP)
	@$(BIN)/python tools/build_interfaces.py
	@$(BIN)/python tools/build_native.py

$(STAMP): pyproject.toml
	@test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	@$(BIN)/python -c 'import sys; assert sys.version_info[:2] in ((3, 11), (3, 12)), "cosim needs Python 3.11 or 3.12 in .venv, found " + sys.version'
	@# uv installs the wheels side by side: the same versions pip picks, in a quarter of the time
	$(BIN)/python -m pip install --quiet --disable-pip-version-check 'uv>=0.5,<1'
	$(BIN)/uv pip install --quiet --python $(BIN)/python -e '.[dev]'
	@touch $(STAMP)

$(JS_STAMP): $(JS)/package.json $(JS)/package-lock.json
	cd $(JS) && npm ci --no-audit --no-fund --loglevel=error
	@touch $(JS_STAMP)

run: install
	$(BIN)/cosim-orchestrate scenarios/nav.yaml

# Test files run side by side, one pytest-xdist worker per core up to 4 (TEST_WORKERS=0: one at
# a time, in pytest's own process): most of a test waits on processes starting and discovering
# each other; more workers would mostly add DDS discovery traffic and load (some tests load
# every core on purpose). Then the tests marked `alone` (realtime, on wall time), one at a time.
# Every test's time is kept in build/test-times*.xml (tools/slowest_tests.py reads them).
TEST_WORKERS ?= $(shell n=$$(nproc 2>/dev/null || echo 2); [ "$$n" -gt 4 ] && n=4; echo $$n)
test: install
	$(BIN)/ruff check .
	$(BIN)/python -m pytest -n $(TEST_WORKERS) --dist loadfile -m "not alone" \
		--junitxml=build/test-times.xml
	$(BIN)/python -m pytest -m alone --junitxml=build/test-times-alone.xml

# The documentation site into build/site (open build/site/index.html); --strict: a dead link or
# a page missing from the nav fails the build. The reference pages are generated from the code.
docs: install
	$(BIN)/python tools/gen_reference.py
	NO_MKDOCS_2_WARNING=1 $(BIN)/python -m mkdocs build --strict

bench: install
	$(BIN)/python -u -m bench

clean:
	rm -rf $(VENV) runs .pytest_cache $(JS)/node_modules
