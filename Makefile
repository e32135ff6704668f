# Two commands do everything on a fresh machine:
#   make demo   - set up the venv (ROS 2 wheels, rosidl messages, deps), run the main job
#   make test   - set up the venv, run the tests
# ROS_DISTRO selects the ROS 2 distribution: jazzy (default, LTS) into .venv, kilted into
# .venv-kilted (`ROS_DISTRO=kilted make test`). Each installs exactly its lock file,
# requirements/<distro>.lock (`make lock` regenerates both from requirements.txt).
# Set-up is idempotent: stamps in the venv make a second run skip what has not changed.

PYTHON ?= python3
ROS_DISTRO ?= jazzy
DISTROS := jazzy kilted
ifeq ($(filter $(ROS_DISTRO),$(DISTROS)),)
$(error ROS_DISTRO=$(ROS_DISTRO) has no ROS 2 wheels here: use jazzy (the default) or kilted, e.g. `ROS_DISTRO=kilted make test`; a system ROS is built with colcon, see README)
endif
ifeq ($(ROS_DISTRO),jazzy)
VENV   ?= .venv
else
VENV   ?= .venv-$(ROS_DISTRO)
endif
LOCK   := requirements/$(ROS_DISTRO).lock
PY     := $(VENV)/bin/python
PIP    := $(PY) -m pip --disable-pip-version-check -q
DEPS_STAMP := $(VENV)/.deps-stamp
PKG_STAMP  := $(VENV)/.pkg-stamp
SYS_STAMP  := $(VENV)/.sys-stamp
WARM_STAMP := $(VENV)/.numba-stamp
MSGS   := $(wildcard msg/*.msg interfaces/can_msgs/msg/*.msg interfaces/can_msgs/CMakeLists.txt)
PYTEST_ARGS ?=
export ROS_DISTRO

.PHONY: all setup demo test bench colcon-check lock clean distclean

all: test

# Debian packages the tests and the Rerun screenshot need (a headless X server and a
# software Vulkan driver for the real Rerun viewer; tmux, the real terminal `watch` is tested in).
# Skipped when already present.
$(SYS_STAMP): | $(DEPS_STAMP)
	@if ! command -v xvfb-run >/dev/null 2>&1 || ! command -v tmux >/dev/null 2>&1 || ! ls /usr/share/vulkan/icd.d/lvp_icd*.json >/dev/null 2>&1; then \
	  echo ">> installing Debian packages: xvfb mesa-vulkan-drivers xauth tmux"; \
	  SUDO=$$( [ "$$(id -u)" = 0 ] || echo sudo ); \
	  $$SUDO apt-get update -qq && DEBIAN_FRONTEND=noninteractive $$SUDO apt-get install -y -qq xvfb xauth mesa-vulkan-drivers tmux >/dev/null; \
	fi
	@touch $@

# uv (at the lock's version) installs exactly the lock, hashes checked. A changed lock rebuilds
# the venv from scratch (seconds, from uv's cache): several ROS wheels install into shared
# directories, and removing one of them in place has deleted another's modules. With their
# bytecode compiled: uv leaves it out by default, and a process that cannot write it (a read-only
# venv, PYTHONDONTWRITEBYTECODE) compiles every module it imports at every start (about 1.7 s of
# the node's 3 s of CPU at start-up here).
$(DEPS_STAMP): $(LOCK)
	@echo ">> installing $(LOCK) into $(VENV) (ROS 2 $(ROS_DISTRO) wheels, numpy, mcap, rerun-sdk, ...)"
	rm -rf $(VENV)
	$(PYTHON) -m venv $(VENV)
	$(PIP) install "$$(sed -n 's/^\(uv==[^ ]*\).*/\1/p' $(LOCK))"
	$(VENV)/bin/uv pip sync -q --compile-bytecode --python $(PY) $(LOCK)
	@touch $@

# The lock files, from requirements.txt (the human-edited input) with ${ROS_DISTRO} put in and
# the other distribution's `# only:` lines left out:
# exact versions and hashes for CPython 3.11 on x86_64 Linux. Run after editing requirements.txt.
lock:
	@command -v uv >/dev/null 2>&1 || $(PYTHON) -m pip install -q uv
	@for d in $(DISTROS); do \
	  echo ">> requirements/$$d.lock"; \
	  awk -v d=$$d '!/# only:/ || $$0 ~ "# only: " d' requirements.txt | sed "s/\$${ROS_DISTRO}/$$d/g" | uv pip compile - -q --generate-hashes \
	    --python-version 3.11 --python-platform x86_64-manylinux_2_28 --no-header \
	    --annotation-style line -o requirements/$$d.lock || exit 1; \
	done

# Generates linkage_monitor.msg from msg/*.msg with rosidl and installs the package
# (editable: Python edits need no re-install; message edits re-run this step).
$(PKG_STAMP): $(DEPS_STAMP) setup.py CMakeLists.txt package.xml $(MSGS)
	@echo ">> building messages and installing linkage_monitor"
	$(PIP) install --no-build-isolation --no-deps -e .
	@echo $(ROS_DISTRO) > linkage_monitor/msg/.ros_distro
	@touch $@

# The physics kernels compiled once into numba's on-disk cache (about a minute the first time),
# so that the node and the tests load machine code instead of compiling it; the package's own
# bytecode with them (the editable install leaves it to the first import, which may not write it).
$(WARM_STAMP): $(PKG_STAMP) $(wildcard linkage_monitor/mechanics/kernels/*.py)
	@echo ">> compiling the physics kernels (numba, cached on disk)"
	$(PY) -m linkage_monitor.mechanics.warm
	$(PY) -m compileall -q linkage_monitor
	@touch $@

# The generated messages live in the source tree (editable install) and belong to one
# distribution: switching distribution regenerates them.
setup: $(PKG_STAMP) $(SYS_STAMP)
	@test "$$(cat linkage_monitor/msg/.ros_distro 2>/dev/null)" = $(ROS_DISTRO) || { rm -f $(PKG_STAMP); $(MAKE) --no-print-directory $(PKG_STAMP); }
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
	VENV=$(VENV) sh tools/colcon_check.sh

clean:
	rm -rf build out .pytest_cache .hypothesis linkage_monitor/msg linkage_monitor/*.so
	rm -f $(PKG_STAMP)

distclean: clean
	rm -rf .venv .venv-*
