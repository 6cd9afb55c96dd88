"""Virtual environments with nothing but ``bpy`` (Blender as a Python module), for the
extension tests: ``.venv-blender/bpy-<version>/``.

Each holds ``bpy==<version>`` and the NumPy that Blender version ships (:data:`NUMPY`:
the ``bpy`` wheels do not all pin it, and 4.2 would otherwise get NumPy 2), and not
render_inspect: the extension must bring it.  Made once (about a minute and 1 GB each) and
reused; ``make blender-venvs`` or the tests call this.

Usage: python tools/blender_venvs.py [VERSION ...]   (default: every tested version)
"""

from __future__ import annotations

import fcntl
import os
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
ROOT = REPO / ".venv-blender"
#: The Blender versions the extension is tested with and the NumPy each ships (its build
#: files: 4.2 LTS pins 1.24.3; 4.5 LTS and 5.0 pin 1.26.4).  4.2 is the manifest's minimum
#: and its NumPy the oldest the extension's wheels must run on (tools/lock.py).
NUMPY = {"4.2.23": "1.24.3", "4.5.15": "1.26.4", "5.0.1": "1.26.4"}
#: RENDER_INSPECT_BPY_VERSIONS (comma-separated, e.g. "4.5.15") picks some of them.
VERSIONS = tuple(v.strip() for v in os.environ.get("RENDER_INSPECT_BPY_VERSIONS", "").split(",")
                 if v.strip()) or tuple(NUMPY)


def numpy_for(version: str) -> str:
    """The NumPy Blender ``version`` ships (that of the same major.minor in NUMPY)."""
    for known, numpy in NUMPY.items():
        if known.split(".")[:2] == version.split(".")[:2]:
            return numpy
    raise SystemExit(f"no NumPy known for Blender {version}: add it to NUMPY in {__file__}")


def venv_python(version: str) -> Path:
    return ROOT / f"bpy-{version}" / "bin" / "python"


def ensure(version: str, *, env: dict | None = None) -> Path:
    """Create ``.venv-blender/bpy-<version>`` unless it is complete; return its python."""
    ROOT.mkdir(exist_ok=True)
    target = ROOT / f"bpy-{version}"
    stamp = target / ".complete"
    with open(ROOT / f".bpy-{version}.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)  # two test runs at once: one builds, one waits
        if stamp.is_file():
            return venv_python(version)
        base = os.environ.get("RENDER_INSPECT_BASE_PYTHON", sys.executable)
        subprocess.run([base, "-m", "venv", "--clear", str(target)], check=True, env=env)
        subprocess.run([str(venv_python(version)), "-m", "pip", "install", "--quiet",
                        f"bpy=={version}", f"numpy=={numpy_for(version)}"],
                       check=True, env=env)
        out = subprocess.run([str(venv_python(version)), "-c",
                              "import bpy, numpy; print(bpy.app.version_string, numpy.__version__)"],
                             check=True, capture_output=True, text=True, env=env)
        stamp.write_text(out.stdout)
    return venv_python(version)


if __name__ == "__main__":
    for v in sys.argv[1:] or VERSIONS:
        print(v, "->", ensure(v))
