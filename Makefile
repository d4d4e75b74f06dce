# leadscrew_sim: fresh-machine set-up, run and test (no ROS installation needed).
#   make setup   create .venv from pinned PyPI wheels and install the package
#   make run     start the node with the default preset and a demo command source
#   make test    run the whole test suite
SHELL := /bin/bash
PYTHON ?= $(shell command -v python3.11 || command -v python3)
VENV := $(CURDIR)/.venv
VPY := $(VENV)/bin/python
STAMP := $(VENV)/.leadscrew_sim_setup
ENV := AMENT_PREFIX_PATH=$(VENV) NUMBA_CACHE_DIR=$(VENV)/numba_cache ROS_LOG_DIR=$(CURDIR)/.ros_log
PRESET ?= default
DURATION ?= 0

.PHONY: setup run test bench clean

setup: $(STAMP)

$(STAMP): requirements.txt constraints.txt setup.py setup.cfg package.xml
	@test -x $(VPY) || $(PYTHON) -m venv $(VENV)
	$(VPY) -m pip install --quiet --disable-pip-version-check --upgrade pip==24.3.1
	$(VPY) -m pip install --quiet --disable-pip-version-check -r requirements.txt -c constraints.txt
	$(VPY) -m pip install --quiet --disable-pip-version-check --no-deps --no-build-isolation -e .
	@touch $(STAMP)
	@echo "setup done: $(VENV)"

run: setup
	$(ENV) $(VPY) -m leadscrew_sim.ros.demo --preset $(PRESET) --duration $(DURATION)

test: setup
	$(ENV) $(VPY) -m pytest -p no:cacheprovider test

bench: setup
	$(ENV) $(VPY) bench/bench_model.py

clean:
	rm -rf $(VENV) build install .ros_log runs *.egg-info
