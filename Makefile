# leadscrew_sim: fresh-machine set-up, run and test (no ROS installation needed).
#   make setup   create .venv from pinned PyPI wheels and install the package
#   make run     start the node with the default preset and a demo command source
#   make test    run the whole test suite
SHELL := /bin/bash
PYTHON ?= $(shell command -v python3.11 || command -v python3)
VENV := $(CURDIR)/.venv
VPY := $(VENV)/bin/python
STAMP := $(VENV)/.leadscrew_sim_setup
# The executables live in .venv/lib/leadscrew_sim (for ros2 run); links in .venv/bin
# put them on the PATH of `source .venv/bin/activate`.
LINKS := $(VENV)/bin/leadscrew_sim $(VENV)/bin/leadscrew_sim_node
# numba's cache is the package's own (~/.cache/leadscrew_sim/numba, or $NUMBA_CACHE_DIR when
# set), the same for make, the venv's commands and ros2 run.
ENV := AMENT_PREFIX_PATH=$(VENV) ROS_LOG_DIR=$(CURDIR)/.ros_log
PRESET ?= default
DURATION ?= 0

.PHONY: setup run test bench clean

setup: $(STAMP) $(LINKS)

$(STAMP): requirements.txt constraints.txt setup.py setup.cfg package.xml
	@echo "setup 1/4: the virtual environment $(VENV)"
	@test -x $(VPY) || $(PYTHON) -m venv $(VENV)
	@$(VPY) -m pip install --quiet --disable-pip-version-check --upgrade pip==24.3.1
	@echo "setup 2/4: the pinned wheels from PyPI (rclpy, numpy, scipy, numba, mcap, dask, ...; about a minute)"
	@set -o pipefail; $(VPY) -m pip install --disable-pip-version-check --progress-bar off \
		-r requirements.txt -c constraints.txt 2>&1 \
		| awk '/^(Collecting|Successfully installed|ERROR)/ { print "  " $$0; fflush() }'
	@echo "setup 3/4: leadscrew_sim into the environment"
	@$(VPY) -m pip install --quiet --disable-pip-version-check --no-deps --no-build-isolation -e .
	@echo "setup 4/4: the compiled kernel (compiled once into numba's cache, about 30 s; then loaded)"
	@$(ENV) $(VPY) -c "from leadscrew_sim.core.warmup import kernel_ready; kernel_ready(lambda t: print('  ' + t))"
	@touch $(STAMP)
	@echo "setup done: $(VENV)"

$(LINKS): | $(STAMP)
	ln -sfn ../lib/leadscrew_sim/$(notdir $@) $@

run: setup
	$(ENV) $(VPY) -m leadscrew_sim.cli.demo --preset $(PRESET) --duration $(DURATION)

# The suite in two parts: the tests that start no ROS node, server or browser and bound no
# wall time in two worker processes (pytest-xdist, a file per worker at a time), then those
# marked `alone` by themselves (test/conftest.py). The recording's compiled fill is cached
# first, so that the two workers never compile it at once. OpenBLAS keeps its thread count:
# identify's fits follow the last bits of its sums, which the thread count changes.
test: setup
	@mkdir -p .ros_log
	@$(ENV) $(VENV)/bin/leadscrew_sim simulate --duration 0.05 -q -o .ros_log/warmup.mcap
	$(ENV) $(VPY) -m pytest -p no:cacheprovider -n 2 --dist loadfile -m "not alone" test
	$(ENV) $(VPY) -m pytest -p no:cacheprovider -m alone test

bench: setup
	$(ENV) $(VPY) bench/bench_model.py

clean:
	rm -rf $(VENV) build install .ros_log runs *.egg-info
