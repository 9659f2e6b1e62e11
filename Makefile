# make demo   the main job: the pick-and-place demo (creates .venv on first use); ARM=ur5e or ARM=fr3 on that arm
# make test   colcon build + colcon test of the packages, then the repository's tests in test/ (system tests in test/system/)
# make test-load  the end-to-end system tests again, beside four CPU-bound processes
# make bench  the speed benchmarks (installs the optional peers to compare against)
# make fuzz   the long run of the arbitrary-input tests (10 000 examples per function)
SHELL := /bin/bash
.SHELLFLAGS := -eo pipefail -c
PYTHON ?= python3
VENV := .venv
BIN := $(abspath $(VENV))/bin
STAMP := $(VENV)/.installed
PACKAGE_FILES := $(wildcard src/*/setup.py src/*/package.xml src/*/CMakeLists.txt src/*/action/* src/*/msg/*)
# Built into the venv by tools/build_interfaces.py (the pip route has no control_msgs, tf2_msgs or vision_msgs wheel).
INTERFACES := control_msgs tf2_msgs vision_msgs picking_interfaces

# Network rule: DDS discovery never leaves the loopback interface, and every run
# gets a domain of its own so that parallel runs never see each other.
export ROS_AUTOMATIC_DISCOVERY_RANGE := LOCALHOST
export ROS_DOMAIN_ID ?= $(shell echo $$(( $$$$ % 90 + 10 )))
export PATH := $(BIN):$(PATH)
export MPLBACKEND := Agg

# colcon builds the Python packages; the interface packages are in the venv already (see INTERFACES).
COLCON_PATHS := --base-paths $(filter-out $(addprefix src/,$(INTERFACES)),$(wildcard src/*)) --build-base build \
	--install-base install

.PHONY: demo test test-load unit system fuzz docs bench clean

$(STAMP): requirements.txt $(PACKAGE_FILES)
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -r requirements.txt
	$(BIN)/python tools/build_interfaces.py --build-dir build/interfaces $(INTERFACES)
	# Compile the IK, forward kinematics and trajectory kernels into numba's cache now, not in the
	# first node that plans.
	$(BIN)/python -c 'from picking_core.kinematics import ArmModel; from picking_description import urdf_path; [ArmModel.from_urdf(urdf_path(a)).load_ik() for a in ("picking_arm", "ur5e", "fr3")]'
	$(BIN)/python -c 'import picking_core.trajectory.fast_sample'
	touch $@

# The pick-and-place cycle of Table 1 through the real nodes, then the paper's examples offline.
# The paper's examples run even when the ROS part failed; make still fails then.
demo: $(STAMP)
	status=0; $(BIN)/picking-demo $(if $(ARM),--arm $(ARM) --out out/demo-$(ARM),--out out/demo) || status=$$?; \
	mkdir -p out; $(BIN)/picking-plan --paper --out out/paper > out/paper.txt || status=$$?; \
	echo "paper examples: out/paper (summary in out/paper.txt)"; \
	exit $$status

test: unit system

# The packages' own tests, built and run the way ROS users do.
unit: $(STAMP)
	rm -rf build/*/test_results
	colcon --log-base log build $(COLCON_PATHS)
	colcon --log-base log test $(COLCON_PATHS) --return-code-on-test-failure \
		--event-handlers console_direct- --pytest-args -q
	colcon test-result --test-result-base build --verbose | tee build/test-summary.txt
	grep -qE '^Summary: [1-9][0-9]* tests, 0 errors, 0 failures' build/test-summary.txt \
		|| { echo 'colcon ran no tests or some failed'; exit 1; }

# The system tests: several processes talking over ROS (pytest exits 5 when it finds none).
system: $(STAMP)
	$(BIN)/python -m pytest test -q

# The end-to-end tests (a pose goal, a pick, a goal mid-motion, the floods, the demo's quick run, the faults)
# beside four CPU-bound processes on the machine's cores, as when perception shares the arm's computer.
test-load: $(STAMP)
	$(BIN)/python -m pytest test -q -m load --cpu-load 4

# The long run of the arbitrary-input (hypothesis) tests: 10 000 examples per function.
fuzz: $(STAMP)
	$(BIN)/python -m pytest -q -m fuzz --hypothesis-profile=long --import-mode=importlib src/picking_common/test \
		src/picking_core/test src/picking_controller/test src/picking_sim/test

# docs/parameters.md from the nodes' parameter tables.
docs: $(STAMP)
	$(BIN)/python tools/param_docs.py

bench: $(STAMP)
	$(BIN)/python -m pip install --quiet -r benchmarks/requirements.txt
	$(BIN)/python benchmarks/run.py

clean:
	rm -rf build install log out
