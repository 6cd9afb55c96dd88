"""Build the self-contained Blender extension: ``dist/render_inspect-<version>-<platform>.zip``.

Blender 4.2 to 5.0 run Python 3.11 and ship NumPy; everything else the add-on's code path
imports is bundled as wheels (Blender's extension format), one zip per platform, built with
the ``blender_ext.py`` that ships inside Blender (here: inside the ``bpy`` package):

1. the wheel of this checkout (``render_inspect``, the shipped scenes as package data);
2. the wheels of its dependencies, at the versions installed in the tested environment
   (``.venv``, pinned by ``requirements.txt``), fetched with ``pip download --only-binary``
   for each platform and Python 3.11;
3. ``blender_addon/`` staged with those wheels under ``wheels/`` and its manifest's
   ``wheels`` / ``platforms`` lists, then ``blender_ext.py build --split-platforms`` and
   ``blender_ext.py validate`` of every zip.

A dependency without a wheel for a platform is left out of that platform's zip and named
on stdout; the add-on names it in its panel and disables the operations that need it.

Usage::

    .venv/bin/python tools/build_blender_extension.py                    # all platforms
    .venv/bin/python tools/build_blender_extension.py --platforms linux-x64
    .venv/bin/python tools/build_blender_extension.py --update-manifest  # rewrite the list
    .venv/bin/python tools/build_blender_extension.py --check-manifest   # list == pins?
"""

from __future__ import annotations

import argparse
import importlib.metadata as md
import json
import re
import shutil
import subprocess
import sys
import tomllib
import zipfile
from pathlib import Path

from packaging.requirements import Requirement
from packaging.utils import canonicalize_name, parse_wheel_filename

REPO = Path(__file__).resolve().parents[1]
ADDON = REPO / "blender_addon"
MANIFEST = ADDON / "blender_manifest.toml"
CACHE = REPO / "build" / "blender_wheels"
STAGE = REPO / "build" / "blender_extension"

#: Python of Blender 4.2 LTS, 4.3, 4.4, 4.5 LTS and 5.0 (all 3.11).
PYTHON_VERSION = "3.11"
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
#: Environment markers of each platform (for dependencies declared per platform).
MARKERS = {
    "linux-x64": {"sys_platform": "linux", "platform_system": "Linux", "platform_machine": "x86_64",
                  "os_name": "posix"},
    "windows-x64": {"sys_platform": "win32", "platform_system": "Windows",
                    "platform_machine": "AMD64", "os_name": "nt"},
    "macos-arm64": {"sys_platform": "darwin", "platform_system": "Darwin",
                    "platform_machine": "arm64", "os_name": "posix"},
    "macos-x64": {"sys_platform": "darwin", "platform_system": "Darwin",
                  "platform_machine": "x86_64", "os_name": "posix"},
}
#: The add-on's code path: render_inspect's own dependencies, its "render" extra (Mitsuba
#: for the interferometer) and the X3P writer of the "metrology" extra.
ROOT = "render_inspect"
ROOT_EXTRAS = ("render",)
EXTRA_PACKAGES = ("x3pio",)
#: Shipped with Blender itself (bundling a second NumPy would break Blender), or Blender.
PROVIDED_BY_BLENDER = {"numpy", "bpy"}
#: Dependencies that only other platforms need, so they are not installed here to read
#: their version from: the versions bundled for those platforms.
OTHER_PLATFORM_PINS = {"colorama": "0.4.6"}

BEGIN = "# --- wheels: written by tools/build_blender_extension.py --update-manifest ---"
END = "# --- end of wheels ---"


def log(msg: str) -> None:
    print(msg, flush=True)


def _markers(platform: str, extra: str = "") -> dict:
    return {"python_version": PYTHON_VERSION, "python_full_version": PYTHON_VERSION + ".0",
            "implementation_name": "cpython", "platform_python_implementation": "CPython",
            "extra": extra, **MARKERS[platform]}


def dependency_pins(platform: str) -> dict[str, str]:
    """{distribution name: version} the add-on needs on ``platform``: the closure of
    render_inspect's requirements, at the versions installed in this environment."""
    todo = [(Requirement(f"{ROOT}[{','.join(ROOT_EXTRAS)}]"), "")]
    todo += [(Requirement(name), "") for name in EXTRA_PACKAGES]
    pins: dict[str, str] = {}
    while todo:
        req, _ = todo.pop()
        name = canonicalize_name(req.name)
        if name in PROVIDED_BY_BLENDER or name in pins:
            continue
        if name in OTHER_PLATFORM_PINS:
            try:
                md.distribution(req.name)
            except md.PackageNotFoundError:
                pins[name] = OTHER_PLATFORM_PINS[name]
                continue
        try:
            dist = md.distribution(req.name)
        except md.PackageNotFoundError:
            raise SystemExit(f"{req.name} (needed on {platform}) is not installed here: add its "
                             f"version to OTHER_PLATFORM_PINS in {Path(__file__).name}") from None
        version = dist.version
        if not req.specifier.contains(version, prereleases=True):
            raise SystemExit(f"installed {req.name} {version} does not satisfy {req}; run make setup")
        if name != canonicalize_name(ROOT):
            pins[name] = version
        for text in dist.requires or ():
            sub = Requirement(text)
            wanted = sub.marker is None or any(
                sub.marker.evaluate(_markers(platform, e)) for e in ("", *req.extras))
            if wanted:
                todo.append((sub, ""))
    return dict(sorted(pins.items()))


def _cached(dest: Path, name: str, version: str) -> list[Path]:
    out = []
    for whl in dest.glob("*.whl"):
        wname, wver, _, _ = parse_wheel_filename(whl.name)
        if wname == canonicalize_name(name) and str(wver) == version:
            out.append(whl)
    return out


def _pip_download(dest: Path, platform: str, specs: list[str]) -> subprocess.CompletedProcess:
    cmd = [sys.executable, "-m", "pip", "download", "--quiet", "--no-deps", "--only-binary=:all:",
           "--python-version", PYTHON_VERSION, "--implementation", "cp", "--dest", str(dest)]
    for tag in PLATFORMS[platform]:
        cmd += ["--platform", tag]
    return subprocess.run(cmd + specs, capture_output=True, text=True)


def download_wheels(platform: str) -> tuple[list[Path], list[str]]:
    """Wheels of every pinned dependency for ``platform`` (cached in build/blender_wheels/)
    and the ``name==version`` of those with no wheel for it."""
    dest = CACHE / platform
    dest.mkdir(parents=True, exist_ok=True)
    pins = dependency_pins(platform)
    todo = [f"{n}=={v}" for n, v in pins.items() if not _cached(dest, n, v)]
    missing = []
    if todo and _pip_download(dest, platform, todo).returncode != 0:
        for spec in todo:  # one at a time to find the ones that have no wheel here
            res = _pip_download(dest, platform, [spec])
            if res.returncode != 0:
                missing.append(spec)
                log(f"  {platform}: no wheel for {spec} ({res.stderr.strip().splitlines()[-1]})")
    wheels = []
    for n, v in pins.items():
        found = _cached(dest, n, v)
        if not found and f"{n}=={v}" not in missing:
            raise SystemExit(f"{platform}: pip reported {n}=={v} downloaded but no wheel is in {dest}")
        wheels += found
    return sorted(wheels), missing


def build_project_wheel() -> Path:
    """The render_inspect wheel of this checkout (the shipped scenes are package data:
    ``render_inspect/scenes/*.toml``)."""
    out = CACHE / "project"
    if out.exists():
        shutil.rmtree(out)
    out.mkdir(parents=True)
    subprocess.run([sys.executable, "-m", "pip", "wheel", "--quiet", "--no-deps", "--wheel-dir",
                    str(out), str(REPO)], check=True)
    (wheel,) = out.glob("render_inspect-*.whl")
    with zipfile.ZipFile(wheel) as zf:
        shipped = [n for n in zf.namelist() if n.startswith("render_inspect/scenes/")]
    if not shipped:
        raise SystemExit(f"{wheel.name} holds no scenes under render_inspect/scenes/")
    return wheel


def manifest_wheels(text: str) -> list[str]:
    return tomllib.loads(text).get("wheels", [])


def write_wheel_list(text: str, wheels: list[str]) -> str:
    body = "wheels = [\n" + "".join(f'  "./wheels/{w}",\n' for w in wheels) + "]"
    block = f"{BEGIN}\n{body}\n{END}"
    if BEGIN not in text:  # top-level keys must come before the first [table]
        raise SystemExit(f"{MANIFEST.name} has no line {BEGIN!r} to put the wheels after")
    return re.sub(re.escape(BEGIN) + r".*?" + re.escape(END), lambda _: block, text, flags=re.S)


def blender_ext() -> Path:
    import bpy  # only to locate the blender_ext.py that ships inside Blender

    path = Path(bpy.utils.system_resource("SCRIPTS")) / "addons_core/bl_pkg/cli/blender_ext.py"
    if not path.is_file():
        raise SystemExit(f"blender_ext.py not found at {path}")
    return path


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--platforms", nargs="+", choices=sorted(PLATFORMS), default=list(PLATFORMS))
    p.add_argument("--output-dir", type=Path, default=REPO / "dist")
    p.add_argument("--update-manifest", action="store_true",
                   help="rewrite the wheels list of blender_addon/blender_manifest.toml")
    p.add_argument("--check-manifest", action="store_true",
                   help="only check that the manifest lists the pinned versions (no build)")
    args = p.parse_args(argv)

    manifest_text = MANIFEST.read_text()
    if args.check_manifest:
        return check_manifest(manifest_text)

    project = build_project_wheel()
    log(f"project wheel: {project.name}")
    per_platform: dict[str, list[Path]] = {}
    missing: dict[str, list[str]] = {}
    for platform in args.platforms:
        wheels, miss = download_wheels(platform)
        per_platform[platform] = [project] + wheels
        missing[platform] = miss
        size = sum(w.stat().st_size for w in per_platform[platform]) / 2**20
        log(f"{platform}: {len(per_platform[platform])} wheels, {size:.0f} MiB"
            + (f"; not available: {', '.join(miss)}" if miss else ""))

    all_wheels = sorted({w.name: w for ws in per_platform.values() for w in ws}.values(),
                        key=lambda w: w.name.lower())
    if args.update_manifest:
        if set(args.platforms) != set(PLATFORMS):
            raise SystemExit("--update-manifest needs every platform")
        MANIFEST.write_text(write_wheel_list(manifest_text, [w.name for w in all_wheels]))
        manifest_text = MANIFEST.read_text()
        log(f"wrote {len(all_wheels)} wheels into {MANIFEST.relative_to(REPO)}")
    listed = {Path(w).name for w in manifest_wheels(manifest_text)}
    unlisted = sorted(w.name for w in all_wheels if w.name not in listed)
    if unlisted:
        raise SystemExit("the manifest does not list these wheels (run with --update-manifest): "
                         + ", ".join(unlisted))

    # stage: the add-on's files, the wheels for these platforms, the manifest restricted to them
    if STAGE.exists():
        shutil.rmtree(STAGE)
    shutil.copytree(ADDON, STAGE, ignore=shutil.ignore_patterns("__pycache__", "*.pyc", "wheels"))
    (STAGE / "wheels").mkdir()
    for w in all_wheels:
        shutil.copy2(w, STAGE / "wheels" / w.name)
    staged = tomllib.loads(manifest_text)
    text = write_wheel_list(manifest_text, [w.name for w in all_wheels])
    text = re.sub(r"(?m)^platforms = \[.*?\]$",
                  "platforms = [" + ", ".join(f'"{p}"' for p in args.platforms) + "]", text)
    if "platforms" not in staged:
        raise SystemExit("the manifest must declare platforms")
    (STAGE / "blender_manifest.toml").write_text(text)

    args.output_dir.mkdir(parents=True, exist_ok=True)
    ext = blender_ext()
    res = subprocess.run([sys.executable, str(ext), "build", "--split-platforms",
                          "--source-dir", str(STAGE), "--output-dir", str(args.output_dir)],
                         capture_output=True, text=True)
    if res.returncode != 0:
        raise SystemExit(f"blender_ext.py build failed:\n{res.stdout}\n{res.stderr}")
    version = staged["version"]
    report = {}
    for platform in args.platforms:
        z = args.output_dir / f"{staged['id']}-{version}-{platform.replace('-', '_')}.zip"
        if not z.is_file():
            raise SystemExit(f"blender_ext.py wrote no {z.name}:\n{res.stdout}")
        check = subprocess.run([sys.executable, str(ext), "validate", str(z)],
                               capture_output=True, text=True)
        if check.returncode != 0:
            raise SystemExit(f"{z.name} does not validate:\n{check.stdout}\n{check.stderr}")
        report[platform] = {"zip": str(z), "size_mib": round(z.stat().st_size / 2**20, 1),
                            "wheels": len(per_platform[platform]), "missing": missing[platform]}
        log(f"built {z.name}: {report[platform]['size_mib']} MiB")
    (args.output_dir / "blender_extension_build.json").write_text(json.dumps(report, indent=2))
    return 0


def check_manifest(text: str) -> int:
    """Every wheel the manifest lists is at the pinned version, and every pinned
    dependency has a wheel listed (for some platform)."""
    listed: dict[str, set[str]] = {}
    for w in manifest_wheels(text):
        name, ver, _, _ = parse_wheel_filename(Path(w).name)
        listed.setdefault(str(name), set()).add(str(ver))
    problems = []
    pins: dict[str, str] = {}
    for platform in PLATFORMS:
        pins.update(dependency_pins(platform))
    for name, ver in pins.items():
        if listed.get(name) != {ver}:
            problems.append(f"{name}: pinned {ver}, manifest lists {sorted(listed.get(name, []))}")
    extra = set(listed) - set(pins) - {canonicalize_name(ROOT)}
    problems += [f"{name}: listed but not a dependency" for name in sorted(extra)]
    for p in problems:
        log(p)
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
