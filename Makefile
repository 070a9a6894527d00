# Front door. Every target sets up what it needs in .venv/, idempotently.
SHELL := /bin/bash
PYTHON ?= $(shell command -v python3.11 || command -v python3)
VENV := .venv
VENV_ABS := $(abspath $(VENV))
PY := $(VENV)/bin/python
STAMP := $(VENV)/.cdpr-setup
PACKAGES := cdpr_msgs_py cdpr_control cdpr_twin cdpr_fdi cdpr_bringup
PACKAGE_FILES := $(foreach p,$(PACKAGES),src/$(p)/setup.py src/$(p)/setup.cfg src/$(p)/package.xml)
# The modules whose per-tick functions are compiled (cdpr_control/kernels.py)
KERNEL_MODULES := cdpr_twin.models.elastic_substeps cdpr_control.platform.substeps cdpr_control.point_mass.substeps \
	cdpr_control.tension_distribution.active_set \
	cdpr_control.control.tracking cdpr_fdi.detection.tick_arithmetic

# What rclpy needs in a venv. The DDS set-up (loopback only, no shared memory) is applied
# by the launchers and the test session themselves (cdpr_msgs_py/dds.py).
export AMENT_PREFIX_PATH := $(VENV_ABS)$(if $(AMENT_PREFIX_PATH),:$(AMENT_PREFIX_PATH))
export RMW_IMPLEMENTATION ?= rmw_fastrtps_cpp

.PHONY: setup kernels demo demo-6dof test bench clean

setup: $(STAMP) kernels

# Built ahead of time from the sources as they are (nothing to do where they are built
# already): a node then starts without loading numba.
kernels: $(STAMP)
	$(PY) -m cdpr_control.kernels $(KERNEL_MODULES)

$(STAMP): requirements.txt $(PACKAGE_FILES) tools/venv-activate.sh
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --disable-pip-version-check -r requirements.txt
	$(PY) -m pip install --quiet --disable-pip-version-check --no-deps $(foreach p,$(PACKAGES),-e src/$(p))
	sed -i '/^# cdpr environment/,$$d' $(VENV)/bin/activate
	cat tools/venv-activate.sh >> $(VENV)/bin/activate
	touch $(STAMP)

demo: setup
	$(VENV)/bin/cdpr-robot --config paper_robot.yaml
	$(VENV)/bin/cdpr-scenario --motion circle --fail-cable 4 --fail-at-fraction 0.375 --engine graph --quiet --out runs/demo

# A rigid 6-DOF platform on eight cables: the model's view of it, then cable 5 broken a
# quarter into the tilting climb, named and the platform recovered to its safe pose,
# through the node graph (docs/platform.md).
demo-6dof: setup
	$(VENV)/bin/cdpr-robot --config robots/crossed_platform_robot.yaml --motions crossed_platform_motions.yaml
	$(VENV)/bin/cdpr-scenario --config robots/crossed_platform_robot.yaml --motions crossed_platform_motions.yaml --motion climb-tilt --fail-cable 5 --fail-at-fraction 0.25 --engine graph --quiet --out runs/demo-6dof

# Two sessions: every test that judges no node against the wall clock and starts no Dask
# cluster, spread over the machine's cores (pytest-xdist, a test file per worker; a
# lockstep graph waits for nothing but its own messages); then those alone, one at a
# time: the realtime tests judge a 500 Hz loop on this machine, and the Dask tests'
# timeouts assume a machine they do not share. Both always run, writing bytecode caches
# (gitignored) whatever the shell says: else both sessions, each xdist worker and every node
# process of every graph compile every module again (the test modules' rewritten asserts
# alone took 2-3 s of each session's start).
test: setup
	unset PYTHONDONTWRITEBYTECODE; \
	$(PY) -m pytest -m 'not realtime and not cluster' -n auto --dist loadfile; first=$$?; \
	$(PY) -m pytest -m 'realtime or cluster'; exit $$(( first || $$? ))

bench: setup
	$(VENV)/bin/cdpr-bench model
	$(VENV)/bin/cdpr-bench run
	$(VENV)/bin/cdpr-bench cycle
	$(VENV)/bin/cdpr-bench graph
	$(VENV)/bin/cdpr-bench fdi
	$(VENV)/bin/cdpr-bench roc
	$(VENV)/bin/cdpr-bench sweep
	$(VENV)/bin/cdpr-bench campaign

clean:
	rm -rf $(VENV) build install log .pytest_cache
