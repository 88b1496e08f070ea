# One entry point for every task. `make test` and `make demo` do all set-up themselves.
SHELL := /bin/bash
.SHELLFLAGS := -eo pipefail -c
.DEFAULT_GOAL := help

VENV       ?= .venv
MODE       := $(shell tools/detect_mode.sh)
VENV_STAMP := $(VENV)/.slip-stamp-$(MODE)
BUILD_STAMP := install/.slip-build-stamp
RUN        := tools/run_ros.sh
PY         := $(VENV)/bin/python
# Files that change what colcon installs (Python sources are symlinked, so edits need no build).
BUILD_INPUTS := $(shell find src -type f \( -name package.xml -o -name setup.py -o -name setup.cfg \
	-o -name CMakeLists.txt -o -name '*.msg' -o -name '*.srv' -o -name '*.action' \
	-o -path '*/resource/*' -o -path '*/config/*' -o -path '*/launch/*' \) \
	-not -path '*/__pycache__/*' 2>/dev/null)
# friction_models' simulation core is compiled with mypyc (setup.py; list = core.native.COMPILED_MODULES).
NATIVE_SOURCES := $(addprefix src/friction_models/friction_models/core/,native.py \
	limit_surface.py reduced.py pad_contact.py actuator.py arm.py table.py plant.py sensors.py \
	sim_cell.py)
PYTEST_ARGS ?=
DEMO_ARGS ?=

.PHONY: help setup test lint demo bench bags clean lock

help:
	@echo "make setup   venv ($(MODE) mode) + colcon build (idempotent)"
	@echo "make test    all tests (runs setup when needed)"
	@echo "make lint    ruff and mypy over every package (runs setup when needed)"
	@echo "make demo    the main job: the simulated cell runs a full slip experiment"
	@echo "make bench   benchmarks (print tables)"
	@echo "make bags    regenerate the recorded experiments in bags/"
	@echo "make clean   remove build/, install/, log/ and the venv"

setup: $(BUILD_STAMP)

$(VENV_STAMP): requirements-ros.txt requirements.txt requirements-system.txt constraints.txt \
		tools/bootstrap_venv.sh tools/write_venv_underlay.sh
	@start=$$(date +%s); tools/bootstrap_venv.sh $(VENV) $(MODE); \
	  rm -f $(VENV)/.slip-stamp-*; touch $@; \
	  echo "setup: venv ready in $$(( $$(date +%s) - start )) s"

$(BUILD_STAMP): $(VENV_STAMP) $(BUILD_INPUTS) $(NATIVE_SOURCES) tools/colcon_build.sh
	@start=$$(date +%s); tools/colcon_build.sh $(VENV) $(MODE); touch $@; \
	  echo "setup: workspace built in $$(( $$(date +%s) - start )) s"

test: setup
	@$(RUN) $(PY) -m pytest $(PYTEST_ARGS)

# Lint: ruff (ruff.toml) over the tree, mypy (mypy.ini) over every Python package.
LINT_PACKAGES := slip_cell_common slip_gripper_driver slip_velocity_sensor friction_models \
	slip_control slip_bringup
lint: setup
	@$(VENV)/bin/ruff check .
	@$(RUN) $(PY) -m mypy $(addprefix -p ,$(LINT_PACKAGES))

demo: setup
	@$(RUN) $(PY) -m slip_bringup.demo $(DEMO_ARGS)

bench: setup
	@for b in bench/bench_*.py; do echo "=== $$b"; $(RUN) $(PY) $$b --quick; done

bags: setup
	@$(RUN) $(PY) -m slip_bringup.make_bags --output bags

lock: $(VENV_STAMP)
	@tools/lock.sh $(VENV) > constraints.txt

clean:
	rm -rf build install log $(VENV) $(VENV).pip.log .pytest_cache
	rm -f src/friction_models/friction_models/core/*.so src/friction_models/friction_models/core/native_sources.json
