# Two commands for a fresh machine: `make demo` and `make test` (each creates .venv if missing).
PYTHON ?= python3
VENV ?= .venv
BIN := $(VENV)/bin
# DDS stays on this host unless you say otherwise.
export ROS_AUTOMATIC_DISCOVERY_RANGE ?= LOCALHOST
export AMENT_PREFIX_PATH ?= $(abspath $(VENV))

.PHONY: demo test lint bench figures colcon clean

SOURCES := $(shell find ellipath_ros config launch resource -type f -not -path '*/__pycache__/*')

# After installing, numba compiles the planner's kernels (~85 s CPU) into its cache once per
# copy, not in whichever test process calls them first: the installed copy (run from / so that
# the checkout is not on the path), which the CLI and node subprocesses use, and the checkout,
# which pytest imports.
$(BIN)/ellipath: setup.py setup.cfg requirements-dev.txt package.xml $(SOURCES)
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -r requirements-dev.txt
	$(BIN)/python -m pip install --quiet '.[plot,bench,test]'
	cd / && $(abspath $(BIN))/python -c 'from ellipath_ros.core.compiled import warm_up; warm_up()'
	$(BIN)/python -c 'from ellipath_ros.core.compiled import warm_up; warm_up()'
	touch $@

demo: $(BIN)/ellipath
	$(BIN)/ellipath plan --pick 0 0 -0.8 --place 0.3 0 -0.75
	$(BIN)/ellipath demo
	$(BIN)/ellipath plot --pick 0 0 -0.8 --place 0.3 0 -0.75 --out figures

test: $(BIN)/ellipath
	$(BIN)/python -m pytest -q

# The benchmark of README.md's Performance section: about 3 min (`ellipath bench --quick`: 30 s).
bench: $(BIN)/ellipath
	$(BIN)/ellipath bench

# The figures that README.md and docs/paper_reproduction.md embed (the paper's example, off-axis
# so that the three joint curves of Figure 7 differ). Commit them after regenerating.
figures: $(BIN)/ellipath
	$(BIN)/ellipath plot --pick -0.15 0.1 -0.8 --place 0.15 0.1 -0.75 --out docs/figures

colcon: $(BIN)/ellipath
	rm -rf build/colcon
	. $(BIN)/activate && colcon --log-base build/colcon/log build --base-paths . \
	    --build-base build/colcon/build --install-base build/colcon/install
	test -x build/colcon/install/ellipath_ros/lib/ellipath_ros/ellipath_node
	test -f build/colcon/install/ellipath_ros/share/ellipath_ros/config/ellipath.yaml
	test -f build/colcon/install/ellipath_ros/share/ellipath_ros/config/paper.yaml
	test -f build/colcon/install/ellipath_ros/share/ellipath_ros/launch/ellipath.launch.py

clean:
	rm -rf $(VENV) build figures *.egg-info .pytest_cache
