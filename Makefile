# mimicrete: every target sets itself up on a fresh machine (venv in .venv, pinned requirements,
# the native module built in release mode) and then does its job. `make help` lists them.
SHELL := /bin/bash
VENV := .venv
PY := $(VENV)/bin/python
PIP := $(VENV)/bin/pip
STAMP := $(VENV)/.requirements.stamp
NATIVE_STAMP := $(VENV)/.native.stamp
RUST_SRC := $(shell find crates -name '*.rs' -o -name Cargo.toml -o -path '*/tasks/*.toml' 2>/dev/null) Cargo.toml Cargo.lock pyproject.toml

.PHONY: help setup native web demos demos-row demos-place demos-gen-place experiments train test test-rs test-py figures bench lint fmt experiments clean export-venv

help: ## list the targets
	@grep -E '^[a-z-]+:.*## ' $(MAKEFILE_LIST) | sed -E 's/:.*## /\t/' | column -t -s $$'\t'

$(PY):
	python3 -m venv $(VENV)

$(STAMP): $(PY) requirements/base.txt requirements/dev.txt requirements/robot.txt requirements/constraints.txt
	$(PIP) install --quiet --upgrade pip
	$(PIP) install --quiet -r requirements/dev.txt -c requirements/constraints.txt
	touch $@

setup: $(STAMP) ## create or reuse .venv and install the pinned requirements

$(NATIVE_STAMP): $(STAMP) $(RUST_SRC)
	VIRTUAL_ENV=$(abspath $(VENV)) PATH=$(abspath $(VENV))/bin:$$PATH maturin develop --release --locked
	touch $@

native: $(NATIVE_STAMP) ## build mimicrete._native into .venv (maturin develop --release)

# The teleop page: pinned npm packages (web/package-lock.json) bundled by esbuild into the
# package's static folder (build output, git-ignored), served by `mimicrete teleop`.
WEB_STATIC := python/mimicrete/teleop/static
WEB_STAMP := $(WEB_STATIC)/.stamp
WEB_SRC := $(wildcard web/src/*.js) web/index.html web/build.mjs web/package.json web/package-lock.json
CHROMIUM := /usr/bin/chromium

$(WEB_STAMP): $(WEB_SRC)
	cd web && npm ci --no-audit --no-fund && npm run build
	touch $@

# The browser tests drive Debian's Chromium through Playwright (no Playwright browser download).
$(CHROMIUM):
	apt-get update
	apt-get install -y --no-install-recommends chromium fonts-dejavu-core

web: $(WEB_STAMP) $(CHROMIUM) ## build the teleop page into $(WEB_STATIC); install chromium if missing

HANDS := data/hands/suction
DEMOS := demos/suction

$(DEMOS)/.done: $(NATIVE_STAMP) $(wildcard python/mimicrete/demonstrator/*.py python/mimicrete/teleop/*.py python/mimicrete/gestures/*.py python/mimicrete/hands/*.py)
	$(VENV)/bin/mimicrete synth-hands --task suction --episodes 60 --seed 0 --out $(HANDS)
	$(VENV)/bin/mimicrete convert $(HANDS) --task suction --out $(DEMOS)
	touch $@

demos: $(DEMOS)/.done ## 60 scripted hand demonstrations -> MCAP demos in demos/suction

ROW_HANDS := data/hands/row
ROW_DEMOS := demos/row

$(ROW_DEMOS)/.done: $(NATIVE_STAMP) $(wildcard python/mimicrete/demonstrator/*.py python/mimicrete/teleop/*.py python/mimicrete/gestures/*.py python/mimicrete/hands/*.py)
	$(VENV)/bin/mimicrete synth-hands --task row --episodes 5 --seed 0 --out $(ROW_HANDS)
	$(VENV)/bin/mimicrete convert $(ROW_HANDS) --task row --out $(ROW_DEMOS) --overwrite
	touch $@

demos-row: $(ROW_DEMOS)/.done ## 5 scripted rows of tiles (TileRow) -> MCAP demos in demos/row (configs/row_fewdemo.yaml)

PLACE_HANDS := data/hands/place
PLACE_DEMOS := demos/place
PLACE_GEN := demos/gen_place5_x4

$(PLACE_DEMOS)/.done: $(NATIVE_STAMP) $(wildcard python/mimicrete/demonstrator/*.py python/mimicrete/teleop/*.py python/mimicrete/gestures/*.py python/mimicrete/hands/*.py)
	$(VENV)/bin/mimicrete synth-hands --task place --episodes 60 --seed 0 --out $(PLACE_HANDS)
	$(VENV)/bin/mimicrete convert $(PLACE_HANDS) --task place --out $(PLACE_DEMOS) --overwrite
	touch $@

demos-place: $(PLACE_DEMOS)/.done ## 60 scripted tiles set down square (TilePlace) -> MCAP demos in demos/place

$(PLACE_GEN)/.done: $(PLACE_DEMOS)/.done $(wildcard python/mimicrete/demogen/*.py)
	$(VENV)/bin/mimicrete demogen --demos $(PLACE_DEMOS) --source-count 5 --count 500 --starts wide --seed 0 --speed 4 --out $(PLACE_GEN) --overwrite
	touch $@

demos-gen-place: $(PLACE_GEN)/.done ## 500 TilePlace demos at the wide starts from the first 5 of demos/place, played 4x faster (demogen) in demos/gen_place5_x4

train: $(PLACE_DEMOS)/.done ## the main job (TilePlace) end to end: synthetic hands -> demos -> generated demos -> train -> eval -> plots
	$(PY) train.py

test-rs: ## Rust tests of every crate
	cargo test --workspace --release --locked

EXP_STAMP := $(VENV)/.experiments.stamp
EXPERIMENTS_ARGS ?=

$(EXP_STAMP): $(STAMP) requirements/experiments.txt
	$(PIP) install --quiet -r requirements/experiments.txt -c requirements/constraints.txt
	touch $@

experiments: $(NATIVE_STAMP) $(EXP_STAMP) ## Table 3 x 3 seeds on Ray Tune (resumable), then docs/RESULTS.md; flags via EXPERIMENTS_ARGS
	$(PY) -m mimicrete.experiments $(EXPERIMENTS_ARGS)

# lerobot 0.4.4 pins torch<2.11 and numpy<2.3, which clash with ours: tests/export loads what
# `mimicrete export --format lerobot` wrote with lerobot's LeRobotDataset in this second venv,
# in a subprocess. Measured here: 5.6 min to install, 8.3 GB on disk (4.3 GB of it CUDA wheels).
EXPORT_VENV := .venv-export
EXPORT_STAMP := $(EXPORT_VENV)/.requirements.stamp

$(EXPORT_STAMP): requirements/export-test.txt
	python3 -m venv $(EXPORT_VENV)
	$(EXPORT_VENV)/bin/pip install --quiet -r requirements/export-test.txt
	touch $@

export-venv: $(EXPORT_STAMP) ## the test-only lerobot venv (.venv-export) tests/export loads datasets with

test-py: $(NATIVE_STAMP) $(EXP_STAMP) $(WEB_STAMP) $(CHROMIUM) $(EXPORT_STAMP) ## Python tests
	$(PY) -m pytest tests -q --runslow

# In order, the lint first: a formatting, clippy or ruff slip fails in a minute, before the long
# tests. clippy runs in test-rs's release profile, so the build scripts and proc-macros it compiles
# are the ones the test build reuses.
test: ## the lint, then all tests (what CI runs: .ci/run)
	$(MAKE) lint
	$(MAKE) test-rs
	$(MAKE) test-py

# The README's screenshots of the live page (docs/figures/teleop_page.png, teleop_gestures.png):
# the page tests that take them, told to keep a copy there (tests alone write only to tmp dirs).
FIGURE_TESTS := tests/teleop/test_live_page.py::test_suction_episode_recorded_live_in_the_browser \
	tests/teleop/test_gesture_mode_page.py::test_page_records_iwer_poses_trains_and_shows_held_out_accuracy

# docs/figures/scene.png: the TileSuction env's own render (top and side views) after reset(seed=0);
# docs/figures/tile_row.png: the same for TileRow-v0 (docs/tasks.md, "A row of tiles").
# docs/figures/group3_episode.gif: the deterministic evaluation episode (seed 10000) of the group-3
# policy the tests keep, tests/learn/data/group3_policy.pt (how it was trained: its README), as
# `mimicrete eval --video 1 --video-format gif` records it, in a temporary run dir (no training).
# The learning curves and the demos figures come from run outputs: `python -m
# mimicrete.experiments.report` (fig7*.png, gail_loss.png), `... demos_needed` and `... peers report`.
figures: $(NATIVE_STAMP) $(WEB_STAMP) $(CHROMIUM) ## the README's scene picture, episode GIF and page screenshots into docs/figures
	$(PY) -c "import gymnasium as gym, matplotlib.pyplot as plt, mimicrete; e = gym.make('mimicrete/TileSuction-v0', render_mode='rgb_array'); e.reset(seed=0); plt.imsave('docs/figures/scene.png', e.render())"
	$(PY) -c "import gymnasium as gym, matplotlib.pyplot as plt, mimicrete; e = gym.make('mimicrete/TileRow-v0', render_mode='rgb_array'); e.reset(seed=0); plt.imsave('docs/figures/tile_row.png', e.render())"
	$(PY) -c "import shutil, tempfile; from pathlib import Path; from mimicrete.learn import video; d = Path(tempfile.mkdtemp()); shutil.copy('tests/learn/data/group3_policy.pt', d / 'policy.pt'); ep = video.record_run_videos(d, 1, None, 'gif')[0]; shutil.copy(d / 'videos' / ep.file, 'docs/figures/group3_episode.gif'); shutil.rmtree(d); print('docs/figures/group3_episode.gif:', ep)"
	$(PY) -m pytest $(FIGURE_TESTS) -q --runslow --figures docs/figures

BENCH_STAMP := $(VENV)/.bench.stamp
$(BENCH_STAMP): $(STAMP) requirements/bench.txt
	$(PIP) install --quiet -r requirements/bench.txt -c requirements/constraints.txt
	touch $@

bench: $(NATIVE_STAMP) $(BENCH_STAMP) $(WEB_STAMP) $(CHROMIUM) ## print every benchmark (installs the peers: mujoco, ikpy, SB3)
	$(PY) -m mimicrete.bench

# The crates' lint levels are Cargo.toml's [workspace.lints]; ruff is pinned (requirements/dev.txt).
lint: $(STAMP) ## fmt, clippy (-D warnings), ruff
	cargo fmt --all --check
	cargo clippy --workspace --all-targets --release --locked -- -D warnings
	$(VENV)/bin/ruff check python tests

fmt: ## format Rust and Python
	cargo fmt --all
	$(VENV)/bin/ruff format python tests

clean: ## remove build products (keeps .venv)
	cargo clean
