# volbench: two commands on a fresh Debian machine (as root):
#   make reproduce   # set up, run the pipeline on PROFILE (default), print where the report is
#   make test        # set up, run the test suite
SHELL := /bin/bash
PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
PROFILE ?= default
CORES ?= $(shell nproc)
# Mesa EGL + llvmpipe for headless OpenGL; VolPack (library, headers and its brainsmall.den example).
APT_PACKAGES := libegl1 libegl-mesa0 libgl1-mesa-dri libgles2 libgomp1 libvolpack1 libvolpack1-dev
STAMP := $(VENV)/.volbench-installed

.PHONY: setup system-packages reproduce smoke test clean

setup: system-packages $(STAMP)

system-packages:
	@missing=$$(for p in $(APT_PACKAGES); do dpkg -s $$p >/dev/null 2>&1 || echo $$p; done); \
	if [ -n "$$missing" ]; then \
	  echo "volbench: installing Debian packages:" $$missing; \
	  if [ "$$(id -u)" = 0 ]; then SUDO=; else SUDO=sudo; fi; \
	  $$SUDO apt-get update -qq && DEBIAN_FRONTEND=noninteractive $$SUDO apt-get install -y -qq $$missing; \
	fi

$(STAMP): pyproject.toml
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install -q --upgrade pip
	$(PY) -m pip install -q -e '.[test]'
	touch $@

reproduce: setup
	$(VENV)/bin/volbench run --profile $(PROFILE) --cores $(CORES)

smoke:
	$(MAKE) reproduce PROFILE=smoke

test: setup
	$(PY) -m pytest -q -n $(CORES)

clean:
	rm -rf results .snakemake
