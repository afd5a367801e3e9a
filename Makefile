# retrace: two commands on a fresh Debian machine.
#   make demo   renders the paper scene (out/paper.png), the bunny (out/bunny.png),
#               a textured scene (out/textured.png) and 24 frames of pan + zoom + a bouncing ball (out/anim/)
#   make test   runs the whole test suite (format, lints, unit and integration tests)
# Both install the Debian packages they need first (Embree, libclang for bindgen,
# Pillow for the test that reads our TGA frames with another decoder, the X
# libraries `retrace view` loads at run time, and an X server with xdotool and
# ImageMagick for the window's tests); `make test` also the OBJ test models
# and OpenImageIO's tools, which read our OpenEXR frames.

VIEW_PACKAGES := libxkbcommon-x11-0 libx11-xcb1 libxcursor1 libxi6 \
	xvfb xauth xdotool x11-apps imagemagick
DEBIAN_PACKAGES := libembree-dev libclang-dev pkg-config python3-pil $(VIEW_PACKAGES)
RETRACE := ./target/release/retrace

.PHONY: all deps build demo test test-deps test-deep fuzz lint test-embree4 bench clean farm-deps test-farm

all: demo

deps:
	@missing=""; \
	for pkg in $(DEBIAN_PACKAGES); do \
	  dpkg-query -W -f='$${Status}' $$pkg 2>/dev/null | grep -q "ok installed" || missing="$$missing $$pkg"; \
	done; \
	if [ -n "$$missing" ]; then \
	  echo "make: installing Debian packages:$$missing"; \
	  if [ "$$(id -u)" = 0 ]; then sudo=""; else sudo="sudo"; fi; \
	  $$sudo apt-get update -qq && \
	  DEBIAN_FRONTEND=noninteractive $$sudo apt-get install -y -qq --no-install-recommends $$missing; \
	fi

build: deps
	cargo build --release

demo: build
	@mkdir -p out
	$(RETRACE) render --spp 16 -o out/paper.png
	$(RETRACE) render scenes/bunny.toml --spp 16 -o out/bunny.png
	$(RETRACE) render scenes/textured.toml --spp 4 -o out/textured.png
	$(RETRACE) animate scenes/paper-all.toml --spp 4 --frames 0-23 -o out/anim/frame_####.png \
	  --dirty-image out/anim/traced_####.png --stats out/anim/stats.csv

# The library is linted without its optional features (the lab, the
# window, the farm) too: what only they use is dead code there, which the
# default build never shows.
lint: deps
	cargo fmt --all -- --check
	cargo clippy --all-targets -- -D warnings
	cargo clippy --lib --no-default-features -- -D warnings

# --all-targets builds the criterion benches too and runs each once, in
# test mode (a separate optimised `cargo bench --no-run` cost a fresh
# machine about 3 more minutes and checked nothing more). The library is
# then built and unit-tested without its optional features, so the
# renderer keeps working without winit, softbuffer and plotters.
test: lint test-deps
	cargo test --all-targets
	cargo build --lib --no-default-features
	cargo test --lib --no-default-features

# Debian's OBJ test models (the textured spider) for the test that renders
# them; OpenImageIO's iinfo and oiiotool for the test that reads our OpenEXR
# frames with programs written elsewhere (tests/it/exr.rs).
TEST_PACKAGES := assimp-testmodels openimageio-tools

test-deps:
	@$(MAKE) --no-print-directory deps DEBIAN_PACKAGES="$(DEBIAN_PACKAGES) $(TEST_PACKAGES)"


# The property tests with sixteen times their cases (release build).
test-deep: deps
	RETRACE_DEEP=1 cargo test --release --test it

# The loaders' fuzzing (tests/it/fuzz.rs) with fifty times its cases, from
# a fresh seed each run (release build; about 6 minutes on 2 cores).
fuzz: deps
	RETRACE_FUZZ=50 cargo test --release --test it -- fuzz::

# The whole suite against Embree 4 (Debian 13) in a chroot, with the same
# packages the tests need here; see .ci/embree4.sh.
test-embree4:
	EMBREE4_EXTRA_PACKAGES="$(filter-out libembree-dev libclang-dev pkg-config,$(DEBIAN_PACKAGES)) $(TEST_PACKAGES)" \
	  bash .ci/embree4.sh

# The paper's table with the scaling rows, into out/bench (report.md).
bench: build
	$(RETRACE) bench --only frame
	$(RETRACE) bench --only frame scenes/bunny.toml
	$(RETRACE) bench --scaling --out out/bench

# Slurm for `make test-farm`, without recommends (slurm-wlm would pull 39
# packages). The packages' scripts would start munged, slurmctld and slurmd
# on the system's default paths; a policy-rc.d that refuses keeps them off
# for the install (the test starts its own, in a private folder).
# ffmpeg: the assembly's MP4, which the test checks.
FARM_PACKAGES := slurmctld slurmd slurm-client munge ffmpeg

farm-deps:
	@missing=""; \
	for pkg in $(FARM_PACKAGES); do \
	  dpkg-query -W -f='$${Status}' $$pkg 2>/dev/null | grep -q "ok installed" || missing="$$missing $$pkg"; \
	done; \
	if [ -n "$$missing" ]; then \
	  echo "make: installing Debian packages:$$missing"; \
	  if [ "$$(id -u)" = 0 ]; then sudo=""; else sudo="sudo"; fi; \
	  guard=""; \
	  if [ ! -e /usr/sbin/policy-rc.d ]; then \
	    printf '#!/bin/sh\nexit 101\n' | $$sudo tee /usr/sbin/policy-rc.d >/dev/null && \
	    $$sudo chmod 755 /usr/sbin/policy-rc.d && guard=1; \
	  fi; \
	  $$sudo apt-get update -qq && \
	  DEBIAN_FRONTEND=noninteractive $$sudo apt-get install -y -qq --no-install-recommends $$missing; \
	  status=$$?; \
	  if [ -n "$$guard" ]; then $$sudo rm -f /usr/sbin/policy-rc.d; fi; \
	  exit $$status; \
	fi

# A real single-node Slurm, started in a private folder and stopped again:
# chunked renders, a cancelled and requeued task, a failed one
# (farm/test-farm.sh says what it checks). Needs root for the daemons.
test-farm: build farm-deps
	bash farm/test-farm.sh $(RETRACE)

clean:
	cargo clean
	rm -rf out
