# furbake — the two commands of the README, plus helpers.
# `make demo`: bake the bundled Fox (fur) and the thesis's grass patch (shells + 400 blades/m²),
#              inspect, verify, extract PNG atlases and render preview PNGs into out/demo; then
#              animate both in a windy runtime scene (24 frames into out/demo/frames) and print
#              its per-stage simulation timings.
# `make test`: the whole test suite (unit, integration, render tests on lavapipe, doc tests).

CARGO ?= cargo
FURBAKE := target/debug/furbake
OUT := out/demo
SUDO := $(shell [ "$$(id -u)" = 0 ] || echo sudo)

.PHONY: demo test build deps bench fmt clippy golden clean-out report fuzz package doc api api-check capi capi-header

# The renderer needs a Vulkan driver; on machines without a GPU that is Mesa's lavapipe. The
# `furbake view` test needs a virtual X server (Xvfb).
deps:
	@if ! ls /usr/share/vulkan/icd.d/*.json >/dev/null 2>&1 || ! ldconfig -p | grep -q 'libvulkan.so.1 '; then \
		echo "installing Mesa's software Vulkan driver (lavapipe)"; \
		$(SUDO) apt-get update -qq && $(SUDO) apt-get install -y -qq --no-install-recommends mesa-vulkan-drivers libvulkan1; \
	fi
	@if ! python3 -c 'import jsonschema' >/dev/null 2>&1; then \
		echo "installing python3 and python3-jsonschema (the schema test validates real outputs with it)"; \
		$(SUDO) apt-get update -qq && $(SUDO) apt-get install -y -qq --no-install-recommends python3 python3-jsonschema; \
	fi
	@if ! command -v npm >/dev/null 2>&1; then \
		echo "installing Node.js and npm (the export test runs the Khronos glTF-Validator)"; \
		$(SUDO) apt-get update -qq && $(SUDO) apt-get install -y -qq --no-install-recommends nodejs npm; \
	fi
	@[ -d tools/node_modules/gltf-validator ] || npm ci --prefix tools --no-audit --no-fund
	@if ! command -v ninja >/dev/null 2>&1; then \
		echo "installing ninja (the build-pipeline test drives it with bake --depfile)"; \
		$(SUDO) apt-get update -qq && $(SUDO) apt-get install -y -qq --no-install-recommends ninja-build; \
	fi
	@if ! command -v xvfb-run >/dev/null 2>&1; then \
		echo "installing Xvfb (the furbake view test opens a window on a virtual X server)"; \
		$(SUDO) apt-get update -qq && $(SUDO) apt-get install -y -qq --no-install-recommends xvfb xauth; \
	fi
	@if ! command -v spirv-val >/dev/null 2>&1 || ! command -v glslangValidator >/dev/null 2>&1; then \
		echo "installing spirv-tools and glslang-tools (the shader export test validates SPIR-V and GLSL)"; \
		$(SUDO) apt-get update -qq && $(SUDO) apt-get install -y -qq --no-install-recommends spirv-tools glslang-tools; \
	fi
	@if [ ! -f /usr/include/EGL/egl.h ] || [ ! -f /usr/include/GL/glcorearb.h ] || ! ldconfig -p | grep -q 'libOpenGL.so ' || ! ldconfig -p | grep -q 'libEGL_mesa.so.0 '; then \
		echo "installing EGL, OpenGL and Mesa's llvmpipe (the OpenGL host test draws headless)"; \
		$(SUDO) apt-get update -qq && $(SUDO) apt-get install -y -qq --no-install-recommends libegl-dev libgl-dev libopengl-dev libegl-mesa0 libgl1-mesa-dri; \
	fi
	@if ! command -v cc >/dev/null 2>&1 || ! command -v pkg-config >/dev/null 2>&1; then \
		echo "installing a C compiler and pkg-config (the C interface's tests build a C host)"; \
		$(SUDO) apt-get update -qq && $(SUDO) apt-get install -y -qq --no-install-recommends gcc libc6-dev pkg-config; \
	fi
	@if ! command -v bazel >/dev/null 2>&1 || ! command -v nginx >/dev/null 2>&1; then \
		echo "installing Bazel and nginx (the bake-farm test bakes under Bazel with an HTTP remote cache)"; \
		$(SUDO) apt-get update -qq && $(SUDO) apt-get install -y -qq --no-install-recommends bazel-bootstrap nginx-light; \
	fi

# The demo uses the dev profile (our crates at opt-level 1, dependencies at 2; see Cargo.toml):
# it shares its build with `make test`, and a release build of wgpu takes ~10 minutes on 2 cores.
build:
	$(CARGO) build -p furbake-cli

demo: deps build
	mkdir -p $(OUT)
	$(FURBAKE) bake fixtures/real/Fox.glb -o $(OUT)/fox.fbk --preset fur --topology prisms --png-dir $(OUT)/fox-png
	$(FURBAKE) inspect $(OUT)/fox.fbk
	$(FURBAKE) verify $(OUT)/fox.fbk
	$(FURBAKE) extract $(OUT)/fox.fbk -o $(OUT)/fox-extract
	$(FURBAKE) bake fixtures/generated/grass_patch.gltf -o $(OUT)/grass-patch.fbk --preset grass --blades 400 --topology prisms --png-dir $(OUT)/grass-png
	$(FURBAKE) inspect --json $(OUT)/grass-patch.fbk > $(OUT)/grass-patch.json
	$(FURBAKE) preview $(OUT)/fox.fbk -o $(OUT)/fox-preview.png --size 640x480
	$(FURBAKE) preview $(OUT)/grass-patch.fbk -o $(OUT)/grass-patch-preview.png --size 640x480
# A furry sphere: its outline is all silhouette, drawn by the silhouette fins.
	$(FURBAKE) bake fixtures/generated/sphere.gltf -o $(OUT)/sphere.fbk --preset fur
	$(FURBAKE) preview $(OUT)/sphere.fbk -o $(OUT)/sphere-preview.png --size 640x480
# The runtime scene: pack paths are relative to the scene file, so it goes beside the packs.
	cp fixtures/scenes/demo_fox_and_grass.toml $(OUT)/fox_and_grass.toml
	$(FURBAKE) preview $(OUT)/fox_and_grass.toml --frames 24 --size 320x240 --out-dir $(OUT)/frames
	$(FURBAKE) simulate $(OUT)/fox_and_grass.toml --frames 120
	@echo "demo done: open $(OUT)/fox-preview.png, $(OUT)/sphere-preview.png, $(OUT)/grass-patch-preview.png, $(OUT)/fox-png/shells_grid.png and $(OUT)/frames/frame_0000.png … frame_0023.png"

test: deps
	$(CARGO) test --workspace

bench:
	$(CARGO) bench --workspace

# The API docs of every crate, failing on any rustdoc warning (broken or ambiguous links, links
# from public docs to private items).
doc:
	RUSTDOCFLAGS="-D warnings" $(CARGO) doc --workspace --no-deps

# The public API of the crates a host builds on, one item a line (docs/api/CRATE.txt): rustdoc's
# JSON of each crate with its default features, listed by tools/public_api.py. The stable
# toolchain writes that JSON for the named crates only (RUSTC_BOOTSTRAP=CRATE), in a target
# folder of its own. `make api` rewrites the snapshots after an intended change; `make
# api-check` (run by .ci/run) fails, with the difference, when the API and its snapshot differ.
API_CRATES := furbake_draw furbake_render furbake_runtime
API_TARGET := target/api
api:
	@mkdir -p docs/api
	@for c in $(API_CRATES); do 		RUSTC_BOOTSTRAP=$$c CARGO_TARGET_DIR=$(API_TARGET) $(CARGO) rustdoc -q -p $$(echo $$c | tr _ -) --lib -- 			-Z unstable-options --output-format json || exit 1; 		python3 tools/public_api.py $(API_TARGET)/doc/$$c.json > docs/api/$$(echo $$c | tr _ -).txt || exit 1; 		echo "docs/api/$$(echo $$c | tr _ -).txt: $$(wc -l < docs/api/$$(echo $$c | tr _ -).txt) items"; 	done

api-check:
	@for c in $(API_CRATES); do 		RUSTC_BOOTSTRAP=$$c CARGO_TARGET_DIR=$(API_TARGET) $(CARGO) rustdoc -q -p $$(echo $$c | tr _ -) --lib -- 			-Z unstable-options --output-format json || exit 1; 		python3 tools/public_api.py $(API_TARGET)/doc/$$c.json > $(API_TARGET)/$$c.txt || exit 1; 		if ! diff -u docs/api/$$(echo $$c | tr _ -).txt $(API_TARGET)/$$c.txt; then 			echo "the public API of $$(echo $$c | tr _ -) differs from docs/api/$$(echo $$c | tr _ -).txt (- snapshot, + code): run make api after an intended change" >&2; 			exit 1; 		fi; 	done; echo "public API matches docs/api/"

# Package every publishable crate as crates.io would (furbake-fuzz is publish = false) and build
# each package from its .crate alone, the workspace's unpublished crates standing in for the
# registry (cargo's verification build), in a target folder of its own (the packages carry no
# profile settings, so nothing is shared with target/debug). Then the `furbake` built from the
# packaged CLI crate bakes and verifies a bundled model. The .crate files land in
# target/package-build/package/.
# Cargo unpacks the packages it verifies into $(CARGO_HOME)/registry/src/-<hash>/ (a folder per
# local registry, its name starting with '-') and reuses an unpacked copy of the same name and
# version from an earlier run without looking at it again: since every run packages version
# 0.1.0, the verification would build the previous run's sources. The furbake copies there are
# removed first; crates.io's folder (index.crates.io-*) is never touched.
PACKAGE_TARGET := target/package-build
CARGO_HOME_DIR := $(or $(CARGO_HOME),$(HOME)/.cargo)
package:
	rm -rf $(CARGO_HOME_DIR)/registry/src/-*/furbake-*
	CARGO_TARGET_DIR=$(PACKAGE_TARGET) $(CARGO) package --workspace --exclude furbake-fuzz
	$(PACKAGE_TARGET)/debug/furbake --version
	$(PACKAGE_TARGET)/debug/furbake bake fixtures/real/Box.glb -o $(PACKAGE_TARGET)/box.fbk --preset fur --quiet
	$(PACKAGE_TARGET)/debug/furbake verify $(PACKAGE_TARGET)/box.fbk

# furbake's C interface as a package under target/capi (docs/c-api.md): include/furbake.h,
# lib/libfurbake_capi.a and .so, lib/pkgconfig/furbake.pc (prefix = that folder; install
# elsewhere with `make capi CAPI_PREFIX=/usr/local` as root). Release build.
CAPI_PREFIX ?= $(CURDIR)/target/capi
capi:
	$(CARGO) build --release -p furbake-capi
	mkdir -p $(CAPI_PREFIX)/include $(CAPI_PREFIX)/lib/pkgconfig
	cp crates/capi/include/furbake.h $(CAPI_PREFIX)/include/
	cp target/release/libfurbake_capi.a target/release/libfurbake_capi.so $(CAPI_PREFIX)/lib/
	sed -e 's|@PREFIX@|$(CAPI_PREFIX)|' -e "s|@VERSION@|$$(sed -n 's/^version = \"\(.*\)\"/\1/p' Cargo.toml | head -1)|" \
		crates/capi/furbake.pc.in > $(CAPI_PREFIX)/lib/pkgconfig/furbake.pc
	@echo "C interface in $(CAPI_PREFIX): PKG_CONFIG_PATH=$(CAPI_PREFIX)/lib/pkgconfig pkg-config --cflags --libs furbake"

# Regenerate crates/capi/include/furbake.h with cbindgen after an intended change to the C
# interface (the crate's `header` test fails while the checked-in copy is stale).
capi-header:
	FURBAKE_BLESS=1 $(CARGO) test -p furbake-capi --test capi header

fmt:
	$(CARGO) fmt --all

clippy:
	$(CARGO) clippy --workspace --all-targets -- -D warnings

clean-out:
	rm -rf out

# Regenerate the golden pack checksums and the committed v1 pack, and the renderer's golden
# images (crates/render/tests/reference/golden_*.png, compared by FLIP) and the HLSL and MSL
# snapshots of `furbake shaders` (tests/cli/reference/shaders/), after an intended change.
golden:
	FURBAKE_BLESS=1 $(CARGO) test -p furbake-cli --test cli golden
	FURBAKE_BLESS=1 $(CARGO) test -p furbake-render --test render golden_images::
	FURBAKE_BLESS=1 $(CARGO) test -p furbake-cli --test cli shaders::hlsl_and_msl

# Regenerate docs/accuracy.md and its SVG charts from measurements (release build; a few minutes
# on 2 cores). It runs the report crate's example — the same library call as `furbake report
# accuracy -o docs` — without the crate's `render` feature, so it does not build the renderer
# (wgpu) in release. Then docs/rendering-accuracy.md (shells and fins against a ray-marched
# reference of the hair volume, furbake_report::rendering) in the dev profile on the GPU or
# lavapipe: about 6 minutes on 2 cores.
report: deps
	$(CARGO) run --release -p furbake-report --no-default-features --example accuracy_report -- docs
	$(CARGO) run -p furbake-report --example rendering_report -- docs

# The long fuzzing campaign (crates/fuzz): release build, 200,000 pack, 3,000 glTF (every 10th also
# through the debug `furbake` binary under a 2 GiB limit) and 3,000 scene mutants, then 5,000
# hostile pipeline cases through the debug `furbake` binary (outputs over devices, FIFOs,
# directories, inputs and each other; depfile names through GNU make and ninja; planted manifests
# under batch; special files as inputs — about 2.5 minutes; needs make and ninja, see `make deps`);
# exits 1 on any panic, abort, hang, slow case or broken rule, with reproducers in
# target/fuzz-reproducers. `make fuzz FUZZ_SEED=7` runs other mutants.
FUZZ_SEED ?= 1
fuzz:
	$(CARGO) build -p furbake-cli
	$(CARGO) run --release -p furbake-fuzz -- --packs 200000 --gltf 3000 --scenes 3000 --pipelines 5000 \
		--seed $(FUZZ_SEED) --cli $(FURBAKE) --cli-every 10 --slow-ms 2000 --out target/fuzz-reproducers
