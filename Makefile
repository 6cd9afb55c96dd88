# The two commands a newcomer types: `make demo` and `make test`.
PY      ?= python3
VENV    := .venv
VPY     := $(VENV)/bin/python
STAMP   := $(VENV)/.setup-stamp
LOCK    := requirements.lock

.PHONY: setup demo test test-quick test-fast bench regress regress-update system-deps clean lock lock-upgrade

setup: $(STAMP)

# System library for Mitsuba's LLVM backend (Debian's LLVM 14/15 crash Dr.Jit).
# Installed when we can (root + apt); otherwise the code falls back to scalar_rgb.
system-deps:
	@if [ ! -e /usr/lib/x86_64-linux-gnu/libLLVM-19.so.1 ] && [ ! -e /usr/lib/x86_64-linux-gnu/libLLVM-19.so ]; then \
	  if [ "$$(id -u)" = "0" ] && command -v apt-get >/dev/null; then \
	    (apt-get install -y -q libllvm19 chromium >/dev/null 2>&1 || (apt-get update -q >/dev/null 2>&1 && apt-get install -y -q libllvm19 chromium >/dev/null 2>&1)) \
	      || echo "note: could not install libllvm19; Mitsuba will use scalar_rgb"; \
	  else echo "note: not root, libllvm19 not installed; Mitsuba will use scalar_rgb"; fi; \
	fi
	@if ! command -v chromium >/dev/null && [ "$$(id -u)" = "0" ] && command -v apt-get >/dev/null; then \
	  apt-get install -y -q chromium >/dev/null 2>&1 || (apt-get update -q >/dev/null 2>&1 && apt-get install -y -q chromium >/dev/null 2>&1) \
	    || echo "note: could not install chromium; the report screenshot check needs it"; fi

# .venv holds exactly the lock (made anew when the lock changes): every distribution at
# its locked version, each file checked against the lock's hashes, wheels only; then
# render_inspect itself, editable, built with the locked setuptools.
# Its bytecode is written at once (an environment with PYTHONDONTWRITEBYTECODE set would
# otherwise compile the package's sources again in every command it runs).
$(STAMP): $(LOCK) pyproject.toml
	@$(MAKE) --no-print-directory system-deps
	$(PY) -m venv --clear $(VENV)
	$(VPY) -m pip install -q --require-hashes --no-deps --only-binary=:all: -r $(LOCK)
	$(VPY) -m pip install -q --no-deps --no-build-isolation -e .
	$(VPY) -m compileall -q render_inspect
	$(VPY) -m render_inspect.pipeline._warmup
	@touch $(STAMP)

# requirements.lock anew from the ranges in pyproject.toml (tools/lock.py: uv's resolver,
# the lock's versions kept where they still fit); lock-upgrade takes the newest instead.
lock: setup
	$(VPY) tools/lock.py

lock-upgrade: setup
	$(VPY) tools/lock.py --upgrade

demo: setup
	$(VENV)/bin/render-inspect demo --out out/demo

# The test tiers (docs/contributing.md): test-quick is the developer's loop (units,
# contracts, messages, small forward models; no process started, no render, no
# simulation over 200,000 samples, no test over 6 s of CPU: tests/conftest.py fails a light
# test that does any);
# test is everything, CI's, on parallel workers (pytest-xdist from the lock).
XDIST   ?= -n 2 --dist loadgroup
QUICK   := not slow and not mitsuba and not blender and not browser and not gpu

test: setup
	$(VPY) -m pytest -q $(XDIST)

test-quick: setup
	$(VPY) -m pytest -q $(XDIST) -m "$(QUICK)"

# Everything but the slow tests (Mitsuba, Blender and browser tests included).
test-fast: setup
	$(VPY) -m pytest -q $(XDIST) -m "not slow"

bench: setup
	ONLY=$(ONLY) $(VPY) benchmarks/run_all.py

# The image regression suite alone (make test runs it too); regress-update makes the
# references anew after an intended change to the images (commit them with the change).
regress: setup
	$(VENV)/bin/render-inspect regress --out out/regress

regress-update: setup
	$(VENV)/bin/render-inspect regress --update --out out/regress

clean:
	rm -rf out .pytest_cache

# The self-contained Blender extension, one zip per platform (linux-x64, windows-x64,
# macos-arm64, macos-x64): the add-on, render_inspect as source and the wheels of what the
# add-on imports at the versions of requirements.lock, built with the blender_ext.py that
# ships inside Blender: dist/render_inspect-<version>-<platform>.zip (and the table of
# sizes in docs/blender.md).
.PHONY: blender-addon blender-venvs
blender-addon: setup
	$(VPY) tools/build_blender_extension.py --output-dir dist --update-docs

# Virtualenvs with only bpy 4.2 LTS, 4.5 LTS and 5.0 and the NumPy each Blender ships
# (.venv-blender/), for the extension tests (the tests make them too when missing).
blender-venvs: setup
	$(VPY) tools/blender_venvs.py
