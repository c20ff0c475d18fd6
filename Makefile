# VPL GI: set-up, tests, demo and extension packaging. Needs only Python 3.11 on the machine.
PYTHON ?= python3.11
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
EMBREEX_WHEEL := embreex-4.4.0.post1-cp311-cp311-manylinux_2_27_x86_64.manylinux_2_28_x86_64.whl
SCIPY_WHEEL := scipy-1.17.1-cp311-cp311-manylinux_2_27_x86_64.manylinux_2_28_x86_64.whl
WHEELS := wheels/$(EMBREEX_WHEEL) wheels/$(SCIPY_WHEEL)
DEMO_SCENE := example_blends/cornell_area.blend

.PHONY: venv test test-all demo wheels extension examples scenes bench clean

venv: $(STAMP)

$(STAMP): requirements.txt
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -r requirements.txt
	touch $@

# Runtime wheels bundled into the extension (fetched, never committed).
wheels: $(WHEELS)

$(WHEELS) &: | $(STAMP)
	mkdir -p wheels
	$(BIN)/python -m pip download --quiet --no-deps --only-binary=:all: --python-version 3.11 \
		--implementation cp --platform manylinux_2_28_x86_64 -d wheels embreex==4.4.0.post1 scipy==1.17.1
	test -f wheels/$(EMBREEX_WHEEL) && test -f wheels/$(SCIPY_WHEEL)

test: $(STAMP) $(WHEELS)
	$(BIN)/python -m pytest

# Everything, including the slow tests (minutes) that CI leaves to the benchmark runs.
test-all: $(STAMP) $(WHEELS)
	$(BIN)/python -m pytest -m "slow or not slow"

demo: $(STAMP)
	mkdir -p out
	$(BIN)/python -m vpl_addon render $(DEMO_SCENE) -o out/demo.exr --overwrite

# The installable extension zip, built and validated by the tool that ships inside the bpy wheel.
BLENDER_EXT := $(VENV)/lib/python3.11/site-packages/bpy/5.0/scripts/addons_core/bl_pkg/cli/blender_ext.py
extension: $(STAMP) $(WHEELS)
	mkdir -p dist
	$(BIN)/python $(BLENDER_EXT) build --source-dir . --output-dir dist
	$(BIN)/python $(BLENDER_EXT) validate dist/vpl_gi-$$(sed -n 's/^version = "\(.*\)"/\1/p' blender_manifest.toml).zip

examples: $(STAMP)
	$(BIN)/python example_blends/make_examples.py
	$(BIN)/python example_blends/make_corridor.py
	$(BIN)/python example_blends/make_metal.py
	$(BIN)/python example_blends/make_pbr.py
	$(BIN)/python example_blends/make_sequences.py

# The public scenes of ../shared/scenes (Mitsuba XML, Cornell measured data, glTF) as .blend files in scenes/ (git-ignored;
# nothing from ../shared is committed). A file is rewritten only when the converter or its source changed.
SCENES_SOURCE ?= ../shared/scenes
scenes: $(STAMP)
	$(BIN)/python -m vpl_addon scenes --source $(SCENES_SOURCE) --out scenes

# Tracer throughput, then time against error of every method and Cycles on every example scene, with the scaling
# runs (12.6 minutes measured on 2 cores before vbnl joined; about 16 with it); results in out/bench/ (bench.csv, <scene>.png, summary.txt, scaling.csv).
BENCH_OUT ?= out/bench
bench: $(STAMP)
	$(BIN)/python bench/tracer_throughput.py
	$(BIN)/python -m vpl_addon bench example_blends/*.blend --scaling --out $(BENCH_OUT) --overwrite

clean:
	rm -rf out dist build .pytest_cache
