# Two commands do all the set-up on a fresh Debian/Ubuntu machine: `make run` and `make test`.
SHELL := /bin/bash
PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed
# Qt's xcb plugin, EGL/Mesa (software OpenGL) and a virtual X server for headless GUI tests.
APT_PKGS := libxcb-cursor0 libxcb-icccm4 libxcb-keysyms1 libxcb-image0 libxcb-render-util0 \
	libxcb-xinerama0 libxcb-xkb1 libxcb-shape0 libxcb-randr0 libxkbcommon-x11-0 \
	libdbus-1-3 libfontconfig1 xvfb xauth libegl1 libgl1 libgl1-mesa-dri libegl-mesa0

.PHONY: bench-tcr run test sysdeps venv lint bench clean dist

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
	touch $@

venv: $(STAMP)

# Opens the window on the built-in showroom; with no display, runs the walkthrough headless into out/.
run: sysdeps $(STAMP)
	$(VENV)/bin/vrpreview --scene showroom

lint: $(STAMP)
	$(VENV)/bin/ruff check --no-cache app ui render assets tests

test: sysdeps $(STAMP) lint
	xvfb-run -a -s "-screen 0 1920x1080x24" $(PY) -m pytest -q -p no:cacheprovider

bench: sysdeps $(STAMP)
	$(VENV)/bin/vrpreview bench --scene showroom --size 1280x720 --frames 120 --out out/bench-showroom.json

# The TCR paper's experiments (issue 3): the cube against distance, orbiting (state 1), gaze held
# (states 2, 3), and the showroom walkthrough; TCR off against the presets, with image error
# against the TCR-off frame. About 10 minutes on 2 cores; tables printed at the end.
TCR_OUT := out/bench-tcr
TCR_RUNS := off:tcr.enabled=false ergonomics:tcr.preset=ergonomics psychology:tcr.preset=psychology
bench-tcr: sysdeps $(STAMP)
	@mkdir -p $(TCR_OUT)
	@for path in tcr_cube_distance tcr_cube_orbit tcr_cube_gaze showroom_walkthrough; do \
	  scene=tcr-cube; every=30; [ $$path = showroom_walkthrough ] && scene=showroom && every=20; \
	  for run in $(TCR_RUNS); do name=$${run%%:*}; set=$${run#*:}; \
	    $(VENV)/bin/vrpreview bench --scene $$scene --path $$path --frames 0 --compare-every $$every \
	      --set tcr.enabled=true --set $$set --out $(TCR_OUT)/$$path-$$name.json > /dev/null || exit 1; \
	  done; \
	done
	$(VENV)/bin/vrpreview report $(TCR_OUT)/*.json --group by_state --group by_gazed_level

clean:
	rm -rf $(VENV) out build *.egg-info

dist: $(STAMP)
	$(PY) -m pip wheel --no-deps -w dist .
