# Two commands do everything on a fresh machine (Python >= 3.10, pip, make, gcc):
#   make demo   set up .venv and run the default scenario (log under logs/)
#   make test   set up .venv and run the whole test suite (slow tests included)
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed-stamp
SCENARIO ?= lane-change

.PHONY: demo test test-fast lint clean bytecode install

# The packages go in with uv where pip can install it (one wheel, about 2 s): it fetches and
# unpacks them in parallel, the whole install about 10 s against pip's 29 s (a fresh clone,
# empty caches, the same versions to the letter). Unlike pip, uv writes no bytecode unless
# told (--compile-bytecode): without it every process compiled numpy, casadi, matplotlib ...
# again where PYTHONDONTWRITEBYTECODE is set (their import 0.51 -> 1.12 s, the suite
# 275 -> 316 s). uv reads no pip.conf: where it fails (an index only pip.conf names, say),
# pip installs them as before.
$(STAMP): pyproject.toml
	$(MAKE) --no-print-directory install EXTRAS=dev
	touch $(STAMP)

# `make install EXTRAS=dev,ray`: the project and its extras into .venv (uv, else pip).
EXTRAS ?= dev
# The venv is made without pip (0.1 s against 3.2 s for ensurepip's copy) and uv put in it by
# the system's pip (--python: pip >= 22.3); uv then installs pip too, for `.venv/bin/pip`.
# Where any of that fails, ensurepip gives the venv its pip, which installs as before.
install:
	test -x $(BIN)/python || $(PYTHON) -m venv --without-pip $(VENV)
	((test -x $(BIN)/uv || $(PYTHON) -m pip --python $(BIN)/python install --quiet uv) \
	    && $(BIN)/uv pip install --quiet --compile-bytecode --python $(BIN)/python \
	        -e '.[$(EXTRAS)]' pip) \
	|| ($(BIN)/python -m ensurepip --upgrade \
	    && $(BIN)/python -m pip install --quiet --upgrade pip \
	    && $(BIN)/python -m pip install --quiet -e '.[$(EXTRAS)]')

# The project's own modules compiled to bytecode once: every process a test or a user
# starts then loads them instead of compiling some 38,000 lines again (0.15 s a process),
# also where PYTHONDONTWRITEBYTECODE stops Python from writing them itself (compileall
# writes them regardless; a module edited since is compiled afresh in memory, as always).
bytecode: $(STAMP)
	$(BIN)/python -m compileall -q cosim estimation tracker

demo: bytecode
	MUJOCO_GL=$${MUJOCO_GL:-disable} $(BIN)/cosim run $(SCENARIO)

# The suite runs on every core (pytest-xdist); TEST_WORKERS=0 runs it in one process.
# Idle workers take tests from busy ones (--dist worksteal): the tests range from
# milliseconds to twenty seconds, and handing them out in fixed batches left one core idle
# at the end while the other finished the long ones (the suite 305-313 s against 284-296 s
# on 2 cores, one tree, back to back). And each worker's share starts with the modules
# that hold slow tests (tests/conftest.py, balanced_order): in collection order a 20-s test
# could start last while the other core had nothing left (the suite 283 -> 277 s).
# One OpenBLAS thread per process (cosim.cli.common.single_threaded_blas: the threads it
# starts with numpy only busy-wait, on the core the other worker needs).
TEST_WORKERS ?= auto
PYTEST := OPENBLAS_NUM_THREADS=$${OPENBLAS_NUM_THREADS:-1} $(BIN)/python -m pytest \
	-n $(TEST_WORKERS) --dist worksteal

test: bytecode
	MUJOCO_GL=$${MUJOCO_GL:-disable} $(PYTEST)

test-fast: bytecode
	MUJOCO_GL=$${MUJOCO_GL:-disable} $(PYTEST) -m "not slow"

lint: $(STAMP)
	$(BIN)/ruff check .

clean:
	rm -rf $(VENV) build dist *.egg-info .pytest_cache
