# VPL GI: set-up, tests, demo and extension packaging. Needs only Python 3.11 on the machine.
PYTHON ?= python3.11
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
# Runtime wheels bundled into the extension, one set per platform of blender_manifest.toml, each for every Python the
# supported Blenders bundle: cp311 (4.2 LTS to 5.0) and cp313 (5.1 and newer); Blender's installer unpacks those
# matching its own. The packages the development venv has too are pinned in requirements.txt alone and read from it
# here, so the tests run the versions users get; cffi, pycparser and the Intel Mac's numba are pinned below. The
# manifest's `wheels` list names exactly `make -s print-wheels` (tests/blender/test_extension.py checks it). embreex
# 4.4 has macOS wheels for 13.0 or newer only; scipy's are the widest ones that pip picks for macOS 13 (OpenBLAS
# builds, not the macOS 14 Accelerate ones). numba 0.68 / llvmlite 0.50 accept numpy 1.26 to 2.5 (what Blender 4.2
# to 5.2 ship); numba's macOS x86-64 wheels end at 0.62.1, which accepts numpy <= 2.3 only, so on an Intel Mac the
# kernels load in Blender 4.2 to 5.0 and not in 5.1 or newer (numpy 2.5), where the add-on registers and says so
# (`dependencies.py`).
PYTHONS := 311 313
pin = $(shell sed -n 's/^$(1)==\([^ ]*\).*/\1/p' requirements.txt)
EMBREEX_VERSION := $(call pin,embreex)
SCIPY_VERSION := $(call pin,scipy)
PYOIDN_VERSION := $(call pin,pyoidn)
NUMBA_VERSION := $(call pin,numba)
LLVMLITE_VERSION := $(call pin,llvmlite)
CFFI_VERSION := 2.1.1
PYCPARSER_VERSION := 3.12
NUMBA_VERSION_MACOS_X64 := 0.62.1
LLVMLITE_VERSION_MACOS_X64 := 0.45.1
# $(call wheel,name,version,platform tag): the wheel of every Python of PYTHONS
wheel = $(foreach py,$(PYTHONS),wheels/$(1)-$(2)-cp$(py)-cp$(py)-$(3).whl)
WHEELS_LINUX_X64 := $(call wheel,embreex,$(EMBREEX_VERSION),manylinux_2_27_x86_64.manylinux_2_28_x86_64) \
	$(call wheel,scipy,$(SCIPY_VERSION),manylinux_2_27_x86_64.manylinux_2_28_x86_64) \
	wheels/pyoidn-$(PYOIDN_VERSION)-py3-none-manylinux2014_x86_64.whl \
	$(call wheel,cffi,$(CFFI_VERSION),manylinux2014_x86_64.manylinux_2_17_x86_64) \
	$(call wheel,numba,$(NUMBA_VERSION),manylinux_2_27_x86_64.manylinux_2_28_x86_64) \
	$(call wheel,llvmlite,$(LLVMLITE_VERSION),manylinux_2_27_x86_64.manylinux_2_28_x86_64)
WHEELS_WINDOWS_X64 := $(call wheel,embreex,$(EMBREEX_VERSION),win_amd64) $(call wheel,scipy,$(SCIPY_VERSION),win_amd64) \
	wheels/pyoidn-$(PYOIDN_VERSION)-py3-none-win_amd64.whl $(call wheel,cffi,$(CFFI_VERSION),win_amd64) \
	$(call wheel,numba,$(NUMBA_VERSION),win_amd64) $(call wheel,llvmlite,$(LLVMLITE_VERSION),win_amd64)
WHEELS_MACOS_ARM64 := $(call wheel,embreex,$(EMBREEX_VERSION),macosx_13_0_arm64) \
	$(call wheel,scipy,$(SCIPY_VERSION),macosx_12_0_arm64) wheels/pyoidn-$(PYOIDN_VERSION)-py3-none-macosx_12_0_arm64.whl \
	$(call wheel,cffi,$(CFFI_VERSION),macosx_11_0_arm64) $(call wheel,numba,$(NUMBA_VERSION),macosx_12_0_arm64) \
	$(call wheel,llvmlite,$(LLVMLITE_VERSION),macosx_12_0_arm64)
WHEELS_MACOS_X64 := $(call wheel,embreex,$(EMBREEX_VERSION),macosx_13_0_x86_64) \
	$(call wheel,scipy,$(SCIPY_VERSION),macosx_10_14_x86_64) \
	wheels/pyoidn-$(PYOIDN_VERSION)-py3-none-macosx_10_15_x86_64.whl \
	$(call wheel,cffi,$(CFFI_VERSION),macosx_10_15_x86_64) \
	$(call wheel,numba,$(NUMBA_VERSION_MACOS_X64),macosx_10_15_x86_64) \
	$(call wheel,llvmlite,$(LLVMLITE_VERSION_MACOS_X64),macosx_10_15_x86_64)
PYCPARSER := wheels/pycparser-$(PYCPARSER_VERSION)-py3-none-any.whl
WHEELS := $(WHEELS_LINUX_X64) $(WHEELS_WINDOWS_X64) $(WHEELS_MACOS_ARM64) $(WHEELS_MACOS_X64) $(PYCPARSER)
DEMO_SCENE := example_blends/cornell_area.blend

.PHONY: venv test test-all test-blender demo wheels print-wheels extension examples scenes bench bench-report docs gallery clean

venv: $(STAMP)

$(STAMP): requirements.txt
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -r requirements.txt
	touch $@

# The wheels of every platform (fetched, never committed): pip picks, for the given Python and platform tags, the files
# named above; `ls` fails if it picked others (a new upload), so the names above must then be updated.
wheels: $(WHEELS)

print-wheels:
	@printf '%s\n' $(WHEELS)

# $(call fetch_wheels,platform tags,numba version,llvmlite version,wheel files)
fetch_wheels = mkdir -p wheels && for py in $(PYTHONS); do $(BIN)/python -m pip download --quiet --no-deps \
	--only-binary=:all: --python-version $$py --implementation cp $(foreach tag,$(1),--platform $(tag)) -d wheels \
	embreex==$(EMBREEX_VERSION) scipy==$(SCIPY_VERSION) pyoidn==$(PYOIDN_VERSION) cffi==$(CFFI_VERSION) \
	numba==$(2) llvmlite==$(3) || exit 1; done && ls $(4) >/dev/null

$(WHEELS_LINUX_X64) &: | $(STAMP)
	$(call fetch_wheels,manylinux_2_28_x86_64 manylinux2014_x86_64,$(NUMBA_VERSION),$(LLVMLITE_VERSION),$(WHEELS_LINUX_X64))
$(WHEELS_WINDOWS_X64) &: | $(STAMP)
	$(call fetch_wheels,win_amd64,$(NUMBA_VERSION),$(LLVMLITE_VERSION),$(WHEELS_WINDOWS_X64))
$(WHEELS_MACOS_ARM64) &: | $(STAMP)
	$(call fetch_wheels,macosx_13_0_arm64,$(NUMBA_VERSION),$(LLVMLITE_VERSION),$(WHEELS_MACOS_ARM64))
$(WHEELS_MACOS_X64) &: | $(STAMP)
	$(call fetch_wheels,macosx_13_0_x86_64,$(NUMBA_VERSION_MACOS_X64),$(LLVMLITE_VERSION_MACOS_X64),$(WHEELS_MACOS_X64))
$(PYCPARSER): | $(STAMP)
	mkdir -p wheels && $(BIN)/python -m pip download --quiet --no-deps -d wheels pycparser==$(PYCPARSER_VERSION)

test: $(STAMP) $(WHEELS)
	$(BIN)/python -m pytest

# Everything, including the slow tests (minutes) that CI leaves to the benchmark runs.
test-all: $(STAMP) $(WHEELS)
	$(BIN)/python -m pytest -m "slow or not slow"

# The version matrix: the Linux zip installed into the bpy module of each supported Blender, each in its own venv
# under BLENDER_VENVS (git-ignored, kept between runs; pip's cache keeps the wheels), rendered and checked against 5.0
# (tests/blender/test_versions.py). 5.0 is the development venv's; 4.2 and 4.5 get the numpy 1.26 those Blenders ship.
BLENDER_VENVS ?= .venv-blender
PYTHON313 ?= $(shell pyenv root 2>/dev/null)/versions/3.13.0/bin/python3.13
BLENDER_MATRIX := 4.2=$(BLENDER_VENVS)/4.2/bin/python 4.5=$(BLENDER_VENVS)/4.5/bin/python 5.0=$(BIN)/python \
	5.2=$(BLENDER_VENVS)/5.2/bin/python
$(BLENDER_VENVS)/4.2/.installed:
	$(PYTHON) -m venv $(@D) && $(@D)/bin/python -m pip install --quiet bpy==4.2.23 "numpy<2" && touch $@
$(BLENDER_VENVS)/4.5/.installed:
	$(PYTHON) -m venv $(@D) && $(@D)/bin/python -m pip install --quiet bpy==4.5.15 "numpy<2" && touch $@
$(BLENDER_VENVS)/5.2/.installed:
	$(PYTHON313) -m venv $(@D) && $(@D)/bin/python -m pip install --quiet bpy==5.2.3 && touch $@

test-blender: extension $(foreach v,4.2 4.5 5.2,$(BLENDER_VENVS)/$(v)/.installed)
	VPL_GI_BLENDERS="$(BLENDER_MATRIX)" $(BIN)/python -m pytest -m versions -n 0 -s -p no:cacheprovider \
		tests/blender/test_versions.py

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

# The example scenes, written by the oldest supported Blender (4.2's bpy, in the version matrix's venv): every newer one
# opens its files, 4.2 does not open those of 5.0 ("not a blend file").
EXAMPLES_PYTHON := $(BLENDER_VENVS)/4.2/bin/python
examples: $(BLENDER_VENVS)/4.2/.installed
	$(EXAMPLES_PYTHON) example_blends/make_examples.py
	$(EXAMPLES_PYTHON) example_blends/make_corridor.py
	$(EXAMPLES_PYTHON) example_blends/make_metal.py
	$(EXAMPLES_PYTHON) example_blends/make_pbr.py
	$(EXAMPLES_PYTHON) example_blends/make_sequences.py

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

# The benchmarks page (docs/benchmarks.md and its plots) from the committed results in bench/results/.
bench-report: $(STAMP)
	$(BIN)/python bench/report.py

# The documentation: the pages made from the code (docs/generate.py: the command line's reference, the methods),
# then the site in strict mode (a broken link or a page left out of the nav fails), into site/.
docs: $(STAMP)
	$(BIN)/python docs/generate.py
	$(BIN)/python bench/report.py
	$(BIN)/python -m mkdocs build --strict --quiet

# The gallery's pictures (docs/images/, then docs/gallery.md by bench/report.py): the defaults against Cycles and
# Cycles + OIDN at equal time. The example stills and the living room at their own resolution, cornell_pbr and the
# other converted scenes (`make scenes` first) at half, where their references are; minutes a scene (a 1024-spp
# reference rendered and cached where none is committed).
GALLERY_FULL ?= $(addprefix example_blends/,cornell_area.blend cornell_point.blend cornell_sun.blend \
	cornell_textured.blend cornell_metal.blend corridor.blend) $(wildcard scenes/living_room.blend)
GALLERY_HALF ?= example_blends/cornell_pbr.blend $(filter-out scenes/living_room.blend,$(wildcard scenes/*.blend))
gallery: $(STAMP)
	$(BIN)/python bench/gallery.py $(GALLERY_FULL)
	$(BIN)/python bench/gallery.py $(GALLERY_HALF) --percentage 50
	$(BIN)/python bench/report.py

clean:
	rm -rf out dist build site .pytest_cache
