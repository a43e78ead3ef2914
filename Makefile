# furbake — the two commands of the README, plus helpers.
# `make demo`: bake the bundled Fox, inspect it, verify it and extract its atlases as PNGs into out/demo.
# `make test`: the whole test suite (unit, integration, doc tests).

CARGO ?= cargo
FURBAKE := target/release/furbake
OUT := out/demo

.PHONY: demo test build bench fmt clippy golden clean-out

build:
	$(CARGO) build --release -p furbake-cli

demo: build
	mkdir -p $(OUT)
	$(FURBAKE) bake fixtures/real/Fox.glb -o $(OUT)/fox.fbk --preset fur --png-dir $(OUT)/fox-png
	$(FURBAKE) inspect $(OUT)/fox.fbk
	$(FURBAKE) verify $(OUT)/fox.fbk
	$(FURBAKE) extract $(OUT)/fox.fbk -o $(OUT)/fox-extract
	$(FURBAKE) bake fixtures/real/BoxVertexColors.glb -o $(OUT)/grass-box.fbk --preset grass --png-dir $(OUT)/grass-png
	$(FURBAKE) inspect --json $(OUT)/grass-box.fbk > $(OUT)/grass-box.json
	@echo "demo done: open $(OUT)/fox-png/shells_grid.png and $(OUT)/fox-png/fins.png"

test:
	$(CARGO) test --workspace

bench:
	$(CARGO) bench --workspace

fmt:
	$(CARGO) fmt --all

clippy:
	$(CARGO) clippy --workspace --all-targets -- -D warnings

clean-out:
	rm -rf out

# Regenerate the golden pack checksums and the committed v1 pack (after an intended change).
golden:
	FURBAKE_BLESS=1 $(CARGO) test -p furbake-cli --test cli golden
