# The two commands of a fresh machine (see README.md):
#   make demo   installs everything and runs the main job
#   make test   installs everything and runs the tests
PY ?= python3.11
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: install demo test test-busy lint bench clean fmus sysdeps

$(STAMP): pyproject.toml
	$(PY) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[test]'
	touch $@

# the vehicle FMUs, built from source with cmake and the C compiler (fmu/build.py)
FMU_MANIFEST := fmu/build/SHA256SUMS
$(FMU_MANIFEST): $(STAMP) fmu/build.py fmu/fmu_xml.py fmu/CMakeLists.txt $(wildcard fmu/src/*) $(wildcard fmu/models/*/*)
	$(BIN)/python fmu/build.py

fmus: $(FMU_MANIFEST)

install: $(STAMP) $(FMU_MANIFEST)

demo: install
	$(BIN)/bench accept test_cases/ -o reports --force

# Debian packages the tests use: headless Chromium (the report is opened in it) and
# poppler (the PDF rendered to pages); installed once, with sudo when not root
SYSPKGS := chromium poppler-utils
SUDO := $(shell [ "$$(id -u)" = 0 ] || echo sudo)
sysdeps:
	@command -v chromium >/dev/null && command -v pdftoppm >/dev/null || { \
	  echo "installing the Debian packages the tests use: $(SYSPKGS)"; \
	  $(SUDO) apt-get update -qq && DEBIAN_FRONTEND=noninteractive $(SUDO) apt-get install -y -qq \
	    --no-install-recommends $(SYSPKGS) >/dev/null; }

test: install sysdeps
	$(BIN)/ruff check .
	$(BIN)/lint-imports
	$(BIN)/python -m pytest -n 2

# `make test` on a loaded machine: two busy loops (`yes`) on the cores beside it, stopped
# by their PIDs whatever happens. The suite must pass this way too (no test may depend on
# how fast the machine is); on a quiet 2-core machine it takes about twice as long.
test-busy: install
	@yes >/dev/null & a=$$!; yes >/dev/null & b=$$!; \
	trap 'kill $$a $$b 2>/dev/null' EXIT; trap 'exit 130' INT TERM; \
	echo "make test beside two busy loops (pids $$a $$b)"; \
	$(MAKE) --no-print-directory test

bench: install
	for f in benchmarks/bench_*.py; do $(BIN)/python $$f || exit 1; done

clean:
	rm -rf $(VENV) build *.egg-info fmu/build
