"""Build the self-contained Blender extension: ``dist/render_inspect-<version>-<platform>.zip``.

Blender 4.2 to 5.0 run Python 3.11 and ship NumPy; everything else the add-on imports is
bundled, one zip per platform, built with the ``blender_ext.py`` that ships inside Blender
(here: inside the ``bpy`` package):

1. the add-on (``blender_addon/``) and render_inspect's own code as source
   (``_bundled/render_inspect``; without the regression references and other test data);
2. for each platform, the wheels of the distributions the add-on imports
   (``blender_addon/_deps.py``) and of what they require (their wheels' ``Requires-Dist``
   for that platform and Python 3.11), each at the version of ``requirements.lock`` and
   checked against the lock's hashes: ``pip download --require-hashes --only-binary``
   from the package index, unmodified;
3. a manifest per platform with those wheels and that platform, ``blender_ext.py build``
   and ``blender_ext.py validate``.

There is no list of wheels to keep by hand: the lock is the one list.  A dependency with
no wheel for a platform is left out of that platform's zip and named on stdout; the add-on
names it in its panel and disables the operations that need it.

``dist/blender_extension_build.json`` records each zip's size and wheels;
``--update-docs`` writes the table of sizes and wheel counts into docs/blender.md (a test
compares the table with a fresh build).

Usage::

    .venv/bin/python tools/build_blender_extension.py                    # all platforms
    .venv/bin/python tools/build_blender_extension.py --platforms linux-x64
    .venv/bin/python tools/build_blender_extension.py --update-docs      # and the docs table

It needs only ``packaging`` and a ``bpy`` to find ``blender_ext.py`` in (this Python's, or
``--blender-python``'s): nothing else installed here is read.
"""

from __future__ import annotations

import argparse
import email.parser
import json
import re
import shutil
import subprocess
import sys
import tempfile
import tomllib
import zipfile
from pathlib import Path

from packaging.requirements import Requirement
from packaging.utils import canonicalize_name, parse_wheel_filename

sys.path.insert(0, str(Path(__file__).resolve().parent))
import lock  # noqa: E402  (tools/lock.py: the lock and the platforms' markers)

REPO = Path(__file__).resolve().parents[1]
ADDON = REPO / "blender_addon"
PACKAGE = REPO / "render_inspect"
MANIFEST = ADDON / "blender_manifest.toml"
CACHE = REPO / "build" / "blender_wheels"
STAGE = REPO / "build" / "blender_extension"
DOCS = REPO / "docs" / "blender.md"

#: Python of Blender 4.2 LTS, 4.3, 4.4, 4.5 LTS and 5.0 (all 3.11).
PYTHON_VERSION = lock.PYTHON
#: Blender platform -> the pip platform tags accepted for it.  Linux: Blender 4.2+ needs
#: glibc 2.28, so manylinux up to 2_28; macOS: Blender 4.2+ needs macOS 11.2 (pip expands
#: ``macosx_11_0_*`` to every older tag and universal2), but SciPy 1.15 has Apple-silicon
#: wheels for macOS 12 and later only, so the macos-arm64 zip needs macOS 12.
PLATFORMS = {
    "linux-x64": [f"manylinux_2_{m}_x86_64" for m in range(28, 16, -1)]
    + ["manylinux2014_x86_64", "manylinux_2_5_x86_64", "manylinux1_x86_64"],
    "windows-x64": ["win_amd64"],
    "macos-arm64": ["macosx_12_0_arm64"],
    "macos-x64": ["macosx_11_0_x86_64"],
}
#: Shipped with Blender itself (bundling a second NumPy would break Blender), or Blender.
PROVIDED_BY_BLENDER = {"numpy", "bpy"}
#: What of render_inspect's source stays out of the extension: test data (the regression
#: cases and their reference images) and Python's caches.
PACKAGE_EXCLUDE = ("__pycache__", "*.pyc", "regression")

DOCS_BEGIN = "<!-- extension sizes: written by tools/build_blender_extension.py --update-docs -->"
DOCS_END = "<!-- end of extension sizes -->"


def log(msg: str) -> None:
    print(msg, flush=True)


def locked_versions() -> dict[str, dict]:
    """{name: lock entry} of requirements.lock."""
    return {e["name"]: e for e in lock.read_lock()}


def _requires(wheel: Path, extras: frozenset, platform: str) -> list[Requirement]:
    """The requirements a wheel declares (``Requires-Dist``) that apply on ``platform``
    with CPython 3.11 and the given extras."""
    with zipfile.ZipFile(wheel) as zf:
        meta = next(n for n in zf.namelist()
                    if n.endswith(".dist-info/METADATA") and n.count("/") == 1)
        msg = email.parser.Parser().parsestr(zf.read(meta).decode("utf-8"))
    out = []
    for text in msg.get_all("Requires-Dist") or ():
        req = Requirement(text)
        if req.marker is None or any(req.marker.evaluate(lock.marker_env(platform, extra=e))
                                     for e in ("", *extras)):
            out.append(req)
    return out


def _pip_download(dest: Path, platform: str, entries: list[dict]) -> subprocess.CompletedProcess:
    """``pip download`` of the locked versions of ``entries`` for ``platform``, with the
    lock's hashes (pip refuses a file whose hash the lock does not list)."""
    reqs = dest / "requirements.txt"
    reqs.write_text("".join(f"{e['name']}=={e['version']}"
                            + "".join(f" --hash={h}" for h in e["hashes"]) + "\n"
                            for e in entries))
    cmd = [sys.executable, "-m", "pip", "download", "--quiet", "--no-deps", "--only-binary=:all:",
           "--require-hashes", "--python-version", PYTHON_VERSION, "--implementation", "cp",
           "--dest", str(dest)]
    for tag in PLATFORMS[platform]:
        cmd += ["--platform", tag]
    return subprocess.run(cmd + ["-r", str(reqs)], capture_output=True, text=True)


def _fetch(platform: str, entries: list[dict], index: dict) -> list[str]:
    """Download the wheels of ``entries`` for ``platform`` into the cache (``index``: name
    -> file name, updated); return the ``name==version`` of those with no wheel."""
    dest = CACHE / platform
    todo = [e for e in entries
            if not (e["name"] in index and (dest / index[e["name"]]).is_file()
                    and str(parse_wheel_filename(index[e["name"]])[1]) == e["version"])]
    missing = []
    for batch in ([todo] if todo else []):
        with tempfile.TemporaryDirectory(dir=CACHE) as tmp:
            if _pip_download(Path(tmp), platform, batch).returncode != 0:
                batch_ok = []
                for e in batch:  # one at a time to find the ones that have no wheel here
                    one = Path(tmp) / e["name"]
                    one.mkdir()
                    res = _pip_download(one, platform, [e])
                    if res.returncode != 0:
                        missing.append(f"{e['name']}=={e['version']}")
                        log(f"  {platform}: no wheel for {e['name']}=={e['version']} "
                            f"({res.stderr.strip().splitlines()[-1]})")
                    else:
                        batch_ok += list(one.glob("*.whl"))
                files = batch_ok
            else:
                files = list(Path(tmp).glob("*.whl"))
            for f in files:
                name = canonicalize_name(str(parse_wheel_filename(f.name)[0]))
                shutil.move(str(f), dest / f.name)
                index[name] = f.name
    return missing


def platform_wheels(platform: str) -> tuple[list[Path], list[str]]:
    """The wheels the add-on needs on ``platform`` (the closure of its imports through the
    wheels' requirements, at the locked versions) and the ``name==version`` of those with
    no wheel for it."""
    dest = CACHE / platform
    dest.mkdir(parents=True, exist_ok=True)
    index_file = dest / "index.json"
    index = json.loads(index_file.read_text()) if index_file.is_file() else {}
    locked = locked_versions()
    wanted: dict[str, frozenset] = {}
    level = {(name, frozenset()) for name in lock.addon_distributions()}
    missing: list[str] = []
    while level:
        new = []
        for name, extras in sorted(level):
            if name in PROVIDED_BY_BLENDER:
                continue
            if name not in locked:
                raise SystemExit(f"{name} (needed on {platform}) is not in "
                                 f"{lock.LOCK.name}: run make lock")
            if name not in wanted or not extras <= wanted[name]:
                wanted[name] = wanted.get(name, frozenset()) | extras
                new.append(name)
        missing += _fetch(platform, [locked[n] for n in new], index)
        index_file.write_text(json.dumps(index, indent=1, sort_keys=True))
        level = set()
        for name in new:
            if f"{name}=={locked[name]['version']}" in missing:
                continue
            for req in _requires(dest / index[name], wanted[name], platform):
                level.add((canonicalize_name(req.name), frozenset(req.extras)))
    wheels = sorted((dest / index[n] for n in wanted
                     if n not in PROVIDED_BY_BLENDER
                     and f"{n}=={locked[n]['version']}" not in missing),
                    key=lambda p: p.name.lower())
    return wheels, sorted(missing)


def blender_ext(blender_python: str | None = None) -> Path:
    """The ``blender_ext.py`` that ships inside Blender: that of this Python's ``bpy``, or
    of the ``bpy`` of ``blender_python`` (a Python that has it)."""
    code = ("import bpy, os; print(os.path.join(bpy.utils.system_resource('SCRIPTS'), "
            "'addons_core', 'bl_pkg', 'cli', 'blender_ext.py'))")
    res = subprocess.run([blender_python or sys.executable, "-c", code], capture_output=True,
                         text=True)
    if res.returncode != 0:
        raise SystemExit("bpy is needed to find Blender's blender_ext.py: run this with the "
                         "project's .venv, or pass --blender-python")
    path = Path(res.stdout.strip().splitlines()[-1])
    if not path.is_file():
        raise SystemExit(f"blender_ext.py not found at {path}")
    return path


def manifest_for(platform: str, wheels: list[Path]) -> str:
    """The tracked manifest with this platform and its wheels (top-level keys go before
    the first table)."""
    text = MANIFEST.read_text()
    if re.search(r"(?m)^wheels\s*=", text):
        raise SystemExit(f"{MANIFEST.name} must not list wheels: the build writes them from the lock")
    text, n = re.subn(r"(?m)^platforms = \[.*?\]$", f'platforms = ["{platform}"]', text)
    if n != 1:
        raise SystemExit(f"{MANIFEST.name} must declare platforms on one line")
    body = "wheels = [\n" + "".join(f'  "./wheels/{w.name}",\n' for w in wheels) + "]\n\n"
    first_table = re.search(r"(?m)^\[", text)
    return text[:first_table.start()] + body + text[first_table.start():]


def stage(platform: str, wheels: list[Path]) -> Path:
    """The extension's source folder for ``platform``: the add-on, render_inspect's source
    under ``_bundled/``, the wheels, the manifest."""
    STAGE.mkdir(parents=True, exist_ok=True)
    # a folder of its own: two builds at once never remove each other's files
    root = Path(tempfile.mkdtemp(prefix=f"{platform}-", dir=STAGE)) / "extension"
    shutil.copytree(ADDON, root, ignore=shutil.ignore_patterns("__pycache__", "*.pyc", "wheels"))
    (root / "_bundled").mkdir()
    (root / "_bundled" / "__init__.py").write_text(
        '"""render_inspect\'s own code, shipped as source with the add-on."""\n')
    shutil.copytree(PACKAGE, root / "_bundled" / "render_inspect",
                    ignore=shutil.ignore_patterns(*PACKAGE_EXCLUDE))
    (root / "wheels").mkdir()
    for w in wheels:
        shutil.copy2(w, root / "wheels" / w.name)
    (root / "blender_manifest.toml").write_text(manifest_for(platform, wheels))
    return root


def docs_table(report: dict) -> str:
    rows = ["| Platform | Zip (MiB) | Wheels | Not available |", "| --- | ---: | ---: | --- |"]
    for platform in PLATFORMS:
        if platform in report:
            r = report[platform]
            rows.append(f"| {platform} | {r['size_mib']:.1f} | {r['wheels']} | "
                        + (", ".join(r["missing"]) or "-") + " |")
    return "\n".join(rows)


def update_docs(report: dict) -> None:
    text = DOCS.read_text()
    if DOCS_BEGIN not in text or DOCS_END not in text:
        raise SystemExit(f"{DOCS.name} has no lines {DOCS_BEGIN!r} ... {DOCS_END!r}")
    block = f"{DOCS_BEGIN}\n{docs_table(report)}\n{DOCS_END}"
    DOCS.write_text(re.sub(re.escape(DOCS_BEGIN) + r".*?" + re.escape(DOCS_END),
                           lambda _: block, text, flags=re.S))


def docs_rows() -> dict[str, dict]:
    """{platform: {size_mib, wheels, missing}} of the table in docs/blender.md."""
    text = DOCS.read_text()
    block = text[text.index(DOCS_BEGIN):text.index(DOCS_END)]
    out = {}
    for m in re.finditer(r"(?m)^\| (\S+) \| ([\d.]+) \| (\d+) \| (.*?) \|$", block):
        out[m.group(1)] = {"size_mib": float(m.group(2)), "wheels": int(m.group(3)),
                           "missing": [] if m.group(4) == "-" else m.group(4).split(", ")}
    return out


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--platforms", nargs="+", choices=sorted(PLATFORMS), default=list(PLATFORMS))
    p.add_argument("--output-dir", type=Path, default=REPO / "dist")
    p.add_argument("--blender-python", help="a Python with bpy, to find Blender's blender_ext.py "
                   "(default: this one)")
    p.add_argument("--update-docs", action="store_true",
                   help="write the sizes and wheel counts into docs/blender.md (all platforms)")
    args = p.parse_args(argv)
    if args.update_docs and set(args.platforms) != set(PLATFORMS):
        raise SystemExit("--update-docs needs every platform")

    manifest = tomllib.loads(MANIFEST.read_text())
    args.output_dir.mkdir(parents=True, exist_ok=True)
    ext = blender_ext(args.blender_python)
    report = {}
    for platform in args.platforms:
        wheels, missing = platform_wheels(platform)
        root = stage(platform, wheels)
        z = args.output_dir / f"{manifest['id']}-{manifest['version']}-{platform.replace('-', '_')}.zip"
        try:
            res = subprocess.run([sys.executable, str(ext), "build", "--source-dir", str(root),
                                  "--output-filepath", str(z)], capture_output=True, text=True)
        finally:
            shutil.rmtree(root.parent, ignore_errors=True)
        if res.returncode != 0 or not z.is_file():
            raise SystemExit(f"blender_ext.py build failed for {platform}:\n{res.stdout}\n{res.stderr}")
        check = subprocess.run([sys.executable, str(ext), "validate", str(z)],
                               capture_output=True, text=True)
        if check.returncode != 0:
            raise SystemExit(f"{z.name} does not validate:\n{check.stdout}\n{check.stderr}")
        report[platform] = {"zip": str(z), "size_mib": round(z.stat().st_size / 2**20, 1),
                            "wheels": len(wheels), "wheel_files": [w.name for w in wheels],
                            "missing": missing}
        log(f"built {z.name}: {report[platform]['size_mib']} MiB, {len(wheels)} wheels"
            + (f"; not available: {', '.join(missing)}" if missing else ""))
    (args.output_dir / "blender_extension_build.json").write_text(json.dumps(report, indent=2))
    if args.update_docs:
        update_docs(report)
        log(f"wrote the table of sizes into {DOCS.relative_to(REPO)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
