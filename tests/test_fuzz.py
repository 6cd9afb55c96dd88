"""Seeded fuzzing of every input path, bounded in time and memory.

Each class of input (scene values, ``--set`` text, scene files, expressions, height-map
and measured files, output folders, machine-program text, memory-driving parameters,
renderer sizes, the command line end to end; hostile output folders and measured files,
filter texts, signals at each phase of writing a folder, address-space limits; bad input
to every command; the Blender operators' tasks; the written NC program of every shipped
scene and unsafe changes of it) is mutated from a fixed seed.  Every case
must either be accepted or be refused with a :class:`RenderInspectError` whose message
names the key; nothing else may escape (a traceback is a failure), refused runs write
nothing and accepted ones write everything.  The number of cases per class is in
:data:`CASES`; the whole module runs in a couple of minutes.
"""

from __future__ import annotations

import copy
import io
import json
import math
import os
import re
import string
import subprocess
import sys
import tracemalloc
from pathlib import Path

import numpy as np
import pytest

from render_inspect.design import make_surface
from render_inspect.design._expression import ExpressionSurface
from render_inspect.design._heightmap import HeightMapSurface
from render_inspect.errors import InputError, RenderInspectError, SceneError
from render_inspect.io import (
    MARKER,
    atomic_output_dir,
    check_output_path,
    read_marker,
    read_measured,
    read_nc,
    read_program_nc,
    write_exr,
    write_nc,
    write_program_nc,
    write_x3p,
)
from render_inspect.pipeline import check_render_limits, plan_program
from render_inspect.processes import process_of
from render_inspect.render import MAX_SAMPLES_PER_PASS, render_passes
from render_inspect.scene import find_scene, load_scene, scene_from_dict, shipped_scenes
from render_inspect.toolpath import LinearProgram, ToolPath

#: the seed of every class (RENDER_INSPECT_FUZZ_SEED changes it, to fuzz further)
SEED = int(os.environ.get("RENDER_INSPECT_FUZZ_SEED", "16"))
#: RENDER_INSPECT_FUZZ_SCALE multiplies the number of cases (1 in CI)
SCALE = max(1, int(os.environ.get("RENDER_INSPECT_FUZZ_SCALE", "1")))
#: cases per class (kept modest so that CI stays fast)
CASES = {k: v * SCALE for k, v in {"schema": 600, "set": 500, "scene_file": 150,
                                   "expression": 400, "files": 160, "out": 120, "nc": 300,
                                   "memory": 30, "render": 200}.items()}
CASES["cli"] = 6
CASES.update({"hostile_out": 80 * SCALE, "hostile_files": 120 * SCALE, "filters": 150 * SCALE,
              "analyze_cli": 12 * SCALE, "signals": 4 * SCALE, "address_space": 3,
              "blender": 20 * SCALE, "programs": 14 * SCALE})

HOSTILE = [math.nan, math.inf, -math.inf, 1e300, -1e300, 1e-300, -1e-300, 5e-324, 0, 0.0,
           -0.0, -1, 1, 2 ** 64, -(2 ** 63), 10 ** 400, True, False, "100", "", "nan", "1e3",
           "x\ny", [], [1, 2], [math.nan] * 4, [0, 0, 1, 1], [[1]], {}, {"a": 1}, None,
           1e20, -1e20, 0.5, 3600, 7, "z", "auto"]


def _rng(name: str):
    return np.random.default_rng([SEED, sum(map(ord, name))])


def _pick(rng, seq):
    return seq[int(rng.integers(len(seq)))]


def _paths(d, prefix=()):
    """Every key path of a nested dict (sections and leaves)."""
    out = []
    for k, v in d.items():
        p = prefix + (k,)
        out.append(p)
        if isinstance(v, dict):
            out.extend(_paths(v, p))
    return out


def _names_key(msg: str, path: tuple) -> bool:
    """The message names the mutated key: its dotted path, or its section and its name."""
    dotted = ".".join(path)
    if dotted in msg:
        return True
    parent = ".".join(path[:-1])
    return (not parent or parent in msg) and path[-1] in msg


# ------------------------------------------------------------------ A: scene values
def test_fuzz_scene_values_are_validated_or_named():
    rng = _rng("schema")
    bases = {name: load_scene(name).to_dict() for name in shipped_scenes()}
    accepted = refused = 0
    for _ in range(CASES["schema"]):
        name = _pick(rng, list(bases))
        data = copy.deepcopy(bases[name])
        path = _pick(rng, _paths(data))
        node = data
        for k in path[:-1]:
            node = node[k]
        node[path[-1]] = copy.deepcopy(_pick(rng, HOSTILE))
        if isinstance(data.get("simulation"), dict) and path[-1] != "max_memory_gb":
            data["simulation"]["max_memory_gb"] = 0.25
        try:
            scene = scene_from_dict(data, source=name)
        except SceneError as err:
            refused += 1
            assert _names_key(str(err), path), (path, str(err))
            continue
        accepted += 1
        # what the commands do first with a scene must hold up too
        try:
            surface = make_surface(scene.design)
            x = np.linspace(scene.simulation.region[0], scene.simulation.region[2], 5)
            with np.errstate(all="ignore"):
                surface.height(x, x)
            process = process_of(scene)
            process.precheck(process.inputs_of(scene), tuple(scene.simulation.region))
            check_render_limits(scene)
        except RenderInspectError:
            pass
    assert accepted + refused == CASES["schema"] and refused > CASES["schema"] / 3


# ------------------------------------------------------------------ B: --set text
_KEYS = ["process.spindle_rpm", "simulation.region", "design.offset", "name", "tool.nose_radius",
         "render.diffuse.spp", "design.expr", "simulation.seed", "x", "a.b.c.d.e.f.g.h.i",
         "process", "simulation", ".", "", "process..kind", "process.kind", "design.type",
         "simulation.region.0", "render.interferometer.reference_height"]
_FRAGMENTS = ["[", "]", "{", "}", "'", '"', '"""', "=", ",", "\n", "\r", "\x00", "\x1b", "\u2028",
              "nan", "inf", "-inf", "1e400", "0x10", "true", "1979-05-27", "#", "\\", "é", "☃",
              "1", "0.5", "-3", "[0,0,1,1]", "{a=1}", "'a\nb'", "x=1"]


def test_fuzz_set_strings_are_parsed_or_named():
    rng = _rng("set")
    for i in range(CASES["set"]):
        key = _pick(rng, _KEYS)
        if i % 5 == 0:
            value = "[" * int(rng.integers(30, 3000)) + "1" + "]" * int(rng.integers(0, 40))
        else:
            value = "".join(_pick(rng, _FRAGMENTS) for _ in range(int(rng.integers(0, 6))))
        item = f"{key}={value}" if i % 17 else value
        try:
            load_scene("sts_sinusoidal_grid", [item])
        except SceneError as err:
            msg = str(err)
            k = item.split("=", 1)[0].strip()
            if "=" in item and k and all(re.fullmatch(r"[A-Za-z_]\w*", p) for p in k.split(".")):
                assert k.split(".")[0] in msg or "--set" in msg, (item, msg)


# ------------------------------------------------------------------ C: scene files
def _mutate_text(rng, raw: bytes) -> bytes:
    kind = int(rng.integers(8))
    if kind == 0:
        return raw[: int(rng.integers(len(raw) + 1))]
    if kind == 1:
        b = bytearray(raw)
        for _ in range(int(rng.integers(1, 8))):
            b[int(rng.integers(len(b)))] = int(rng.integers(256))
        return bytes(b)
    if kind == 2:
        return b"\xff\xfe" + raw
    if kind == 3:
        return raw + b"\nx = [" + b"[" * 5000 + b"]" * 5000 + b"]\n"
    if kind == 4:
        return raw + b"\n[" + b".".join([b"a"] * 5000) + b"]\nb = 1\n"
    if kind == 5:
        return bytes(rng.integers(0, 256, int(rng.integers(0, 2000)), dtype=np.uint8))
    if kind == 6:
        return raw.replace(b"=", b"= true #", 1)
    return raw + b"\n" + b"\x00" * 10


def test_fuzz_scene_files_load_or_fail_cleanly(tmp_path):
    rng = _rng("scene_file")
    raws = [find_scene(n).read_bytes() for n in shipped_scenes()]
    for i in range(CASES["scene_file"]):
        f = tmp_path / f"s{i}.toml"
        f.write_bytes(_mutate_text(rng, _pick(rng, raws)))
        try:
            load_scene(f)
        except SceneError:
            pass
    for special in [tmp_path, "/dev/null", "/dev/zero", tmp_path / "missing.toml", ""]:
        with pytest.raises(SceneError, match="scene"):
            load_scene(special)
    os.mkfifo(tmp_path / "fifo.toml")
    with pytest.raises(SceneError, match="not a regular file"):
        load_scene(tmp_path / "fifo.toml")
    (tmp_path / "big.toml").write_bytes(b"# " + b"x" * (5 * 2 ** 20))
    with pytest.raises(SceneError, match="larger than"):
        load_scene(tmp_path / "big.toml")


# ------------------------------------------------------------------ D: expressions
_ATOMS = ["x", "y", "pi", "e", "1", "0", "2.5", "1e12", "1e-12", "-3", "a", "__import__",
          "x.real", "'s'", "[x]", "lambda: 1", "None", "True", "1e400", "0x1f", "1j"]
_UNARY = ["sin", "cos", "tan", "exp", "log", "sqrt", "abs", "arcsin", "tanh", "sign", "eval",
          "open", "getattr"]
_BINOPS = ["+", "-", "*", "/", "**", "//", "%", "@", "<", "and", ","]


def _expr(rng, depth: int) -> str:
    if depth <= 0 or rng.random() < 0.25:
        return _pick(rng, _ATOMS)
    r = rng.random()
    if r < 0.45:
        return f"{_expr(rng, depth - 1)} {_pick(rng, _BINOPS)} {_expr(rng, depth - 1)}"
    if r < 0.75:
        return f"{_pick(rng, _UNARY)}({_expr(rng, depth - 1)})"
    if r < 0.85:
        return f"({_expr(rng, depth - 1)})"
    if r < 0.9:
        return "+".join(_expr(rng, min(depth - 1, 1)) for _ in range(int(rng.integers(2, 200))))
    return f"-{_expr(rng, depth - 1)}"


def test_fuzz_expressions_are_safe():
    rng = _rng("expression")
    x = np.linspace(-1, 1, 7)
    X, Y = np.meshgrid(x, x)
    ok = 0
    for i in range(CASES["expression"]):
        expr = _expr(rng, int(rng.integers(1, 12)))
        if i % 50 == 0:
            expr = "sin(" * int(rng.integers(50, 300)) + "x" + ")" * 300
        try:
            s = ExpressionSurface(expr, {"a": 2.0})
            for f in (s.height, s.gradient, s.hessian):
                for v in np.atleast_1d(f(X, Y)) if f is s.height else f(X, Y):
                    assert np.all(np.isfinite(v))
            ok += 1
        except InputError as err:
            assert "design.expr" in str(err) or "design.constants" in str(err)
    assert ok > 10


# ------------------------------------------------------------------ E: map files
def _npy_bytes(rng) -> bytes:
    buf = io.BytesIO()
    dtype = _pick(rng, [np.float64, np.float32, np.int16, np.complex128, object, "U4", bool])
    shape = _pick(rng, [(8, 8), (1, 8), (0, 0), (8,), (2, 2, 2), (5, 7)])
    try:
        arr = np.zeros(shape, dtype=dtype)
        np.save(buf, arr, allow_pickle=True)
    except (TypeError, ValueError):
        np.save(buf, np.zeros((8, 8)))
    raw = buf.getvalue()
    if rng.random() < 0.3:  # a header claiming another shape
        raw = raw.replace(repr(shape).encode(), repr(_pick(rng, [(10 ** 6, 10 ** 6), (2 ** 40, 2),
                                                                 (8, 9), (-1, 8)])).encode(), 1)
    return raw


def _corrupt(rng, raw: bytes) -> bytes:
    k = int(rng.integers(4))
    if k == 0 or not raw:
        return raw
    if k == 1:
        return raw[: int(rng.integers(len(raw)))]
    if k == 2:
        b = bytearray(raw)
        for _ in range(int(rng.integers(1, 20))):
            b[int(rng.integers(len(b)))] = int(rng.integers(256))
        return bytes(b)
    return bytes(rng.integers(0, 256, int(rng.integers(0, 600)), dtype=np.uint8))


def test_fuzz_measured_and_design_map_files(tmp_path):
    rng = _rng("files")
    z = np.random.default_rng(1).normal(0, 1e-4, (12, 12))
    x3p = write_x3p(tmp_path / "ref.x3p", z, pixel=0.001).read_bytes()
    exr = write_exr(tmp_path / "ref.exr", {"design": z.astype(np.float32)},
                    {"pixel_size_mm": 0.001, "origin_mm": [0.0, 0.0]}).read_bytes()
    buf = io.BytesIO()
    np.savez(buf, z=z, pixel_mm=0.001)
    npz = buf.getvalue()
    sidecars = ['{"pixel_mm": 0.001}', "{", '{"pixel_mm": "a"}', "[]", '{"pixel_mm": 1e999}',
                '{"pixel_mm": 0.001, "origin_mm": [1, 2, 3]}', "\x00", '{"units": "furlong"}']
    for i in range(CASES["files"]):
        kind = _pick(rng, ["npy", "npz", "exr", "x3p"])
        raw = {"npy": lambda: _npy_bytes(rng), "npz": lambda: npz, "exr": lambda: exr,
               "x3p": lambda: x3p}[kind]()
        f = tmp_path / f"m{i}.{kind}"
        f.write_bytes(_corrupt(rng, raw))
        f.with_suffix(".json").write_text(_pick(rng, sidecars))
        try:
            zz, pixel, origin, meta = read_measured(f, pixel=0.001 if kind == "npz" else None)
            assert zz.ndim == 2 and zz.dtype == np.float64 and pixel > 0
        except RenderInspectError:
            pass
        if kind in ("npy", "exr"):
            try:
                HeightMapSurface(f, pixel=0.001, origin=(0.0, 0.0), interpolation="linear")
            except RenderInspectError as err:
                assert "design" in str(err)


# ------------------------------------------------------------------ F: output folders
_OUT_PARTS = ["a", "..", ".", "", " ", "\n", "\x00", "é☃", "x" * 300, "/dev/null", "/proc",
              "/", "f", "f/sub", "-", "~", ".hidden", "d"]


def test_fuzz_output_folders(tmp_path, monkeypatch):
    rng = _rng("out")
    work = tmp_path / "work"
    (work / "d").mkdir(parents=True)
    (work / "f").write_text("a file")
    monkeypatch.chdir(work)
    for i in range(CASES["out"]):
        parts = [_pick(rng, _OUT_PARTS) for _ in range(int(rng.integers(1, 4)))]
        out = "/".join(parts)
        try:
            target = check_output_path(out)
        except InputError as err:
            assert "--out" in str(err)
            continue
        if not str(target).startswith(str(tmp_path)):
            continue  # only ever write inside the test's folder
        before = {str(p) for p in tmp_path.rglob("*")}
        fail = rng.random() < 0.5
        try:
            with atomic_output_dir(out, command="fuzz", overwrite=bool(rng.random() < 0.3)) as tmp:
                (tmp / "a.txt").write_text(str(i))
                if fail:
                    raise KeyboardInterrupt if rng.random() < 0.5 else RuntimeError("fail")
        except (KeyboardInterrupt, RuntimeError):
            assert {str(p) for p in tmp_path.rglob("*")} == before
            continue
        except InputError as err:
            assert "--out" in str(err)
            assert {str(p) for p in tmp_path.rglob("*")} == before
            continue
        assert (target / "a.txt").read_text() == str(i)
        assert read_marker(target)["files"]["a.txt"] == "fuzz"
        assert not [p for p in target.parent.iterdir() if ".partial-" in p.name]
    assert (work / "f").read_text() == "a file"


# ------------------------------------------------------------------ G: program text
_PRINTABLE = set(string.printable) - set("\t\n\r\x0b\x0c")


def test_fuzz_program_text(tmp_path):
    rng = _rng("nc")
    alphabet = [chr(c) for c in list(range(0, 0x180)) + [0x2028, 0x2029, 0x85, 0xfeff, 0x202e]]
    n = 20
    th = np.linspace(0, 4 * np.pi, n)
    tp = ToolPath(th, 1 - th / 100, 1e-3 * np.sin(th), np.linspace(0, 2, n), {"spindle_rpm": 60})
    lp = LinearProgram(np.zeros(n), np.linspace(0, 1, n), np.zeros(n), np.linspace(0, 1, n),
                       np.repeat([0, 1], n // 2), {"feed_mm_per_min": 100.0})
    for i in range(CASES["nc"]):
        name = "".join(rng.choice(alphabet, size=int(rng.integers(0, 60))))
        header = {"scene": name, "comment": name[::-1]}
        f = write_nc(tmp_path / "t.nc", tp, header=header) if i % 2 else \
            write_program_nc(tmp_path / "t.nc", lp, header=header)
        text = f.read_bytes().decode("ascii")
        for line in text.split("\n")[:-1]:
            assert set(line) <= _PRINTABLE
            if line.startswith(";"):
                assert ";" not in line[1:] and "(" not in line and ")" not in line
            else:
                assert re.fullmatch(r"(G18 G21 G40|G17 G40|G90 G93|G90 G94 G21|M30|N\d+ G01( [CXYZF]-?[0-9.e+-]+)+)", line)
        back = read_nc(f) if i % 2 else read_program_nc(f)
        assert back.points == n


# ------------------------------------------------------------------ H: memory
def test_fuzz_memory_parameters_stay_within_the_budget():
    """Random combinations of the keys that drive the size of the program and the grid,
    under a 64 MiB budget: each is refused naming a key, or planned within 1.5 x the
    budget (tracemalloc)."""
    rng = _rng("memory")
    budget_gb = 64 / 1024
    choices = {
        "process.points_per_rev": [8, 3600, 10 ** 5, 10 ** 7],
        "process.feed_mm_per_min": [1e-9, 1e-3, 0.5, 20.0],
        "process.sampling": ["'constant_angle'", "'constant_arc'", "'hybrid'"],
        "process.arc_length": [1e-9, 1e-4, 0.005],
        "process.chordal_tolerance": [1e-15, 1e-9, 1e-6],
        "process.workpiece_radius": [0.3, 5.0, 500.0],
        "simulation.pixel": [1e-6, 1e-3, 0.01],
    }
    for _ in range(CASES["memory"]):
        over = [f"{k}={_pick(rng, v)}" for k, v in choices.items() if rng.random() < 0.6]
        try:
            scene = load_scene("sts_sinusoidal_grid", over + [f"simulation.max_memory_gb={budget_gb}"])
        except SceneError:
            continue
        tracemalloc.start()
        try:
            plan_program(scene)
        except RenderInspectError as err:
            assert re.search(r"process\.|simulation\.", str(err)), str(err)
            assert not re.search(r"\d{13,}", str(err))
        finally:
            _, peak = tracemalloc.get_traced_memory()
            tracemalloc.stop()
        assert peak < 1.5 * budget_gb * 2 ** 30, (over, peak)


# ------------------------------------------------------------------ I: renderer sizes
def test_fuzz_render_sizes():
    rng = _rng("render")
    base = load_scene("sts_sinusoidal_grid", ["simulation.max_memory_gb=2"])
    for _ in range(CASES["render"]):
        res = int(rng.choice([1, 16, 255, 4096, 8192, 8193, 65536]))
        spp = int(rng.choice([0, 1, 300, 65536, 2 ** 20]))
        over = [f"render.diffuse.resolution={res}", f"render.diffuse.spp={spp}"]
        if rng.random() < 0.3:
            w = float(rng.choice([1e-6, 1e-3, 0.1]))
            over.append(f"render.diffuse.window=[0, -0.5, {w}, 0.5]")
        if rng.random() < 0.3:
            over.append(f"render.interferometer.pixel={rng.choice([1e-7, 1e-6, 1e-4, 0.01])}")
            over.append(f"render.interferometer.subsamples={rng.integers(0, 10)}")
        try:
            scene = base.with_overrides(over)
        except SceneError as err:
            assert "render." in str(err)
            continue
        try:
            check_render_limits(scene)
        except RenderInspectError as err:
            assert "render." in str(err)
        passes = render_passes(min(res, 8192), min(res, 8192), max(spp, 1))
        assert max(passes) * min(res, 8192) ** 2 <= MAX_SAMPLES_PER_PASS


# ------------------------------------------------------------------ J: command line
def _run_cli(*args, cwd):
    return subprocess.run([sys.executable, "-m", "render_inspect.cli", *map(str, args)],
                          capture_output=True, text=True, cwd=cwd, timeout=300)


@pytest.mark.slow
def test_fuzz_command_line_end_to_end(tmp_path):
    """A few whole runs in a fresh process: exit 1, one line naming the input, no
    traceback, nothing written."""
    (tmp_path / "bin.toml").write_bytes(b"\x00\xff" * 50)
    deep = tmp_path / "deep.toml"
    deep.write_bytes(b"x = " + b"[" * 5000 + b"]" * 5000 + b"\n")
    cases = [
        (["simulate", tmp_path / "bin.toml"], "UTF-8"),
        (["simulate", deep], "deeper"),
        (["simulate", tmp_path], "is a folder"),
        (["simulate", "sts_sinusoidal_grid", "--set", "process.spindle_rpm=true"], "process.spindle_rpm"),
        (["toolpath", "sts_sinusoidal_grid", "--set", "process.points_per_rev=10000000",
          "--set", "simulation.max_memory_gb=1"], "process.points_per_rev"),
        (["compare", "sts_sinusoidal_grid", "--measured", tmp_path / "bin.toml"], "measured"),
    ]
    assert len(cases) == CASES["cli"]
    for args, key in cases:
        out = tmp_path / "out"
        r = _run_cli(*args, "--out", out, cwd=tmp_path)
        assert r.returncode == 1, (args, r.stderr)
        assert "Traceback" not in r.stderr and key in r.stderr, (args, r.stderr)
        assert len(r.stderr.strip().splitlines()) == 1, r.stderr
        assert not out.exists() and not [p for p in tmp_path.iterdir() if ".partial" in p.name]


# ------------------------------------------------------------------ K: hostile output folders
def _digest(paths) -> dict:
    out = {}
    for p in paths:
        try:
            out[str(p)] = p.read_bytes() if p.is_file() and not p.is_symlink() else os.readlink(p) \
                if p.is_symlink() else None
        except OSError:
            out[str(p)] = None
    return out


def test_fuzz_hostile_output_folders(tmp_path):
    """Random mixes of what a user or an attacker leaves around an output folder: user
    files (some named like render-inspect's temporaries), a user file inside a nested
    output, a marker copied from elsewhere or of an earlier layout, siblings named like
    backups, a planted lock (link, hard link, garbage), ``--out`` a link to a user's
    folder, an input inside ``--out``.  Whatever the run does, a user's file is never
    changed or deleted without --overwrite, the lock's target never written, a refused or
    failed run changes nothing, and a finished run leaves a complete folder."""
    rng = _rng("hostile_out")
    user_names = ["notes.txt", ".metrics.json.backup-1", ".x.lock", ".a.txt.partial-1",
                  ".heightmap.exr.123.tmp", "sub/mine.txt", ".DS_Store.bak"]
    for i in range(CASES["hostile_out"]):
        root = tmp_path / f"c{i}"
        root.mkdir()
        victim = root / "victim.txt"
        victim.write_text("secret")
        out = root / "out"
        user: list = [victim]
        traits = {k for k in ("ours", "user_file", "nested", "forged", "old_marker", "siblings",
                              "lock", "link", "input") if rng.random() < 0.35}
        if "ours" in traits or "nested" in traits:
            with atomic_output_dir(out, command="simulate") as tmp:
                (tmp / "a.txt").write_text("old")
        if "nested" in traits:
            with atomic_output_dir(out / "sub", command="toolpath") as tmp:
                (tmp / "t.txt").write_text("nested")
            (out / "sub" / "mine.txt").write_text("user's")
            user.append(out / "sub" / "mine.txt")
        if "user_file" in traits:
            name = _pick(rng, user_names)
            f = out / name
            f.parent.mkdir(parents=True, exist_ok=True)
            f.write_text("user's")
            user.append(f)
        if "forged" in traits or "old_marker" in traits:
            mine = root / "mine"
            (mine / "data.txt").parent.mkdir(parents=True, exist_ok=True)
            (mine / "data.txt").write_text("user's")
            user.append(mine / "data.txt")
            marker = {"written_by": "render_inspect", "marker_version": 1,
                      "files": {"data.txt": "simulate"}, "commands": {"simulate": {}}}
            if "forged" in traits:
                marker.update(marker_version=2, stat={"data.txt": [1, 2]})
            (mine / MARKER).write_text(json.dumps(marker))
            out = mine
        if "siblings" in traits:
            for name in (f".{out.name}.backup-1", f".{out.name}.backup-7-0123abcd"):
                (root / name).mkdir(exist_ok=True)
                (root / name / "keep.txt").write_text("user's")
            user.append(root / f".{out.name}.backup-1" / "keep.txt")
        if "lock" in traits:
            lock = root / f".{out.name}.lock"
            kind = int(rng.integers(3))
            if kind == 0:
                lock.symlink_to(victim)
            elif kind == 1:
                os.link(victim, lock)
            else:
                lock.write_text("not a process id")
                user.append(lock)
        target = out
        if "link" in traits:
            real = root / "precious"
            real.mkdir(exist_ok=True)
            (real / "keep.txt").write_text("user's")
            user.append(real / "keep.txt")
            out = root / "link"
            out.symlink_to(real)
        inputs = []
        if "input" in traits and target.is_dir():
            f = target / "input.npy"
            f.write_text("input")
            user.append(f)
            inputs = [f]
        overwrite = bool(rng.random() < 0.4)
        fail = rng.random() < 0.2
        before = _digest(user)
        try:
            with atomic_output_dir(out, command="fuzz", overwrite=overwrite, inputs=inputs) as tmp:
                (tmp / "a.txt").write_text(f"new {i}")
                if fail:
                    raise RuntimeError("fail")
        except RuntimeError:
            assert _digest(user) == before, (traits, "a failed run changed a user's file")
            continue
        except InputError as err:
            assert str(err).startswith("--out") and "\n" not in str(err), str(err)
            assert _digest(user) == before, (traits, "a refused run changed a user's file")
            continue
        assert victim.read_text() == "secret"
        final = Path(os.path.realpath(out))
        assert (final / "a.txt").read_text() == f"new {i}" and read_marker(final) is not None
        after = _digest(user)
        for f, content in before.items():
            inside = Path(f).resolve().is_relative_to(final) if os.path.exists(f) else \
                Path(f).parent.resolve().is_relative_to(final)
            if after[f] != content:
                assert overwrite and inside and not inputs, (traits, f, overwrite)
        assert not [p for p in root.iterdir() if ".partial-" in p.name]


# ------------------------------------------------------------------ L: hostile measured files
def _hostile_npy(rng, d: Path) -> Path:
    f = d / "m.npy"
    kind = int(rng.integers(6))
    z = np.random.default_rng(int(rng.integers(1 << 30))).normal(0, 1e-5, (12, 12))
    if kind == 0:
        z = np.full((12, 12), _pick(rng, [1e300, -1e300, 1e5, np.inf, np.nan, 5e-324]))
    elif kind == 1:
        z = np.full((12, 12), np.iinfo(np.uint64).max, dtype=np.uint64)
    elif kind == 2:
        z = z.astype(_pick(rng, [np.complex128, "U3", np.int8, np.float16, bool]))
    np.save(f, z)
    if kind == 3:
        shape = _pick(rng, [b"(True, True)", b"(-1, 12)", b"(12, 1e3)", b"(10**6, 10**6)",
                            b"(1, 1)", b"(12,)"])
        f.write_bytes(f.read_bytes().replace(b"(12, 12)", shape, 1))
    pixel = _pick(rng, [0.001, 1e300, 1e-12, 0.0, -1.0, [0.001, 1e9], "1", None, 150.0])
    origin = _pick(rng, [[0, 0], [1e300, 0], [1, 2, 3], None])
    side = {k: v for k, v in (("pixel_mm", pixel), ("origin_mm", origin)) if v is not None}
    if kind == 4:
        side["units"] = _pick(rng, ["m", "nm", "furlong", 3])
    f.with_suffix(".json").write_text(json.dumps(side))
    return f


def _hostile_zarr(rng, d: Path) -> Path:
    from render_inspect.io._heightmap import grid_attrs
    from render_inspect.io._zarr import write_heightmap_zarr

    z = np.random.default_rng(int(rng.integers(1 << 30))).normal(0, 1e-5, (24, 24))
    pixel = _pick(rng, [0.001, 0.001, 1e300, 1e-12])
    store = write_heightmap_zarr(d / "s.zarr", z, z, chunk=16, levels=0,
                                 attrs=grid_attrs(pixel, (0.0, 0.0), {}, {}))
    kind = int(rng.integers(7))
    for ch in ("design", "machined", "residual"):
        meta = store / ch / "zarr.json"
        m = json.loads(meta.read_text())
        if kind == 0:
            m["chunk_grid"]["configuration"]["chunk_shape"] = _pick(
                rng, [[0, 0], [-1, 4], [40000, 40000], [1, 1], [16]])
        elif kind == 1:
            m["data_type"] = _pick(rng, ["string", "complex128", "bool", "float64", "int8", "x"])
        elif kind == 2:
            m["shape"] = _pick(rng, [[0, 0], [24], [10 ** 6, 10 ** 6], [24, 25]])
        meta.write_text(json.dumps(m))
    chunk = store / "machined" / "c" / "0" / "0"
    if kind == 3:
        chunk.write_bytes(bytes(rng.integers(0, 256, int(rng.integers(0, 4000)), dtype=np.uint8)))
    elif kind == 4:
        chunk.unlink()
        os.symlink(_pick(rng, ["/dev/zero", "/dev/null", "/etc/hostname", "missing"]), chunk)
    elif kind == 5:
        chunk.unlink()  # a missing chunk reads as the fill value (NaN): fine
    return store


def _hostile_x3p(rng, d: Path, ref: Path) -> Path:
    import hashlib
    import zipfile

    zin = zipfile.ZipFile(ref)
    main = zin.read("main.xml").decode()
    size = _pick(rng, ["<SizeX >{n}</SizeX>", "<SizeX>{n}<!-- c --></SizeX>",
                       "<SizeX><![CDATA[{n}]]></SizeX>", "<SizeX>{n}</SizeX>", "<SizeX>1e{k}</SizeX>",
                       "<SizeX>-{n}</SizeX>", "<SizeX>{n}</SizeX><SizeX>12</SizeX>"])
    n = _pick(rng, [12, 13, 10 ** 5, 10 ** 9, 2 ** 40])
    main = main.replace("<SizeX>12</SizeX>", size.format(n=n, k=int(rng.integers(1, 30))))
    if rng.random() < 0.2:
        main = main.replace('<?xml version="1.0" encoding="UTF-8"?>',
                            '<?xml version="1.0"?><!DOCTYPE p [<!ENTITY e "1">]>')
    f = d / "m.x3p"
    with zipfile.ZipFile(f, "w", zipfile.ZIP_DEFLATED) as zout:
        for i in zin.infolist():
            data = zin.read(i)
            if i.filename == "main.xml":
                data = main.encode()
            elif i.filename == "md5checksum.hex":
                data = (hashlib.md5(main.encode()).hexdigest() + " *main.xml\n").encode()
            zout.writestr(i.filename, data)
    return f


def _hostile_frt(rng, d: Path) -> Path:
    from render_inspect.io._frt import frt_bytes

    counts = rng.integers(0, 3, size=(int(rng.integers(1, 8)), int(rng.integers(1, 8))))
    raw = frt_bytes(counts.astype(np.uint16), pixel_m=float(_pick(rng, [1e-6, 0.0, 1e300, -1e-6])),
                    zscale_m=float(_pick(rng, [1e-9, 1e300, 0.0])))
    f = d / "m.frt"
    f.write_bytes(_corrupt(rng, raw) if rng.random() < 0.4 else raw)
    return f


@pytest.mark.slow
def test_fuzz_hostile_measured_files(tmp_path, monkeypatch):
    """Hostile .npy headers and values, side-cars, Zarr stores (chunk shapes, data types,
    damaged or linked chunks, declared shapes), X3P size declarations and DTDs, FRT files:
    each is read as a plausible map (heights and pixels within bounds) or refused with an
    InputError naming the file; under a 256 MiB budget nothing allocates beyond it."""
    import render_inspect.core.limits as L
    from render_inspect.core.limits import MAX_ABS_MM, PIXEL_RANGE_MM
    from render_inspect.io import read_surface

    monkeypatch.setattr(L, "available_memory", lambda: int(256 * 2 ** 20 / L.AUTO_FRACTION))
    rng = _rng("hostile_files")
    ref = write_x3p(tmp_path / "ref.x3p", np.random.default_rng(3).normal(0, 1e-5, (12, 12)),
                    pixel=0.001)
    makers = [_hostile_npy, _hostile_zarr, lambda r, d: _hostile_x3p(r, d, ref), _hostile_frt]
    accepted = 0
    for i in range(CASES["hostile_files"]):
        d = tmp_path / f"f{i}"
        d.mkdir()
        f = makers[i % len(makers)](rng, d)
        tracemalloc.start()
        try:
            m = read_surface(f)
        except RenderInspectError as err:
            msg = str(err)
            assert f.name in msg and "\n" not in msg, msg
            continue
        finally:
            _, peak = tracemalloc.get_traced_memory()
            tracemalloc.stop()
            assert peak < 384 * 2 ** 20, (f, peak)
        accepted += 1
        ok = np.isfinite(m.z)
        assert ok.any() and np.abs(m.z[ok]).max() <= MAX_ABS_MM
        assert all(PIXEL_RANGE_MM[0] <= p <= PIXEL_RANGE_MM[1] for p in m.pixel)
    assert 0 < accepted < CASES["hostile_files"]


def test_fuzz_analyze_filters_and_maps(tmp_path):
    """Random --filter texts on random small maps: parse_filter and analyze_map accept
    them or refuse naming --filter (and the allowed range), never anything else."""
    from render_inspect.metrology import analyze_map, parse_filter

    rng = _rng("filters")
    tokens = ["", "0", "0.0025", "0.8", "2.5", "800", "1e-9", "1e300", "1e308", "-1", "nan",
              "inf", "0.01", "0.05", "x", " 0.02 ", "1e-3"]
    refused = 0
    for i in range(CASES["filters"]):
        spec = ",".join(_pick(rng, tokens) for _ in range(int(_pick(rng, [1, 2, 2, 2, 3]))))
        ny, nx = int(rng.integers(3, 40)), int(rng.integers(3, 40))
        z = np.random.default_rng(i).normal(0, 1e-5, (ny, nx))
        if rng.random() < 0.3:
            z[rng.random(z.shape) < 0.5] = np.nan
        try:
            s_mm, l_mm = parse_filter(spec)
            analyze_map(z, pixel=float(_pick(rng, [0.001, 0.0005, 0.01])), s_filter_mm=s_mm,
                        l_filter_mm=l_mm, form=_pick(rng, ["none", "plane"]))
        except InputError as err:
            refused += 1
            msg = str(err)
            assert msg.startswith(("--filter", "analyze_map:", "autocorrelation:",
                                   "areal_parameters:")), (spec, msg)
            assert "\n" not in msg
    assert 0 < refused < CASES["filters"]


@pytest.mark.slow
def test_fuzz_analyze_command_on_hostile_files(tmp_path, capsys, monkeypatch):
    """The analyze command on hostile files: exit 1, one line without a traceback or
    "internal error", no output folder."""
    rng = _rng("analyze_cli")
    ref = write_x3p(tmp_path / "ref.x3p", np.random.default_rng(3).normal(0, 1e-5, (12, 12)),
                    pixel=0.001)
    makers = [_hostile_npy, _hostile_zarr, lambda r, d: _hostile_x3p(r, d, ref), _hostile_frt]
    from render_inspect.cli import log, main

    for i in range(CASES["analyze_cli"]):
        d = tmp_path / f"a{i}"
        d.mkdir()
        f = makers[i % len(makers)](rng, d)
        out = d / "out"
        log.handlers.clear()
        rc = main(["analyze", str(f), "--out", str(out), "-q",
                   "--filter", _pick(rng, ["", ",0.005", "2.5,800", "1e-9,1e300"])])
        err = capsys.readouterr().err.strip().splitlines()
        log.handlers.clear()
        if rc == 0:
            assert (out / "metrics.json").is_file()
            continue
        assert rc == 1 and len(err) == 1, err
        assert "Traceback" not in err[0] and "internal error" not in err[0], err[0]
        assert not out.exists()


# ------------------------------------------------------------------ N: signals, limits
_SIGNAL_AT = """
import os, signal, sys
from render_inspect.io import _atomic
phase, sig = sys.argv[1], getattr(signal, sys.argv[2])
def hook(name, fn):
    orig = getattr(_atomic, name)
    def wrapped(*a, **k):
        if name == phase:
            os.kill(os.getpid(), sig)
        return orig(*a, **k)
    setattr(_atomic, name, wrapped)
for name in ("_restore_backup", "_write_marker", "_swap_in", "_clean_stale"):
    hook(name, None)
from render_inspect import cli
sys.exit(cli.main(sys.argv[3:]))
"""


@pytest.mark.slow
def test_fuzz_signals_at_every_phase_of_the_folder(tmp_path):
    """SIGINT / SIGTERM at each phase of writing an output folder (after the lock, while
    the marker is written, during the swap, during the clean-up after it): exit 130 /
    143, and the message matches what happened to the folder."""
    rng = _rng("signals")
    # the program kept small (120 points per revolution): the signals come while the
    # folder is written, after the program is made, whatever its size
    scene_args = ["toolpath", "sts_sinusoidal_grid", "--set", "process.points_per_rev=120", "-q"]
    phases = ["_restore_backup", "_write_marker", "_swap_in", "_clean_stale"]
    for i in range(CASES["signals"]):
        phase = phases[i % len(phases)]
        sig, code = _pick(rng, [("SIGINT", 130), ("SIGTERM", 143)])
        out = tmp_path / f"o{i}"
        with atomic_output_dir(out, command="old") as tmp:
            (tmp / "old.txt").write_text("old")
        r = subprocess.run([sys.executable, "-c", _SIGNAL_AT, phase, sig, *scene_args,
                            "--out", str(out)], capture_output=True, text=True, timeout=300)
        assert r.returncode == code, (phase, sig, r.stderr)
        assert "Traceback" not in r.stderr and len(r.stderr.strip().splitlines()) == 1, r.stderr
        replaced = not (out / "old.txt").exists()
        # the marker, the swap and the clean-up run with the signals held: the folder is
        # put in place first; the lock and the inspection come before anything is written
        assert replaced == (phase != "_restore_backup"), (phase, r.stderr)
        if replaced:
            assert "had been written completely" in r.stderr and (out / "toolpath.npz").is_file()
        else:
            assert "left as it was" in r.stderr and set(read_marker(out)["commands"]) == {"old"}
        assert not [p for p in tmp_path.iterdir() if ".partial-" in p.name or ".lock" in p.name]


@pytest.mark.slow
def test_fuzz_commands_under_an_address_space_limit(tmp_path):
    """Commands run under ``ulimit -v`` (RLIMIT_AS): refused at the start with one line
    naming the limit, or finished; never a segmentation fault or a late MemoryError."""
    import resource

    big = np.random.default_rng(0).normal(0, 1e-5, (3000, 3000))
    np.save(tmp_path / "big.npy", big)
    (tmp_path / "big.json").write_text('{"pixel_mm": 0.001}')
    del big
    runs = [["simulate", "sts_sinusoidal_grid", "--set", "simulation.region=[-1,-1,1,1]",
             "--set", "simulation.pixel=0.0004"],
            ["analyze", str(tmp_path / "big.npy")],
            ["render", "sts_sinusoidal_grid", "--kind", "diffuse", "--set",
             "simulation.region=[-0.1,-0.1,0.1,0.1]"]]
    for i, args in enumerate(runs[:CASES["address_space"]]):
        out = tmp_path / f"o{i}"

        def cap():
            resource.setrlimit(resource.RLIMIT_AS, (1536 * 2 ** 20, 1536 * 2 ** 20))

        r = subprocess.run([sys.executable, "-m", "render_inspect.cli", *args, "--out", str(out),
                            "-q"], capture_output=True, text=True, timeout=300, preexec_fn=cap)
        assert r.returncode in (0, 1), (args, r.returncode, r.stderr[-500:])
        if r.returncode == 1:
            err = r.stderr.strip().splitlines()
            assert len(err) == 1 and "ulimit -v" in err[0] and "Traceback" not in r.stderr, err
            assert not out.exists()


# ------------------------------------------------------------------ O: sweeps and regress
CASES.update({"sweep_files": 60 * SCALE, "regress_inputs": 60 * SCALE,
              "scheduler_addresses": 40 * SCALE})

_SWEEP_KEYS = ["tool.nose_radius", "process.feed_mm_per_min", "process.spindle_rpm",
               "simulation.seed", "tool.nose_radus", "nose_radius", "simulation.region",
               "process.kind", "machine.preset", "material.preset", "design.amplitude_x",
               "render.interferometer.wavelength_nm", "..", "a.", ".b", "x.y.z", "=cmd.x"]
_SWEEP_VALUES = [0.2, 0.5, 1, -1, 0, 1e300, "ideal", "=1+2", "@SUM(A1)", "-x", "a\n# b", True,
                 [0.1], [-0.02, -0.02, 0.02, 0.02], [], {}, "sts", 7]
_NAMES = ["ok", "ok_2.v", "", "../evil", "/tmp/evil", ".hidden", "a/b", "x\ny", "=HYPERLINK(1)",
          "-", "a" * 101, "con", "..", "a..b", " sp", "\t"]
_SCENES = ["sts_sinusoidal_grid", "/etc/passwd", "../../nope.toml", "nope", "", "/dev/null",
           "sweep.toml"]


def _sweep_text(rng) -> str:
    """A sweep file: a small valid core (ideal machine, small region) and random mutations."""
    from render_inspect.batch import toml_value

    lines = [f"scene = {toml_value(_pick(rng, _SCENES) if rng.random() < 0.3 else 'sts_sinusoidal_grid')}"]
    if rng.random() < 0.5:
        lines.append(f"name = {toml_value(_pick(rng, _NAMES))}")
    sets = {"machine.preset": "ideal", "material.preset": "ideal",
            "simulation.region": [-0.02, -0.02, 0.02, 0.02], "simulation.pixel": 0.002,
            "process.workpiece_radius": 0.05}
    if rng.random() < 0.4:
        sets[_pick(rng, _SWEEP_KEYS)] = _pick(rng, _SWEEP_VALUES)
    lines.append("[set]")
    lines += [f"{json.dumps(k)} = {toml_value(v)}" for k, v in sets.items()]
    kind = rng.integers(4)
    if kind == 1:
        n = int(_pick(rng, [1, 2, 3, 1000]))
        lines.append("[grid]")
        for _ in range(int(rng.integers(1, 4))):
            lines.append(f"{json.dumps(_pick(rng, _SWEEP_KEYS))} = "
                         f"{toml_value([_pick(rng, _SWEEP_VALUES) for _ in range(n)] if n < 10 else list(range(n)))}")
    elif kind == 2:
        lines.append("[[study]]")
        lines.append(f"name = {toml_value(_pick(rng, _NAMES))}")
        lines.append(f"set = {{ {json.dumps(_pick(rng, _SWEEP_KEYS))} = {toml_value(_pick(rng, _SWEEP_VALUES))} }}")
    elif kind == 3:
        lines.append("[[plot]]")
        lines.append('kind = "curves"\nx = "tool.nose_radius"')
        lines.append(f"name = {toml_value(_pick(rng, _NAMES))}")
    if rng.random() < 0.2:
        lines.append(_pick(rng, ["[run]\nrender = \"nope\"", "[run]\nmeasure = true",
                                 "workers = 3", "[zip]\n\"tool.nose_radius\" = [1, 2]\n"
                                 "\"process.spindle_rpm\" = [1]", "\x00"]))
    return "\n".join(lines) + "\n"


@pytest.mark.slow
def test_fuzz_sweep_files(tmp_path, capsys, monkeypatch):
    """Random sweep files through ``render-inspect sweep`` (the points' runs replaced by a
    stub: what is fuzzed is everything before and after them): exit 0, or 1 with one
    message and no traceback; a refused sweep writes nothing; nothing is written outside
    ``--out`` whatever the names say; each case within a few seconds."""
    import time as _time

    import render_inspect.pipeline._sweep as sw
    from render_inspect.cli import log, main

    ran = []

    @__import__("contextlib").contextmanager
    def no_cluster(**kw):
        yield None

    def fake_run(c, todo, records, results, info, *, total, progress, check=None):
        ran.append(len(todo))  # every point refused or recorded failed: the files still follow
        for t in todo:
            rec = {"id": t["id"], "index": t["index"], "params": t["params"], "studies": t["studies"],
                   "overrides": t["overrides"], "folder": None, "status": "failed",
                   "error": "=not run (fuzz)\n# x", "error_type": "Fuzz"}
            results.append(rec)
            records[t["id"]] = rec

    monkeypatch.setattr(sw, "dask_client", no_cluster)
    monkeypatch.setattr(sw, "_run_on_dask", fake_run)
    rng = _rng("sweep_files")
    root = tmp_path / "root"
    for i in range(CASES["sweep_files"]):
        case = root / f"c{i}"
        (case / "in").mkdir(parents=True)
        f = case / "in" / "sweep.toml"
        f.write_text(_sweep_text(rng))
        before = {p for p in tmp_path.rglob("*")}
        out = case / "in" / "out"
        log.handlers.clear()
        t0 = _time.monotonic()
        rc = main(["sweep", str(f), "--out", str(out), "-q"])
        dt = _time.monotonic() - t0
        err = capsys.readouterr().err.strip()
        log.handlers.clear()
        assert dt < 20, (f.read_text(), dt)
        assert rc in (0, 1), (rc, err, f.read_text())
        assert "Traceback" not in err and "internal error" not in err, (err, f.read_text())
        new = {p for p in tmp_path.rglob("*")} - before
        assert all(out == p or out in p.parents for p in new), (sorted(map(str, new)), f.read_text())
        if out.exists():
            csv_text = (out / "results.csv").read_text()
            for row in __import__("csv").reader(io.StringIO(csv_text)):
                assert not any(c.startswith(("=", "+", "@", "\t", "\r")) for c in row), row
            md = (out / "summary.md").read_text()
            assert not any(ln.startswith("# ") for ln in md.splitlines()[1:]), md
        else:
            assert rc == 1 and err.startswith("render-inspect sweep: error:"), err


@pytest.mark.mitsuba
def test_fuzz_regress_inputs(tmp_path):
    """Random ``--only`` patterns, ``--set`` texts and case files through ``run_regress``
    (rendering replaced by a stub that says a case was accepted): a case is accepted or
    refused with a :class:`RenderInspectError`; nothing else escapes."""
    import render_inspect.pipeline._regress as rg
    from render_inspect.pipeline import run_regress

    class Accepted(Exception):
        pass

    def stub(*a, **k):
        raise Accepted

    mp = pytest.MonkeyPatch()
    mp.setattr(rg, "case_images", stub)
    rng = _rng("regress_inputs")
    shipped = (Path(rg.regression_cases_dir()) / "sts_grid_z.toml").read_text()
    onlys = [None, "sts_grid_z", "nope", "*", "sts_*", "a,,b", "../x", "[", "\x00", "," * 50,
             "c0"]
    sets = ["simulation.seed=7", "simulation.seed=-1", "simulation.seed=1e9",
            "simulation.seed='x'", "simulation.seed=", "tool.nose_radius=0.4",
            "tool.nose_radus=1", "=", "x", "simulation.seed=2000000", "render.diffuse.spp=0"]
    mutations = ["", "\nimages = [\"nope\"]", "\npasses = 0", "\nreference_passes = -1",
                 "\n[tolerance.residual]\natol = -1", "\n[set]\n\"x.y\" = 1", "\x00",
                 "\nscene = \"/etc/passwd\""]
    try:
        for i in range(CASES["regress_inputs"]):
            cases = tmp_path / f"r{i}"
            cases.mkdir()
            text = shipped + _pick(rng, mutations) if rng.random() < 0.7 else \
                shipped.replace("sts_sinusoidal_grid", _pick(rng, _SCENES))
            (cases / "c0.toml").write_text(text)
            overrides = [_pick(rng, sets) for _ in range(int(rng.integers(0, 3)))]
            try:
                run_regress(cases=cases, only=_pick(rng, onlys), out=cases / "out",
                            overrides=overrides, update=bool(rng.random() < 0.1))
            except Accepted:
                pass
            except RenderInspectError as err:
                assert str(err).strip() and "Traceback" not in str(err)
    finally:
        mp.undo()


def test_fuzz_scheduler_addresses(tmp_path):
    """Random ``--scheduler`` texts: malformed ones refused at once, well-formed ones to
    closed ports refused within seconds; always one :class:`InputError`."""
    import time as _time

    from render_inspect.batch import dask_client

    rng = _rng("scheduler_addresses")
    pieces = ["tcp://", "tls://", "", "127.0.0.1", "localhost", "[::1]", "host with space",
              "a" * 300, ":9", ":0", ":99999", ":-1", "/x", "\n", "\x00", "tcp://127.0.0.1:9",
              "udp://x:1", "127.0.0.1:1"]
    for _ in range(CASES["scheduler_addresses"]):
        addr = "".join(_pick(rng, pieces) for _ in range(int(rng.integers(1, 4))))
        t0 = _time.monotonic()
        with pytest.raises(InputError):
            with dask_client(scheduler=addr):
                pass
        assert _time.monotonic() - t0 < 20, addr


# ------------------------------------------------------------------ P: every command, bad input
def _every_command_cases(tmp: Path) -> list[tuple[list, str, int]]:
    """(arguments, what the one line must name, exit code) for every command."""
    (tmp / "bin.toml").write_bytes(b"\x00\xff" * 50)
    (tmp / "empty.npy").write_bytes(b"")
    (tmp / "a_file").write_text("x")
    sweep = tmp / "bad_sweep.toml"
    sweep.write_text('name = "s"\nscene = "sts_sinusoidal_grid"\n[grid]\n"process.spindle_rpm" = [10, 20]\n'
                     '[run]\nrender = "bogus"\n')
    from render_inspect.io import write_measurement_exr

    measured = tmp / "height.exr"  # a measured map as measure writes it (a tilted plane)
    z = 1e-5 * np.arange(64)[None, :] + np.zeros((64, 1))
    write_measurement_exr(measured, z, np.ones_like(z, bool), pixel=0.001, origin=(0.3, -0.05),
                          attrs={"objective": "20x", "mode": "psi"})
    fit = ["fit", measured, "--scene", "sts_sinusoidal_grid"]
    return [
        (["simulate", "sts_sinusoidal_grid", "--tiled", "--tile", "20000", "--set",
          "material.preset='ideal'"], "--tile", 1),
        (["simulate", "sts_sinusoidal_grid", "--set", "simulation.region=[-500,-500,500,500]"],
         "simulation.region", 1),
        (["simulate", "sts_sinusoidal_grid", "--set", "simulation.region=[0,0,1]"],
         "simulation.region", 1),
        (["toolpath", "sts_sinusoidal_grid", "--set", "process.clearance=0.001"],
         "process.clearance", 1),
        (["toolpath", "sculpt_quad_mla", "--format", "bogus"], "--format", 2),
        (["render", "sts_sinusoidal_grid", "--set", "render.interferometer.numerical_aperture=3"],
         "numerical_aperture", 1),
        (["compare", "sts_sinusoidal_grid", "--measured", tmp / "missing.zarr"], "--measured", 1),
        (["compare", "sts_sinusoidal_grid", "--vary", "process.nope=1,2"], "process.nope", 1),
        (["analyze", tmp / "empty.npy"], "empty.npy", 1),
        (["analyze", tmp / "a_file", "--filter", "a,b"], "--filter", 1),
        (["measure", tmp / "nope.exr"], "nope.exr", 1),
        (["measure", tmp / "a_file", "--min-modulation", "5"], "a_file", 1),
        (["characterise", "--objective", "7x"], "7x", 2),
        (["characterise", "--set", "numerical_aperture=3"], "numerical_aperture", 1),
        (["sweep", tmp / "bin.toml"], "bin.toml", 1),
        (["sweep", sweep], "run.render", 1),
        (["regress", "--only", "no_such_case"], "no_such_case", 1),
        (["regress", "--update", "--set", "process.spindle_rpm=10"], "--set", 1),
        (["demo"], "--out", 1),
        (["fit", tmp / "nope.exr", "--scene", "sts_sinusoidal_grid", "--free", "tool.nose_radius"],
         "nope.exr", 1),
        ([*fit, "--free", "tool.nose_radius", "--bounds", "tool.nose_radius=-1,2"],
         "tool.nose_radius", 1),
        ([*fit, "--free", "process.nope"], "process.nope", 1),
        ([*fit, "--free", "tool.nose_radius", "--cache", tmp / "a_file"], "--cache", 1),
        ([*fit, "--free", "tool.nose_radius", "--window", "-1"], "--window", 1),
        (fit, "--free", 2),
    ]


@pytest.mark.slow
def test_fuzz_every_command_refuses_bad_input_in_one_line(tmp_path):
    """Bad input to every command, in a fresh process: one line naming the input, exit 1
    (2 for a usage error), no traceback, no output folder and no temporary left."""
    cases = _every_command_cases(tmp_path)
    assert {c[0][0] for c in cases} == {"simulate", "toolpath", "render", "compare", "analyze",
                                        "measure", "characterise", "sweep", "regress", "demo",
                                        "fit"}
    for i, (args, key, code) in enumerate(cases):
        out = tmp_path / f"out{i}"
        extra = ["--out", str(tmp_path / "a_file" / "out")] if args[0] == "demo" else \
            ["--out", str(out)]
        r = subprocess.run([sys.executable, "-m", "render_inspect.cli", *map(str, args), *extra, "-q"],
                           capture_output=True, text=True, cwd=tmp_path, timeout=300)
        assert r.returncode == code, (args, r.returncode, r.stderr[-500:])
        assert "Traceback" not in r.stderr and key in r.stderr, (args, r.stderr[-500:])
        if code == 1:
            assert len(r.stderr.strip().splitlines()) == 1, r.stderr
        assert not out.exists() and not (tmp_path / f"out{i}.cache").exists(), args
        assert not [p for p in tmp_path.iterdir() if ".partial-" in p.name or
                    p.name.endswith(".lock")], args


# ------------------------------------------------------------------ Q: the Blender operators' tasks
def test_fuzz_blender_tasks_refuse_bad_parameters_cleanly(tmp_path):
    """The add-on's operators run the tasks of ``blender_addon/_tasks.py`` (in a worker or
    in Blender): bad parameters of every task end as the errors the worker reports in one
    line (RenderInspectError or OSError), never another exception, and write nothing."""
    import importlib.util

    spec = importlib.util.spec_from_file_location(
        "render_inspect_addon_tasks", Path(__file__).resolve().parents[1] / "blender_addon" / "_tasks.py")
    tasks = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(tasks)
    (tmp_path / "a_file").write_text("x")
    render = {"heightmap": str(tmp_path / "none.exr"), "variant": "v", "surface": "machined",
              "exaggeration": 1.0, "view": "micro", "resolution": 64, "samples": 4, "seed": 0,
              "out": str(tmp_path / "o")}
    rng = _rng("blender")
    cases = [
        ("simulate", {"scene_path": str(tmp_path / "none.toml"), "out": str(tmp_path / "o")}),
        ("simulate", {"scene_path": "sts_sinusoidal_grid", "overrides": ["process.spindle_rpm=-1"],
                      "out": str(tmp_path / "o")}),
        ("simulate", {"scene_path": "sts_sinusoidal_grid", "overrides": [5], "out": str(tmp_path / "o")}),
        ("simulate", {"scene_path": "sts_sinusoidal_grid", "out": str(tmp_path / "a_file" / "o")}),
        ("simulate", {"scene_path": "sts_sinusoidal_grid", "surface": "bogus", "out": str(tmp_path / "o")}),
        ("simulate", {"scene_path": "sts_sinusoidal_grid", "exaggeration": -5, "out": str(tmp_path / "o")}),
        ("render", render),
        ("render", {**render, "heightmap": str(tmp_path / "a_file")}),
        ("compare", {"scene_path": "sts_sinusoidal_grid", "overrides": ["bad key=1"],
                     "out": str(tmp_path / "o")}),
        ("compare", {"scene_path": str(tmp_path / "a_file"), "out": str(tmp_path / "o")}),
        ("export", {"heightmap": str(tmp_path / "none.exr"), "variant": "v", "surface": "machined",
                    "exaggeration": 1.0, "formats": ["bogus"], "out": str(tmp_path / "o")}),
        ("export", {"heightmap": str(tmp_path / "none.exr"), "variant": "v", "surface": "machined",
                    "exaggeration": 1.0, "formats": [{"a": 1}], "out": str(tmp_path / "o")}),
    ]
    for _ in range(CASES["blender"]):  # hostile values in the render task's parameters
        key = _pick(rng, [k for k in render if k not in ("heightmap", "out")])
        cases.append(("render", {**render, key: copy.deepcopy(_pick(rng, HOSTILE))}))
    for task, params in cases:
        with pytest.raises((RenderInspectError, OSError)):
            tasks.run(task, params)
        assert not (tmp_path / "o").exists(), (task, params)


# ------------------------------------------------------------------ R: written programs
def _shipped_program_scenes():
    """Every shipped scene with its program kept small: the turning programs sampled at
    120 points per revolution (the same part, links and limits; a third of the blocks to
    read back and verify for every change)."""
    out = {}
    for name in shipped_scenes():
        scene = load_scene(name)
        sets = ["process.points_per_rev=120"] if hasattr(scene.process, "points_per_rev") else []
        if scene.process.kind == "sculpt":
            sets = ["process.arc_length=0.01"]
        out[name] = load_scene(name, sets)
    return out


_UNSAFE = ["rapid_low", "plunge_sideways", "cut_below", "feed_high", "no_retract", "no_link",
           "plunge_fast"]


def _program_sites(lines: list[str]) -> tuple[list[int], list[int], list[int]]:
    """The blocks of a written program an unsafe change can hit: its rapids, its feeds
    outside the cut (approach, link, exit) and its cutting blocks with a feed."""
    blocks = [i for i, ln in enumerate(lines) if ln.startswith("N")]
    sec, where = None, {}
    for i, ln in enumerate(lines):
        if ln.startswith("; ") and ln[2:].split(" ")[0] in ("approach", "cut", "link", "exit", "line"):
            sec = ln[2:].split(" ")[0]
        elif ln.startswith("N"):
            where[i] = sec
    rapids = [i for i in blocks[1:] if " G00 " in lines[i] and "X" in lines[i]]
    feeds = [i for i in blocks if " G01 " in lines[i] and where[i] in ("approach", "link", "exit")]
    cuts = [i for i in blocks if where[i] in ("cut", "line") and " F" in lines[i]]
    return rapids, feeds, cuts


def _mutate_program(lines: list[str], kind: str, rng, sites=None) -> list[str] | None:
    """One unsafe change of a written program (None when the program has no block for it);
    ``sites``: :func:`_program_sites` of ``lines``, when already known."""
    rapids, feeds, cuts = sites if sites is not None else _program_sites(lines)
    out = list(lines)

    def sub(i, word, fn):
        out[i] = re.sub(rf"{word}(-?[0-9.e+]+)", lambda m: f"{word}{fn(float(m.group(1))):.6f}",
                        out[i], count=1)

    if kind == "rapid_low" and rapids:
        sub(int(_pick(rng, rapids)), "Z", lambda z: 0.0)
    elif kind == "plunge_sideways" and feeds:
        sub(int(_pick(rng, feeds)), "X", lambda x: x + 0.05)
    elif kind == "cut_below" and len(cuts) > 2:
        sub(int(_pick(rng, cuts[1:-1])), "Z", lambda z: z - 0.01)
    elif kind == "feed_high" and cuts:
        i = int(_pick(rng, cuts))
        out[i] = re.sub(r"F([0-9.e+]+)", lambda m: f"F{float(m.group(1)) * 1e4:.10g}", out[i])
    elif kind == "no_retract" and feeds:
        retracts = [i for i in feeds if i + 1 < len(out) and " G00 " in out[i + 1]]
        if not retracts:
            return None
        del out[int(_pick(rng, retracts))]
    elif kind == "no_link" and "; link" in out:
        k = out.index("; link")
        del out[k:k + 4]
    elif kind == "plunge_fast" and feeds:
        i = int(_pick(rng, feeds))
        out[i] = re.sub(r"F([0-9.e+]+)", lambda m: f"F{float(m.group(1)) * 100:.10g}", out[i])
    else:
        return None
    return out


@pytest.mark.slow
def test_fuzz_written_programs_are_verified_and_unsafe_ones_refused(tmp_path):
    """The NC program of every shipped scene is written, read back and verified (the
    toolpath command refuses to write one that fails); seeded unsafe changes of those
    programs (a rapid through the part, a sideways plunge, a cut below the design, a feed
    over the limit, a missing retract or link, a plunge far faster than the plunge feed)
    are all refused
    naming a block: zero unsafe programs accepted, zero tracebacks."""
    from render_inspect.io import read_nc_blocks
    from render_inspect.pipeline import run_toolpath
    from render_inspect.toolpath import verify_blocks

    rng = _rng("programs")
    accepted_unsafe, refused = [], 0
    for name, scene in _shipped_program_scenes().items():
        folder = tmp_path / name
        run_toolpath(scene, folder, fmt="nc")
        facts = json.loads((folder / "toolpath.json").read_text())["program_check"]
        assert facts["clearance_above_part_mm"] >= 0.1 - 2e-6 and facts["as_planned"]["points"] > 0
        process = process_of(scene)
        cfg = process.inputs_of(scene)
        surface = make_surface(scene.design)
        plan = plan_program(scene, surface=surface)
        part, limits = process.program_part(cfg, surface, plan), process.program_limits(cfg)
        links = process.program_links(cfg, surface, plan)
        lines = (folder / "toolpath.nc").read_text().splitlines()
        sites = _program_sites(lines)
        for k in range(CASES["programs"]):
            kind = _UNSAFE[k % len(_UNSAFE)]
            bad = _mutate_program(lines, kind, rng, sites)
            if bad is None:
                continue
            f = tmp_path / "mutated.nc"
            f.write_text("\n".join(bad) + "\n")
            try:
                verify_blocks(read_nc_blocks(f), part, limits, links)
            except InputError as err:
                assert re.search(r"block N\d+ \(G0[01], ", str(err)), str(err)
                refused += 1
            else:
                accepted_unsafe.append((name, kind))
    assert not accepted_unsafe, accepted_unsafe
    assert refused >= len(_UNSAFE)


# ------------------------------------------------------------------ R1: the part's top
CASES.update({"peaks": 40 * SCALE, "bounded_expressions": 150 * SCALE})


class TestFuzzPartTop:
    """The clearance plane's height: the design's true highest point over the part, found
    by an interval bound however narrow the peak and wherever it stands, and never below
    any height the design takes there."""

    def test_narrow_peaks_anywhere_are_found(self):
        from render_inspect.design import max_height

        rng = _rng("peaks")
        for _ in range(CASES["peaks"]):
            r, a = 0.95 * math.sqrt(rng.random()), rng.uniform(0, 2 * math.pi)
            cx, cy = r * math.cos(a), r * math.sin(a)
            h, w = rng.uniform(1e-3, 1.0), 10 ** rng.uniform(-4.5, -2)
            expr = (f"{h!r}*exp(-((x-{cx!r})**2 + (y-{cy!r})**2)/(2*{w!r}**2)) "
                    f"+ 1e-3*cos(3*x) - 2e-3*y**2")
            s = ExpressionSurface(expr)
            b = max_height(s, ("disc", 0.0, 0.0, 1.0), tolerance=1e-6)
            peak = float(s.height(np.array([cx]), np.array([cy]))[0])
            assert b.method == "interval" and b.high >= peak and b.high - b.low <= 1.1e-6, expr

    def test_random_formulas_are_bounded_from_above(self):
        from render_inspect.design import max_height

        rng = _rng("bounded_expressions")
        checked = 0
        u = rng.uniform(-1, 1, (2, 4000))
        inside = np.hypot(*u) <= 1
        for _ in range(CASES["bounded_expressions"]):
            try:
                s = ExpressionSurface(_expr(rng, int(rng.integers(1, 6))), {"a": 2.0})
                z = s.height(u[0][inside], u[1][inside])
            except InputError:
                continue
            b = max_height(s, ("disc", 0.0, 0.0, 1.0))
            if b is None:
                continue
            assert float(z.max()) <= b.high, s.expr
            checked += 1
        assert checked > 20


# ------------------------------------------------------------------ R2: write errors
CASES.update({"write_errors": 24 * SCALE, "zarr_trees": 30 * SCALE, "diffuse_sizes": 60 * SCALE,
              "tile_stops": 6 * SCALE, "input_kinds": 20 * SCALE})


class TestFuzzWriteErrors:
    """A write that fails for want of space, quota or a working disk, in any writer and
    any file of an output folder: one line naming the file and the cause, and nothing
    left behind (no folder, no partial folder, no temporary file)."""

    def test_write_errors_in_an_output_folder(self, tmp_path, monkeypatch):
        import errno as errno_

        import OpenEXR as real_exr

        from render_inspect.io import _atomic_write

        rng = _rng("write_errors")
        codes = [errno_.ENOSPC, errno_.EDQUOT, errno_.EIO, errno_.EFBIG]
        for i in range(CASES["write_errors"]):
            code = int(_pick(rng, codes))
            writer = _pick(rng, ["exr", "text", "x3p"])
            name = {"exr": "diffuse.exr", "text": "metrics.json", "x3p": "height.x3p"}[writer]

            class File:
                def __init__(self, *a, **k):
                    pass

                def __enter__(self):
                    return self

                def __exit__(self, *exc):
                    return False

                def write(self, path, code=code):
                    raise RuntimeError(f'Failed to write pixel data to image file "{path}". '
                                       f'{os.strerror(code)}.')

            with monkeypatch.context() as m:
                if writer == "exr":
                    import types

                    fake = types.ModuleType("OpenEXR")
                    fake.__dict__.update({k: getattr(real_exr, k) for k in dir(real_exr)
                                          if not k.startswith("__")})
                    fake.File = File
                    m.setitem(sys.modules, "OpenEXR", fake)
                else:
                    def full(path, *a, code=code, **k):
                        raise OSError(code, os.strerror(code), str(path))
                    m.setattr(_atomic_write, "atomic_write_stream", full)
                out = tmp_path / f"o{i}"
                with pytest.raises(InputError) as info:
                    with atomic_output_dir(out, command="render") as tmp:
                        if writer == "exr":
                            write_exr(tmp / name, {"R": np.zeros((4, 4))})
                        elif writer == "text":
                            _atomic_write.atomic_write_text(tmp / name, "{}")
                        else:
                            write_x3p(tmp / name, np.zeros((4, 4)), pixel=0.001)
            msg = str(info.value)
            assert "\n" not in msg and os.strerror(code) in msg, (writer, msg)
            if writer != "x3p":  # the x3p writer names its own temporary member
                assert name in msg, (writer, msg)
            assert os.listdir(tmp_path) == [], (writer, os.listdir(tmp_path))


# ------------------------------------------------------------------ R3: zarr stores
class TestFuzzZarrStores:
    """Stores with links, pipes and oversized metadata anywhere inside: refused in one
    line before zarr reads them; a store without them reads."""

    def test_hostile_store_trees(self, tmp_path):
        from render_inspect.io import ZarrHeightMap
        from render_inspect.io._heightmap import grid_attrs
        from render_inspect.io._zarr import write_heightmap_zarr

        rng = _rng("zarr_trees")
        z = np.zeros((24, 24))
        other = write_heightmap_zarr(tmp_path / "other.zarr", z + 1, z + 1, chunk=16, levels=1,
                                     attrs=grid_attrs(0.001, (0.0, 0.0), {}, {}))
        for i in range(CASES["zarr_trees"]):
            s = write_heightmap_zarr(tmp_path / f"s{i}.zarr", z, z, chunk=16, levels=1,
                                     attrs=grid_attrs(0.001, (0.0, 0.0), {}, {}))
            entries = sorted(p.relative_to(s) for p in s.rglob("*"))
            rel = _pick(rng, entries)
            target = s / rel
            kind = _pick(rng, ["link_other", "link_outside", "dangling", "fifo", "huge", "none"])
            if kind in ("link_other", "link_outside", "dangling", "fifo"):
                if target.is_dir():
                    import shutil

                    shutil.rmtree(target)
                else:
                    target.unlink()
                if kind == "fifo":
                    os.mkfifo(target)
                else:
                    os.symlink({"link_other": other / rel, "link_outside": "/etc/hostname",
                                "dangling": tmp_path / "missing"}[kind], target)
            elif kind == "huge":
                meta = [p for p in s.rglob("zarr.json")]
                f = _pick(rng, meta)
                with open(f, "r+b") as fh:
                    fh.truncate(17 * 2 ** 20)
            if kind == "none":
                ZarrHeightMap(s).read("machined")
                continue
            with pytest.raises(InputError) as info:
                ZarrHeightMap(s).read("machined")
            msg = str(info.value)
            assert "\n" not in msg and str(s) in msg, (kind, rel, msg)


# ------------------------------------------------------------------ R4: memory estimates
class TestFuzzMemoryEstimates:
    """The diffuse estimate grows with the image, not with the samples per pixel (the
    wavefront's per-pixel arrays), and a spectral render needs more than an RGB one;
    the NC program's estimate grows with its points."""

    def test_estimates_follow_their_drivers(self):
        from render_inspect.pipeline._toolpath import nc_memory
        from render_inspect.render import DiffuseConfig, diffuse_memory

        rng = _rng("diffuse_sizes")
        for _ in range(CASES["diffuse_sizes"]):
            res = int(rng.integers(16, 8193))
            spp = int(rng.integers(1, 1025))
            shape = (int(rng.integers(2, 4000)), int(rng.integers(2, 4000)))
            a = diffuse_memory(DiffuseConfig(resolution=res, spp=spp), shape)
            b = diffuse_memory(DiffuseConfig(resolution=res, spp=1), shape)
            c = diffuse_memory(DiffuseConfig(resolution=min(res * 2, 8192), spp=spp), shape)
            rgb = diffuse_memory(DiffuseConfig(resolution=res, spp=spp), shape, spectral=False)
            assert a == b and c >= a and rgb < a
            assert a >= res * res * 1000
        scene = load_scene("sts_sinusoidal_grid", ["simulation.max_memory_gb=64"])
        assert nc_memory(scene, 2_000_000) > nc_memory(scene, 1_000_000) > 1_000_000 * 250


# ------------------------------------------------------------------ R5: signals
class TestFuzzSignalsAnytime:
    """A stop at a random moment of a threaded tile run: the run raises only once every
    tile that started has ended (none writes into a folder after it was removed)."""

    def test_stops_at_random_moments(self):
        import threading
        import time

        from render_inspect.batch import _tiled

        rng = _rng("tile_stops")
        for _ in range(CASES["tile_stops"]):
            state = {"started": 0, "ended": 0}
            lock = threading.Lock()
            durations = rng.uniform(0.01, 0.15, 12)
            stop_after = int(rng.integers(1, 8))

            def tile(i):
                with lock:
                    state["started"] += 1
                time.sleep(float(durations[i]))
                with lock:
                    state["ended"] += 1
                return i

            def progress(done, total, dt):
                if done >= stop_after:
                    raise KeyboardInterrupt

            with pytest.raises(KeyboardInterrupt):
                _tiled._run(tile, [(i,) for i in range(12)], (), workers=int(rng.integers(2, 5)),
                            progress=progress)
            assert state["ended"] == state["started"], state


# ------------------------------------------------------------------ R6: input kinds
class TestFuzzInputKinds:
    """Paths that are not files (pipes, devices, folders, missing) given to the readers:
    one line saying which; a scene with a byte-order mark reads as the scene."""

    def test_paths_that_are_not_files(self, tmp_path, capsys):
        from render_inspect import cli

        rng = _rng("input_kinds")
        want = {"fifo": "named pipe", "device": "device", "folder": "folder",
                "missing": "not found"}
        for i in range(CASES["input_kinds"]):
            kind = _pick(rng, list(want))
            suffix = _pick(rng, [".npy", ".exr", ".x3p", ".sur", ".tmd"])
            p = tmp_path / f"in{i}{suffix}"
            if kind == "fifo":
                os.mkfifo(p)
            elif kind == "device":
                os.symlink(_pick(rng, ["/dev/zero", "/dev/null", "/dev/urandom"]), p)
            elif kind == "folder":
                p.mkdir()
            rc = cli.main(["analyze", str(p), "--out", str(tmp_path / f"o{i}"), "-q"])
            err = capsys.readouterr().err.strip().splitlines()
            assert rc == 1 and len(err) == 1 and want[kind] in err[0], (kind, err)
            assert not (tmp_path / f"o{i}").exists()

    def test_a_byte_order_mark(self, tmp_path):
        raw = find_scene("sts_sinusoidal_grid").read_bytes()
        (tmp_path / "a.toml").write_bytes(b"\xef\xbb\xbf" + raw)
        assert load_scene(str(tmp_path / "a.toml")).to_dict() == \
            load_scene("sts_sinusoidal_grid").to_dict()


# ------------------------------------------------------------------ R7: verifier limits
CASES.update({"plunge_feeds": 8 * SCALE, "depths": 4 * SCALE, "cache_tamper": 40 * SCALE})


class TestFuzzVerifierLimits:
    """The verifier's limits are the machine's (its largest feed, its travel) and the
    cut's physics (a plunge no faster than the cutting feed), never the program's own
    values: random plunge feeds (sculpturing) and depths of cut (turning)."""

    BASE = ["design.rows=3", "design.cols=3"]

    def test_plunge_feeds(self, tmp_path):
        from render_inspect.pipeline import run_toolpath

        rng = _rng("plunge_feeds")
        cutting = load_scene("sculpt_quad_mla", self.BASE).process.feed_mm_per_min
        for i in range(CASES["plunge_feeds"]):
            f = float(f"{10 ** rng.uniform(np.log10(cutting) + 0.01, 5):.6g}")  # schema: <= 1e5
            scene = load_scene("sculpt_quad_mla", self.BASE + [f"process.plunge_feed_mm_per_min={f}"])
            out = tmp_path / f"o{i}"
            with pytest.raises(InputError) as err:
                run_toolpath(scene, out, fmt="nc")
            msg = str(err.value)
            if f > 3000:
                assert "over the 3000 mm/min machine.preset" in msg, (f, msg)
            else:
                assert f"over the {cutting:g} mm/min of the cutting speed" in msg, (f, msg)
            assert "\n" not in msg and not out.exists()

    def test_depths_of_cut_past_the_travel(self, tmp_path):
        from render_inspect.pipeline import run_toolpath

        rng = _rng("depths")
        for i in range(CASES["depths"]):
            d = float(f"{10 ** rng.uniform(np.log10(150), 9):.6g}")  # schema: <= 1e9
            scene = load_scene("sts_sinusoidal_grid", ["process.workpiece_radius=0.05",
                                                       f"process.depth_of_cut={d}"])
            out = tmp_path / f"o{i}"
            with pytest.raises(InputError, match=r"outside the travel \[-150, 150\] mm of "
                                                 r"machine.preset 'sts_lathe'"):
                run_toolpath(scene, out, fmt="nc")
            assert not out.exists()


# ------------------------------------------------------------------ R8: the fit's cache
class TestFuzzFitCache:
    """A resumed fit reads its cache folder as untrusted: every random alteration of an
    entry (scaled, reshaped, truncated, inflated, another context, foreign members,
    garbage) is refused and recomputed; an untouched entry comes back bit for bit."""

    SHAPE = (24, 24)

    def _write(self, path, height, meta_text, digest, extra=None):
        members = {"height": height, "meta": np.array(meta_text), "digest": np.array(digest)}
        members.update(extra or {})
        buf = io.BytesIO()
        np.savez_compressed(buf, **members)
        path.write_bytes(buf.getvalue())

    def test_tampered_entries_are_recomputed(self, tmp_path):
        from render_inspect.fit._cache import EvaluationCache

        rng = _rng("cache_tamper")
        ctx = {"scene": "a" * 64, "measured": "b" * 64}
        cache = EvaluationCache(tmp_path, context=ctx, shape=self.SHAPE)
        kinds = ["scale", "reshape", "truncate", "inflate", "context", "member", "garbage",
                 "dtype", "none"]
        made = {}
        for i in range(CASES["cache_tamper"]):
            key = f"{i:064x}"
            h = rng.normal(size=self.SHAPE)
            made[key] = (cache.put(key, h, {"i": i}), _pick(rng, kinds))
        for key, (h, kind) in made.items():
            p = cache.folder / f"{key}.npz"
            with np.load(p) as z:
                raw, meta, digest = np.array(z["height"]), str(z["meta"]), str(z["digest"])
            if kind == "scale":
                self._write(p, raw * np.float32(3), meta, digest)
            elif kind == "reshape":
                self._write(p, raw.reshape(self.SHAPE[0] // 2, -1), meta, digest)
            elif kind == "truncate":
                p.write_bytes(p.read_bytes()[: int(rng.integers(1, p.stat().st_size))])
            elif kind == "inflate":
                self._write(p, np.zeros((4096, 4096), np.float32), meta, digest)
            elif kind == "context":
                from render_inspect.fit._cache import content_hash
                self._write(p, raw, meta, content_hash(key, raw, meta, {"scene": "c" * 64}))
            elif kind == "member":
                self._write(p, raw, meta, digest, {"extra": np.zeros(3)})
            elif kind == "garbage":
                p.write_bytes(rng.bytes(int(rng.integers(0, 5000))))
            elif kind == "dtype":
                self._write(p, raw.astype(np.float64), meta, digest)
        assert {kind for _, kind in made.values()} == set(kinds)  # every alteration drawn
        again = EvaluationCache(tmp_path, context=ctx, shape=self.SHAPE)
        for key, (h, kind) in made.items():
            got = again.get(key)
            if kind == "none":
                assert got is not None and np.array_equal(got[0], h), key
            else:
                assert got is None, (kind, key)
        refused = {k for k, _ in again.rejected}
        assert refused == {k for k, (_, kind) in made.items() if kind != "none"}
