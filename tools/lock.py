"""Write ``requirements.lock``: every distribution ``make setup`` installs, at one exact
version each, with the SHA-256 hashes of every file the package index has for it.

``make lock`` runs this.  It resolves the ranges of ``pyproject.toml`` (its ``dev`` extra:
the package, every optional part, the test tools, pip, setuptools and uv) with uv's
resolver, for CPython 3.11 (the Python of Blender 4.2 to 5.0) on every platform, in two
steps:

1. **The Blender extension's floor.**  The distributions the add-on imports
   (``blender_addon/_deps.py``) are resolved against the oldest NumPy a supported Blender
   ships (Blender 4.2: NumPy 1.24.3, ``tools/blender_venvs.py``): the newest versions that
   still run on it (SciPy, contourpy, ...).
2. **The environment.**  The ``dev`` extra is resolved with those versions as
   constraints, so the extension bundles exactly the versions the tests ran with
   (``tools/build_blender_extension.py`` reads its wheel list from the lock).

uv's universal resolution also writes entries for later Pythons; those that apply to no
CPython 3.11 platform are left out (the lock is for 3.11).  uv does not read pip's
configuration: the package indexes pip uses here (``pip config list``: index-url,
extra-index-url, find-links, constraint) are passed to it explicitly, the main index
first, so that the hashes are those of the files on it.

The versions already in the lock are kept while the ranges allow them (uv's preferences,
as pip-compile does): ``make lock`` after a change of pyproject.toml moves only what it
must, and run twice it writes the same file.  ``--upgrade`` (``make lock-upgrade``) takes
the newest versions the ranges allow instead.

Usage: .venv/bin/python tools/lock.py [--upgrade] [--output FILE]
"""

from __future__ import annotations

import argparse
import importlib.util
import os
import re
import shlex
import subprocess
import sys
import tomllib
from pathlib import Path

from packaging.markers import Marker
from packaging.requirements import Requirement
from packaging.utils import canonicalize_name

REPO = Path(__file__).resolve().parents[1]
LOCK = REPO / "requirements.lock"
WORK = REPO / "build" / "lock"
PYTHON = "3.11"
DEFAULT_INDEX = "https://pypi.org/simple"
#: The platforms the lock is for (the extension's, and Linux x86-64 for make setup).
ENVIRONMENTS = {
    "linux-x64": {"sys_platform": "linux", "platform_system": "Linux",
                  "platform_machine": "x86_64", "os_name": "posix"},
    "windows-x64": {"sys_platform": "win32", "platform_system": "Windows",
                    "platform_machine": "AMD64", "os_name": "nt"},
    "macos-arm64": {"sys_platform": "darwin", "platform_system": "Darwin",
                    "platform_machine": "arm64", "os_name": "posix"},
    "macos-x64": {"sys_platform": "darwin", "platform_system": "Darwin",
                  "platform_machine": "x86_64", "os_name": "posix"},
}


def marker_env(platform: str, python: str = PYTHON, extra: str = "") -> dict:
    """The environment markers of CPython ``python`` on ``platform`` (a key of ENVIRONMENTS)."""
    return {"python_version": python, "python_full_version": python + ".0",
            "implementation_name": "cpython", "platform_python_implementation": "CPython",
            "platform_release": "", "platform_version": "", "extra": extra,
            **ENVIRONMENTS[platform]}


def _load(path: Path, name: str):
    spec = importlib.util.spec_from_file_location(name, path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def addon_distributions() -> list[str]:
    """The third-party distributions the add-on imports (``blender_addon/_deps.py``),
    less NumPy (Blender's own) and render_inspect (shipped as source)."""
    deps = _load(REPO / "blender_addon" / "_deps.py", "render_inspect_addon_deps")
    names = {canonicalize_name(dist) for _, dist, _ in deps.ALL}
    return sorted(names - {"numpy", "render-inspect"})


def blender_numpy_floor() -> str:
    """The oldest NumPy a supported Blender ships (``tools/blender_venvs.py``)."""
    venvs = _load(REPO / "tools" / "blender_venvs.py", "render_inspect_blender_venvs")
    return min(venvs.NUMPY.values(), key=lambda v: tuple(int(p) for p in v.split(".")))


def pyproject_requirements() -> dict[str, Requirement]:
    """{name: requirement} of every dependency pyproject.toml names (core and extras)."""
    project = tomllib.loads((REPO / "pyproject.toml").read_text())["project"]
    out = {}
    for text in [*project["dependencies"],
                 *(r for reqs in project["optional-dependencies"].values() for r in reqs)]:
        req = Requirement(text)
        out.setdefault(canonicalize_name(req.name), req)
    return out


def pip_sources() -> list[str]:
    """uv's index options for pip's configuration here, the main index first (highest
    priority: the lock's hashes are those of its files; the others hold copies)."""
    res = subprocess.run([sys.executable, "-m", "pip", "config", "list"], capture_output=True,
                         text=True, check=True)
    conf: dict[str, str] = {}
    for line in res.stdout.splitlines():
        key, _, value = line.partition("=")
        conf[key.split(".", 1)[-1]] = value.strip().strip("'\"")
    env = {k: os.environ[f"PIP_{k.upper().replace('-', '_')}"]
           for k in ("index-url", "extra-index-url", "find-links", "constraint")
           if f"PIP_{k.upper().replace('-', '_')}" in os.environ}
    conf.update(env)
    indexes = [conf.get("index-url", DEFAULT_INDEX)] + conf.get("extra-index-url", "").split()
    args = []
    for url in indexes:
        if url.startswith("file://") and not Path(url[7:]).is_dir():
            continue
        args += ["--index", url]
    for path in conf.get("find-links", "").split():
        if Path(path).is_dir():
            args += ["--find-links", path]
    for path in conf.get("constraint", "").split():
        if Path(path).is_file():
            args += ["--constraint", path]
    return args


def uv_compile(inputs: list[str], output: Path, extra: list[str], *,
               prefer: Path | None = None) -> None:
    """``uv pip compile`` into ``output``; the versions of ``prefer`` (a lock) are kept
    where they still fit (uv reads the output file's pins as preferences)."""
    if prefer is not None and prefer.is_file():
        output.write_text(prefer.read_text())
    elif output.exists():
        output.unlink()
    cmd = [sys.executable, "-m", "uv", "pip", "compile", *inputs, "--universal",
           "--python-version", PYTHON, "--generate-hashes", "--index-strategy",
           "unsafe-best-match", "--custom-compile-command", "make lock", "--quiet",
           *pip_sources(), *extra, "--output-file", str(output)]
    res = subprocess.run(cmd, cwd=REPO, capture_output=True, text=True)
    if res.returncode != 0:
        raise SystemExit(f"uv pip compile failed:\n{shlex.join(cmd)}\n{res.stderr}")


ENTRY = re.compile(r"^([A-Za-z0-9][A-Za-z0-9._-]*)==([^\s;\\]+)(?:\s*;\s*([^\\]+?))?\s*\\?$")


def entries(text: str) -> list[tuple[str, str, str | None, list[str]]]:
    """(name, version, marker, lines) of each entry of a uv-compiled requirements file;
    the header comes as name ''."""
    out: list = [("", "", None, [])]
    for line in text.splitlines():
        m = ENTRY.match(line)
        if m:
            out.append((canonicalize_name(m.group(1)), m.group(2), m.group(3), [line]))
        else:
            out[-1][3].append(line)
    return out


def for_python(text: str) -> str:
    """Leave out the entries whose markers hold on no CPython 3.11 platform."""
    kept = []
    for name, version, marker, lines in entries(text):
        if marker and not any(Marker(marker).evaluate(marker_env(p)) for p in ENVIRONMENTS):
            continue
        kept += lines
    return "\n".join(kept) + "\n"


def pins(text: str) -> dict[str, str]:
    return {name: version for name, version, _, _ in entries(text) if name}


def read_lock(path: Path = LOCK) -> list[dict]:
    """The lock's entries: ``name`` (canonical), ``version``, ``marker`` (or None) and
    ``hashes`` (``sha256:...``)."""
    out = []
    for name, version, marker, lines in entries(path.read_text()):
        if name:
            hashes = [h for line in lines for h in re.findall(r"--hash=(sha256:[0-9a-f]{64})", line)]
            out.append({"name": name, "version": version, "marker": marker, "hashes": hashes})
    return out


def applies(entry: dict, platform: str) -> bool:
    """Whether a lock entry is installed on ``platform`` (CPython 3.11)."""
    return not entry["marker"] or Marker(entry["marker"]).evaluate(marker_env(platform))


def constraints(path: Path = LOCK) -> str:
    """The lock as a pip constraints file without hashes (``name==version ; marker``)."""
    return "".join(f"{e['name']}=={e['version']}" + (f" ; {e['marker']}" if e["marker"] else "")
                   + "\n" for e in read_lock(path))


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--output", type=Path, default=LOCK)
    p.add_argument("--upgrade", action="store_true",
                   help="the newest versions the ranges allow (else the lock's are kept)")
    args = p.parse_args(argv)
    prefer = None if args.upgrade else args.output
    WORK.mkdir(parents=True, exist_ok=True)

    # 1. the add-on's distributions on the oldest NumPy a supported Blender ships
    numpy_floor = blender_numpy_floor()
    ranges = pyproject_requirements()
    floor_in = WORK / "blender-floor.in"
    floor_in.write_text("# the add-on's imports (blender_addon/_deps.py) on Blender 4.2's NumPy\n"
                        + "".join(f"{ranges.get(n, n)}\n" for n in addon_distributions())
                        + f"numpy=={numpy_floor}\n")
    floor_out = WORK / "blender-floor.txt"
    uv_compile([str(floor_in.relative_to(REPO))], floor_out, ["--no-annotate", "--no-header"],
               prefer=prefer)
    floor = {n: v for n, v in pins(for_python(floor_out.read_text())).items() if n != "numpy"}
    constraints = WORK / "blender-floor-constraints.txt"
    constraints.write_text("".join(f"{n}=={v}\n" for n, v in sorted(floor.items())))

    # 2. the whole environment, with the add-on's versions as constraints
    raw = WORK / "requirements.raw"
    uv_compile(["pyproject.toml", "--extra", "dev", "--constraint",
                str(constraints.relative_to(REPO))], raw, [], prefer=prefer)
    text = for_python(raw.read_text())
    header = ("# Every distribution `make setup` installs (CPython 3.11), exact versions and\n"
              "# hashes: written by tools/lock.py from the ranges in pyproject.toml (its dev extra)\n"
              f"# with the add-on's dependencies held to versions that run on NumPy {numpy_floor}\n"
              "# (Blender 4.2's); entries for later Pythons left out.\n")
    args.output.write_text(header + text)
    locked = pins(text)
    print(f"{args.output.name}: {len(locked)} distributions; the add-on's "
          f"{len(floor)} held to NumPy {numpy_floor}: "
          + ", ".join(f"{n} {v}" for n, v in sorted(floor.items()) if n in locked))
    return 0


if __name__ == "__main__":
    sys.exit(main())
