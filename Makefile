# volbench: two commands on a fresh Debian machine (as root):
#   make reproduce   # set up, run the pipeline on PROFILE (default), print where the report is
#   make test        # set up, run the unit tests (all but the `integration` and `cluster` tests)
# and
#   make integration-test  # the tests that run Snakemake, a whole workflow or a browser (CI runs them)
#   make cluster-test  # the smoke profile on a one-node SLURM started here and, side by side, the
#                      # local smoke run brought up to date (results/smoke); then the two compared
SHELL := /bin/bash
PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
PROFILE ?= default
CORES ?= $(shell nproc)
# Mesa EGL + llvmpipe for headless OpenGL; VolPack (library, headers and its brainsmall.den example);
# Debian's PoCL, the OpenCL CPU device. It builds kernels on any x86-64 CPU: it ships kernel
# libraries for sse2 up to avx512 and picks one by the CPU's feature flags, giving LLVM that
# library's CPU name, so a CPU newer than its LLVM still gets one. PyPI's PoCL (pyproject.toml)
# gives LLVM the host CPU's name instead, which a CPU newer than LLVM 14 lacks ('generic',
# rejected: every kernel build fails). pyopencl lists both; renderers/cl/context.py takes the
# first device that builds a kernel.
APT_PACKAGES := libegl1 libegl-mesa0 libgl1-mesa-dri libgles2 libgomp1 libvolpack1 libvolpack1-dev pocl-opencl-icd
# The one-node SLURM of the cluster tests (scripts/slurm-single-node): controller, node daemon,
# client commands (sbatch, srun, squeue, scontrol) and munge for their authentication.
CLUSTER_PACKAGES := slurmctld slurmd slurm-client munge
# The headless browser of tests/test_report_browser.py (it skips without one).
BROWSER_PACKAGES := chromium
# The local smoke run the cluster test brings up to date and compares with.
CLUSTER_BASELINE ?= results/smoke
STAMP := $(VENV)/.volbench-installed

.PHONY: setup system-packages cluster-packages browser-packages reproduce smoke test integration-test cluster-test clean

setup: system-packages $(STAMP)
	@# Every job and test process imports the project: its bytecode once here (pipeline.cli).
	@$(PY) -c 'from pipeline.launch import compile_packages; compile_packages()'

# apt-get install the packages of $(1) that are missing; waiting for another apt or dpkg to finish
# (CI installs some packages while pip runs; a machine may be upgrading itself) rather than failing.
APT_WAIT := -o DPkg::Lock::Timeout=600
define install_missing
	@missing=$$(for p in $(1); do dpkg-query -W -f='$${Status}' $$p 2>/dev/null | grep -q 'ok installed' || echo $$p; done); \
	if [ -n "$$missing" ]; then \
	  echo "volbench: installing Debian packages:" $$missing; \
	  if [ "$$(id -u)" = 0 ]; then SUDO=; else SUDO=sudo; fi; \
	  $$SUDO apt-get $(APT_WAIT) update -qq && DEBIAN_FRONTEND=noninteractive $$SUDO apt-get $(APT_WAIT) install -y -qq $$missing; \
	fi
endef

system-packages:
	$(call install_missing,$(APT_PACKAGES))

cluster-packages:
	$(call install_missing,$(CLUSTER_PACKAGES))

browser-packages:
	$(call install_missing,$(BROWSER_PACKAGES))

$(STAMP): pyproject.toml
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install -q --upgrade pip
	$(PY) -m pip install -q -e '.[test]'
	touch $@

reproduce: setup
	$(VENV)/bin/volbench run --profile $(PROFILE) --cores $(CORES)

smoke:
	$(MAKE) reproduce PROFILE=smoke

# --dist loadfile: a module's tests share a worker, so the Numba kernels they use are compiled
# once, not in every worker (a fresh clone: 214 s instead of 245 s on 2 cores; warm 148 s, not 159).
# The unit tests; the tests that run Snakemake on copies of the workflow, a workflow of their own or a
# browser are `integration` tests, which CI runs as a stage of their own (.ci/run).
test: setup
	$(PY) -m pytest -q -n $(CORES) --dist loadfile -m "not cluster and not integration"

integration-test: setup
	$(PY) -m pytest -q -n $(CORES) --dist loadfile -m "integration and not cluster"

# Starts (and stops) the one-node SLURM itself; needs root. VOLBENCH_REQUIRE_CLUSTER=1 turns its
# skips (no root, SLURM will not start) into failures, as CI wants.
cluster-test: setup cluster-packages
	VOLBENCH_CLUSTER_BASELINE=$(CLUSTER_BASELINE) $(PY) -m pytest -q -s -p no:cacheprovider -m cluster tests/test_cluster.py

clean:
	rm -rf results .snakemake
