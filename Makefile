# VPL GI: set-up, tests, demo and extension packaging. Needs only Python 3.11 on the machine.
PYTHON ?= python3.11
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
# Runtime wheels bundled into the extension, one set per platform of blender_manifest.toml (cp311: Blender 4.2-5.0
# bundle Python 3.11 and numpy). embreex 4.4 has macOS wheels for 13.0 or newer only; scipy's are the widest ones that
# pip picks for macOS 13 (OpenBLAS builds, not the macOS 14 Accelerate ones).
EMBREEX_VERSION := 4.4.0.post1
SCIPY_VERSION := 1.17.1
WHEELS_LINUX_X64 := wheels/embreex-$(EMBREEX_VERSION)-cp311-cp311-manylinux_2_27_x86_64.manylinux_2_28_x86_64.whl \
	wheels/scipy-$(SCIPY_VERSION)-cp311-cp311-manylinux_2_27_x86_64.manylinux_2_28_x86_64.whl
WHEELS_WINDOWS_X64 := wheels/embreex-$(EMBREEX_VERSION)-cp311-cp311-win_amd64.whl \
	wheels/scipy-$(SCIPY_VERSION)-cp311-cp311-win_amd64.whl
WHEELS_MACOS_ARM64 := wheels/embreex-$(EMBREEX_VERSION)-cp311-cp311-macosx_13_0_arm64.whl \
	wheels/scipy-$(SCIPY_VERSION)-cp311-cp311-macosx_12_0_arm64.whl
WHEELS_MACOS_X64 := wheels/embreex-$(EMBREEX_VERSION)-cp311-cp311-macosx_13_0_x86_64.whl \
	wheels/scipy-$(SCIPY_VERSION)-cp311-cp311-macosx_10_14_x86_64.whl
# The denoiser (issue 23): OpenImageDenoise's libraries in the pyoidn wheel, and its cffi binding (pycparser is pure)
PYOIDN_VERSION := 2.5.1.0
CFFI_VERSION := 2.1.1
PYCPARSER := wheels/pycparser-3.12-py3-none-any.whl
WHEELS_LINUX_X64 += wheels/pyoidn-$(PYOIDN_VERSION)-py3-none-manylinux2014_x86_64.whl \
	wheels/cffi-$(CFFI_VERSION)-cp311-cp311-manylinux2014_x86_64.manylinux_2_17_x86_64.whl $(PYCPARSER)
WHEELS_WINDOWS_X64 += wheels/pyoidn-$(PYOIDN_VERSION)-py3-none-win_amd64.whl \
	wheels/cffi-$(CFFI_VERSION)-cp311-cp311-win_amd64.whl
WHEELS_MACOS_ARM64 += wheels/pyoidn-$(PYOIDN_VERSION)-py3-none-macosx_12_0_arm64.whl \
	wheels/cffi-$(CFFI_VERSION)-cp311-cp311-macosx_11_0_arm64.whl
WHEELS_MACOS_X64 += wheels/pyoidn-$(PYOIDN_VERSION)-py3-none-macosx_10_15_x86_64.whl \
	wheels/cffi-$(CFFI_VERSION)-cp311-cp311-macosx_10_15_x86_64.whl
# Compiled kernels (issue 26): numba and its LLVM binding; numba 0.62 is the last with macOS x86-64 wheels
NUMBA_VERSION := 0.62.1
LLVMLITE_VERSION := 0.45.1
WHEELS_LINUX_X64 += wheels/numba-$(NUMBA_VERSION)-cp311-cp311-manylinux2014_x86_64.manylinux_2_17_x86_64.whl \
	wheels/llvmlite-$(LLVMLITE_VERSION)-cp311-cp311-manylinux2014_x86_64.manylinux_2_17_x86_64.whl
WHEELS_WINDOWS_X64 += wheels/numba-$(NUMBA_VERSION)-cp311-cp311-win_amd64.whl \
	wheels/llvmlite-$(LLVMLITE_VERSION)-cp311-cp311-win_amd64.whl
WHEELS_MACOS_ARM64 += wheels/numba-$(NUMBA_VERSION)-cp311-cp311-macosx_11_0_arm64.whl \
	wheels/llvmlite-$(LLVMLITE_VERSION)-cp311-cp311-macosx_11_0_arm64.whl
WHEELS_MACOS_X64 += wheels/numba-$(NUMBA_VERSION)-cp311-cp311-macosx_10_15_x86_64.whl \
	wheels/llvmlite-$(LLVMLITE_VERSION)-cp311-cp311-macosx_10_15_x86_64.whl
WHEELS := $(WHEELS_LINUX_X64) $(WHEELS_WINDOWS_X64) $(WHEELS_MACOS_ARM64) $(WHEELS_MACOS_X64)
DEMO_SCENE := example_blends/cornell_area.blend

.PHONY: venv test test-all demo wheels extension examples scenes bench clean

venv: $(STAMP)

$(STAMP): requirements.txt
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -r requirements.txt
	touch $@

# The wheels of every platform (fetched, never committed): pip picks, for the given platform tag, the files named above;
# `ls` fails if it picked others (a new upload), so the manifest's list and these names must then be updated together.
wheels: $(WHEELS)

fetch_wheels = mkdir -p wheels && $(BIN)/python -m pip download --quiet --no-deps --only-binary=:all: \
	--python-version 3.11 --implementation cp $(foreach tag,$(1),--platform $(tag)) -d wheels \
	embreex==$(EMBREEX_VERSION) scipy==$(SCIPY_VERSION) pyoidn==$(PYOIDN_VERSION) cffi==$(CFFI_VERSION) \
	pycparser==3.12 numba==$(NUMBA_VERSION) llvmlite==$(LLVMLITE_VERSION) && ls $(2) >/dev/null

$(WHEELS_LINUX_X64) &: | $(STAMP)
	$(call fetch_wheels,manylinux_2_28_x86_64 manylinux2014_x86_64,$(WHEELS_LINUX_X64))
$(WHEELS_WINDOWS_X64) &: | $(STAMP)
	$(call fetch_wheels,win_amd64,$(WHEELS_WINDOWS_X64))
$(WHEELS_MACOS_ARM64) &: | $(STAMP)
	$(call fetch_wheels,macosx_13_0_arm64,$(WHEELS_MACOS_ARM64))
$(WHEELS_MACOS_X64) &: | $(STAMP)
	$(call fetch_wheels,macosx_13_0_x86_64,$(WHEELS_MACOS_X64))

test: $(STAMP) $(WHEELS)
	$(BIN)/python -m pytest

# Everything, including the slow tests (minutes) that CI leaves to the benchmark runs.
test-all: $(STAMP) $(WHEELS)
	$(BIN)/python -m pytest -m "slow or not slow"

demo: $(STAMP)
	mkdir -p out
	$(BIN)/python -m vpl_addon render $(DEMO_SCENE) -o out/demo.exr --overwrite

# One installable zip per platform of the manifest, dist/vpl_gi-<version>-<platform>.zip (linux_x64, windows_x64,
# macos_arm64, macos_x64), each with only its platform's wheels, built and validated by the tool that ships inside the
# bpy wheel.
BLENDER_EXT := $(VENV)/lib/python3.11/site-packages/bpy/5.0/scripts/addons_core/bl_pkg/cli/blender_ext.py
VERSION_AND_PLATFORMS = $(shell $(BIN)/python -c 'import tomllib; m = tomllib.load(open("blender_manifest.toml", "rb")); \
	print(m["version"], *(p.replace("-", "_") for p in m["platforms"]))')
extension: $(STAMP) $(WHEELS)
	mkdir -p dist
	$(BIN)/python $(BLENDER_EXT) build --split-platforms --source-dir . --output-dir dist
	for platform in $(wordlist 2,99,$(VERSION_AND_PLATFORMS)); do \
		$(BIN)/python $(BLENDER_EXT) validate dist/vpl_gi-$(word 1,$(VERSION_AND_PLATFORMS))-$$platform.zip || exit 1; done

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
