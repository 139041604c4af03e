# Two commands on a fresh machine: `make run` (set-up + main job) and `make test` (set-up + linters + docs + tests).
# Set-up installs the exact versions pinned in constraints.txt (see docs/development.md, "Dependencies and linters").
PY ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
LOCK := constraints.txt

.PHONY: run test lint docs system-deps test-slow bench serve lock clean

# uv installs the same pinned versions as pip in a quarter of the time (19 s against 82 s with empty caches on
# 2026-11-29); should uv fail (its own index or TLS settings, not pip's), pip installs them as before. Both
# compile the packages' bytecode at install time (uv only when asked): a process that may not write it
# (PYTHONDONTWRITEBYTECODE) would otherwise compile every module it imports, every time it starts.
$(STAMP): pyproject.toml $(LOCK)
	$(PY) -m venv $(VENV)
	$(BIN)/pip install --quiet -c $(LOCK) --upgrade pip uv
	$(BIN)/uv pip install --quiet --compile-bytecode --python $(BIN)/python -c $(LOCK) -e ".[test]" \
	  || { echo "uv failed: installing with pip" >&2; $(BIN)/pip install --quiet -c $(LOCK) -e ".[test]"; }
	touch $(STAMP)

run: $(STAMP)
	$(BIN)/backlash run

lint: $(STAMP)
	$(BIN)/ruff check .
	$(BIN)/ruff format --check .
	$(BIN)/mypy

# The documentation site (mkdocs.yml, docs/): every generated figure up to date, then a strict build
# (warnings are errors) into out/site. Open out/site/index.html, or `$(BIN)/mkdocs serve` while writing.
docs: $(STAMP)
	$(BIN)/python docs/gen.py --check
	NO_MKDOCS_2_WARNING=1 $(BIN)/mkdocs build --strict --quiet

# Docker engine, debootstrap and chromium for the system-level tests, when root on Debian (never fails)
system-deps:
	sh .ci/system-deps.sh

# the default suite on $(TEST_WORKERS) workers (pytest-xdist), then alone the tests that measure a
# latency or a timing (marked serial), which the other worker's load would make flaky
TEST_WORKERS ?= 2
# numba threads (kernels and candidate fits) per test worker during the parallel part: the workers already fill
# the cores, and more threads than cores made OpenMP's threads wait for each other (docs/development.md)
TEST_THREADS ?= 1
# the tests' processes write the bytecode of the project's modules and pytest's rewritten test modules to
# __pycache__ (ignored by git) even where the environment says not to: otherwise each of the run's many processes
# (test workers, services, their spawned workers, CLI calls) compiles them again
test test-slow: export PYTHONDONTWRITEBYTECODE =

# numba compiles the simulation kernels once (python -m engine.warm_up: about 20 s of one core from a fresh
# clone, 3 min before 2c80424), beside the linters, the docs build and the system set-up, which leave the other core idle; the test
# workers then load them from the cache instead of each compiling them (docs/development.md)
WARM_LOG := out/warm-up.log

test: $(STAMP)
	@mkdir -p out
	@$(BIN)/python -m engine.warm_up > $(WARM_LOG) 2>&1 & warm=$$!; \
	$(MAKE) --no-print-directory lint docs system-deps; status=$$?; \
	if wait $$warm; then cat $(WARM_LOG); else echo "compiling the kernels failed:" >&2; cat $(WARM_LOG) >&2; status=1; fi; \
	exit $$status
	NUMBA_NUM_THREADS=$(TEST_THREADS) $(BIN)/python -m pytest -q -n $(TEST_WORKERS) --dist worksteal -m "not slow and not serial"
	$(BIN)/python -m pytest -q -m "serial and not slow"

test-slow: $(STAMP)
	NUMBA_NUM_THREADS=$(TEST_THREADS) $(BIN)/python -m pytest -q -n $(TEST_WORKERS) --dist worksteal -m slow

bench: $(STAMP)
	$(BIN)/backlash bench

serve: $(STAMP)
	$(BIN)/backlash serve

# Re-resolve every dependency to its newest allowed release and pin the result in constraints.txt.
# Run it on purpose (then `make test`), never from CI.
lock:
	rm -rf .lock-venv
	$(PY) -m venv .lock-venv
	.lock-venv/bin/pip install --quiet --upgrade pip uv
	.lock-venv/bin/pip install --quiet ".[test]"
	{ echo "# Resolved dependency versions for CI and set-up; regenerate with 'make lock' (docs/development.md, Dependencies)."; \
	  .lock-venv/bin/pip freeze --all --exclude-editable | grep -v -i -E '^(backlash|setuptools|wheel)( @|==)' | LC_ALL=C sort -f; } > $(LOCK)
	rm -rf .lock-venv build *.egg-info

clean:
	rm -rf $(VENV) out
