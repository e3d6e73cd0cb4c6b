# volpath's front door. Every target creates or reuses .venv (Python 3.11, bpy==5.0.1).
PYTHON_SYS ?= python3.11
VENV       := .venv
PY         := $(VENV)/bin/python
BLENDER    ?= $(shell command -v blender 2>/dev/null)
OUT        ?= out/demo

.PHONY: venv demo test test-native test-addon test-compare fuzz extension install-blender bench clean

venv: $(VENV)/.stamp
$(VENV)/.stamp: requirements.txt native/pyproject.toml
	test -x $(PY) || $(PYTHON_SYS) -m venv $(VENV)
	$(PY) -m pip install -q --upgrade pip
	$(PY) -m pip install -q -r requirements.txt
	$(PY) -m pip install -q -e native
	touch $@

# The main job: build the Cornell fog example, render it with VolPath and Cycles, compare.
demo: venv
	$(PY) -m addon.compare demo --out $(OUT)

test: venv
	$(PY) -m pytest -q --durations=25 tests

test-native: venv
	$(PY) -m pytest -q tests/native

test-addon: venv
	$(PY) -m pytest -q tests/addon tests/addon_volume

test-compare: venv
	$(PY) -m pytest -q tests/compare

# The long fuzz run: random Blender scenes and .vpscene files through the invariants of
# tests/fuzz (figures in out/fuzz/fuzz.log and fuzz.json), then 100 random cancels of native and
# F12 renders. `make test` runs a short version of each.
fuzz: venv
	$(PY) tests/fuzz/run_fuzz.py --scenes 1000 --files 3000 --out out/fuzz
	VOLPATH_RANDOM_CANCELS=100 $(PY) -m pytest -q -s tests/native/test_reliability.py tests/addon/test_cancel.py -k random_cancels

extension: venv
	$(PY) addon/build_extension.py build

install-blender: venv
	@test -n "$(BLENDER)" || { echo "usage: make install-blender BLENDER=/path/to/blender"; exit 2; }
	$(PY) addon/build_extension.py install --blender "$(BLENDER)"

bench: venv
	$(PY) -m pip install -q -r requirements-bench.txt
	$(PY) tests/benchmarks/run_all.py

clean:
	rm -rf build dist wheels out
