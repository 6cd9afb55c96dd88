# The two commands a newcomer types: `make demo` and `make test`.
PY      ?= python3
VENV    := .venv
VPY     := $(VENV)/bin/python
STAMP   := $(VENV)/.setup-stamp

.PHONY: setup demo test test-fast bench system-deps clean

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

$(STAMP): requirements.txt pyproject.toml
	@$(MAKE) --no-print-directory system-deps
	@test -x $(VPY) || $(PY) -m venv $(VENV)
	$(VPY) -m pip install -q --upgrade pip
	$(VPY) -m pip install -q -r requirements.txt
	$(VPY) -m pip install -q --no-deps -e .
	$(VPY) -m render_inspect.pipeline._warmup
	@touch $(STAMP)

demo: setup
	$(VENV)/bin/render-inspect demo --out out/demo

test: setup
	$(VPY) -m pytest -q

test-fast: setup
	$(VPY) -m pytest -q -m "not slow"

bench: setup
	ONLY=$(ONLY) $(VPY) benchmarks/run_all.py

clean:
	rm -rf out .pytest_cache

# Build the Blender extension zip (dist/render_inspect-<version>.zip) with Blender's own tool.
BLENDER_EXT = $(shell $(VPY) -c "import bpy,pathlib;print(pathlib.Path(bpy.utils.system_resource('SCRIPTS'))/'addons_core/bl_pkg/cli/blender_ext.py')" 2>/dev/null)
.PHONY: blender-addon
blender-addon: setup
	mkdir -p dist && $(VPY) $(BLENDER_EXT) build --source-dir blender_addon --output-dir dist
