# Two commands do all the set-up on a fresh Debian/Ubuntu machine: `make run` and `make test`.
SHELL := /bin/bash
PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed
# Qt's xcb plugin, EGL/Mesa (software OpenGL), a virtual X server for headless GUI tests, and a
# C++ compiler with Python's headers (meshoptimizer's binding is built at install).
APT_PKGS := g++ python3-dev libxcb-cursor0 libxcb-icccm4 libxcb-keysyms1 libxcb-image0 libxcb-render-util0 \
	libxcb-xinerama0 libxcb-xkb1 libxcb-shape0 libxcb-randr0 libxkbcommon-x11-0 \
	libdbus-1-3 libfontconfig1 xvfb xauth libegl1 libgl1 libgl1-mesa-dri libegl-mesa0

.PHONY: bench-tcr bench-cps bench-photons run test sysdeps venv lint bench clean dist dist-check \
	install-desktop

sysdeps:
	@if ! command -v dpkg-query >/dev/null; then \
		echo "note: not a Debian/Ubuntu system; make sure Qt xcb libraries, Mesa EGL and Xvfb are installed"; exit 0; fi; \
	missing=$$(for p in $(APT_PKGS); do \
		dpkg-query -W -f='$${Status}' $$p 2>/dev/null | grep -q 'ok installed' || echo $$p; done); \
	if [ -n "$$missing" ]; then \
		if [ "$$(id -u)" = 0 ]; then \
			echo "Installing system packages:" $$missing; \
			apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends $$missing; \
		else \
			echo "Missing system packages. Run this, then make again:"; \
			echo "  sudo apt-get update && sudo apt-get install -y" $$missing; exit 1; \
		fi; \
	fi

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install -q --upgrade pip
	$(PY) -m pip install -q -e '.[test]'
	# .[reference] without its numpy<2 pin (pyproject.toml): Cycles for tests/test_reference.py
	$(PY) -m pip install -q zstandard requests cython && $(PY) -m pip install -q --no-deps 'bpy==5.0.1'
	touch $@

venv: $(STAMP)

# Opens the window on the built-in showroom; with no display, runs the walkthrough headless into out/.
run: sysdeps $(STAMP)
	$(VENV)/bin/vrpreview --scene showroom

lint: $(STAMP)
	$(VENV)/bin/ruff check --no-cache app ui render assets tests
	$(VENV)/bin/ruff format --check --no-cache app ui render assets tests
	$(VENV)/bin/lint-imports
	$(VENV)/bin/mypy

test: sysdeps $(STAMP) lint
	xvfb-run -a -s "-screen 0 1920x1080x24" $(PY) -m pytest -q -p no:cacheprovider

bench: sysdeps $(STAMP)
	$(VENV)/bin/vrpreview bench --scene showroom --size 1280x720 --frames 120 --out out/bench-showroom.json

# The papers' experiments, one benchmark after another, tables printed at the end:
# bench-tcr (issue 3, ~13 min): the cube against distance, orbiting, gaze held, the showroom
# walkthrough, each with TCR off / ergonomics / psychology. bench-cps (issue 4): the corridor
# walk with 100 lights, Tables 1 and 2 of the CPS paper and the filters' image error.
bench-tcr: sysdeps $(STAMP)
	$(VENV)/bin/vrpreview experiments tcr --out out/bench-tcr

bench-cps: sysdeps $(STAMP)
	$(VENV)/bin/vrpreview experiments cps --out out/bench-cps

# bench-photons (issue 5): the photon-mapping paper's Tables 1-5 on the showroom and the
# comparison with scipy's cKDTree on the same photons and query points.
bench-photons: sysdeps $(STAMP)
	$(VENV)/bin/vrpreview experiments photons --out out/bench-photons

clean:
	rm -rf $(VENV) out build *.egg-info

# The wheel (dist/vrpreview-*.whl) and the one-folder app dist/vrpreview/ (PyInstaller,
# packaging/vrpreview.spec; about 1 min on 2 cores). build/lib is cleared so that no deleted module
# from an earlier build travels in the wheel. See packaging/README.md.
DIST_STAMP := $(VENV)/.dist-installed
$(DIST_STAMP): pyproject.toml $(STAMP)
	$(PY) -m pip install -q -e '.[test,dist]'
	touch $@

dist: $(DIST_STAMP)
	rm -rf build/lib build/bdist.* dist/vrpreview dist/vrpreview-*.whl
	$(PY) -m pip wheel -q --no-deps -w dist .
	$(VENV)/bin/pyinstaller --noconfirm --log-level WARN --distpath dist \
		--workpath build/pyinstaller packaging/vrpreview.spec
	@du -sh dist/vrpreview dist/vrpreview-*.whl

# The bundle's own render from an empty folder in a clean environment, against the venv's.
dist-check: dist
	$(PY) packaging/dist_check.py dist/vrpreview/vrpreview

# The menu entry, its icon and the model file types for this user (after installing the wheel
# or putting dist/vrpreview on PATH).
DATA_HOME ?= $(HOME)/.local/share
install-desktop:
	$(PYTHON) packaging/install_desktop.py --data-home "$(DATA_HOME)"
