# fabric_fenicsx: set-up and entry points.
#
#   make test    install what is missing, then run the test suite
#   make demo    install what is missing, then run the demo ($(DEMO_CMD))
#   make bench   install what is missing, then run every benchmarks/*.py
#
# Works on a fresh Debian 12 machine as root (or as a user with sudo). Each step is
# skipped when already done: apt only runs when a package is missing, the venv is made
# once, pip only runs again when pyproject.toml or constraints.txt changed.

SHELL := /bin/bash
.DEFAULT_GOAL := help

# DOLFINx 0.5.2, gmsh 4.8.4, mpi4py, petsc4py, numpy 1.24.2, scipy 1.10.1 and matplotlib 3.6.3
# come from Debian. libegl1 lets VTK (pyvista) render off-screen without an X server.
APT_PACKAGES ?= python3-dolfinx python3-gmsh python3-venv python3-matplotlib libegl1

SYSTEM_PYTHON ?= /usr/bin/python3
VENV ?= .venv
PY := $(VENV)/bin/python
PIP := $(PY) -m pip
STAMP := $(VENV)/.fabric_fenicsx-installed
PIP_FLAGS ?= --progress-bar off

# The demo: Y90 at 57.3 m/s on a coarse mesh (4 mm at the impact point instead of the scene's
# 1.41 mm) so that it finishes in minutes from a fresh clone (under 1.5 min with the Debian
# packages installed: its table tiles ship with the package and `make setup` compiles numba's
# kernels beside pip; about 15 s of run, docs/demo.md); docs/mesh_independence.md says what the
# mesh changes.
DEMO_CMD ?= $(VENV)/bin/fabric-fenicsx impact demos/scenes/y90.toml --out out/impact-y90 --set projectile.velocity=57.3 --set mesh.h_centre=0.004
PYTEST_ARGS ?= -q tests

SUDO := $(shell [ "$$(id -u)" = 0 ] || echo sudo)

export DEBIAN_FRONTEND := noninteractive
# OpenMPI refuses to start as root without these; oversubscribe lets `mpirun -n 2` run on one core.
export OMPI_ALLOW_RUN_AS_ROOT := 1
export OMPI_ALLOW_RUN_AS_ROOT_CONFIRM := 1
export OMPI_MCA_rmaps_base_oversubscribe := 1
# Batch runs never open a window: render with EGL straight away (no "bad X server" warning).
export PYVISTA_OFF_SCREEN ?= true
export VTK_DEFAULT_OPENGL_WINDOW ?= vtkEGLRenderWindow

.PHONY: help setup apt test demo bench clean distclean

help:
	@echo "make demo       run the demo: $(DEMO_CMD)"
	@echo "make test       run the tests: $(PY) -m pytest $(PYTEST_ARGS)"
	@echo "make bench      run benchmarks/*.py"
	@echo "make setup      only install (apt packages, $(VENV), the package)"
	@echo "make clean      remove out/, caches and build files (keeps $(VENV))"
	@echo "make distclean  clean, and remove $(VENV)"

setup: $(STAMP)

# Always checked (dpkg-query is fast); apt-get update + install only for missing packages.
apt:
	@missing=""; \
	for p in $(APT_PACKAGES); do \
	  dpkg-query -W -f='$${Status}' "$$p" 2>/dev/null | grep -q "install ok installed" || missing="$$missing $$p"; \
	done; \
	if [ -n "$$missing" ]; then \
	  echo "apt: installing$$missing"; \
	  $(SUDO) apt-get update -q && \
	  $(SUDO) env DEBIAN_FRONTEND=noninteractive apt-get install -y -q$$missing; \
	fi

$(PY): | apt
	$(SYSTEM_PYTHON) -m venv --system-site-packages $(VENV)

# numba first, then the package with the test extra, and the cluster extra (dask.distributed)
# so that the tests of studies on a cluster run too. While pip installs the rest, a short run of
# the demo's scene compiles numba's kernels into their on-disk cache on the other core
# (fabric_fenicsx.impact.warm: it needs only numba and Debian's packages), so that the
# first run does not compile them (about 25 s); WARM=0 skips it. It ends before setup does; a
# failed warm-up only means the first run compiles them itself.
WARM ?= 1
$(STAMP): pyproject.toml constraints.txt | $(PY) apt
	$(PIP) install $(PIP_FLAGS) -c constraints.txt numba llvmlite
	@warm=""; log=$$(mktemp); \
	if [ "$(WARM)" = 1 ]; then \
	  echo "numba warm-up: compiling the kernels in the background"; \
	  PYTHONPATH="$(CURDIR)$${PYTHONPATH:+:$$PYTHONPATH}" timeout 300 $(PY) -m fabric_fenicsx.impact.warm > $$log 2>&1 & warm=$$!; \
	fi; \
	echo "$(PIP) install $(PIP_FLAGS) -c constraints.txt -e '.[test,cluster]'"; \
	$(PIP) install $(PIP_FLAGS) -c constraints.txt -e '.[test,cluster]'; rc=$$?; \
	if [ -n "$$warm" ]; then \
	  wait $$warm || echo "numba warm-up: stopped (exit $$?); the first run compiles the kernels"; \
	  if [ -n "$$(tail -n 1 $$log)" ]; then tail -n 1 $$log; fi; \
	fi; \
	rm -f $$log; exit $$rc
	$(PY) -c "import dolfinx, pyvista, numpy, scipy, distributed; \
	  assert numpy.__version__ == '1.24.2', f'numpy {numpy.__version__} in $(VENV), expected 1.24.2 (constraints.txt)'; \
	  print('dolfinx', dolfinx.__version__, '| pyvista', pyvista.__version__, '| numpy', numpy.__version__, '| scipy', scipy.__version__, '| distributed', distributed.__version__)"
	touch $@

test: $(STAMP)
	@$(PY) -m pytest $(PYTEST_ARGS); rc=$$?; \
	if [ $$rc -eq 5 ]; then echo "make test: pytest collected no tests" >&2; fi; \
	exit $$rc

demo: $(STAMP)
	$(DEMO_CMD)

bench: $(STAMP)
	@shopt -s nullglob; scripts=(benchmarks/*.py); \
	if [ $${#scripts[@]} -eq 0 ]; then echo "make bench: no benchmarks/*.py"; exit 0; fi; \
	for f in "$${scripts[@]}"; do echo "== $$f"; $(PY) "$$f" || exit $$?; done

clean:
	rm -rf out .pytest_cache build dist *.egg-info
	find . -path ./$(VENV) -prune -o -name __pycache__ -type d -exec rm -rf {} +

distclean: clean
	rm -rf $(VENV)
