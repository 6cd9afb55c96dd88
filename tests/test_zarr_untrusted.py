"""Zarr stores are read as untrusted input: nothing outside a store is read through a
symbolic link inside it (an array folder, a group, a chunk or a metadata file that is a
link), and metadata files are refused by their size before they are parsed (a 300 MB
``zarr.json`` once peaked at 1.34 GiB being parsed)."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from render_inspect.errors import InputError
from render_inspect.io import ZarrHeightMap, check_store_tree, read_measured
from render_inspect.io._heightmap import grid_attrs
from render_inspect.io._zarr import MAX_ROOT_METADATA_BYTES, write_heightmap_zarr

REPO = Path(__file__).resolve().parents[1]


def _store(d: Path, name="s.zarr", value=0.0) -> Path:
    z = np.full((24, 24), value) + np.random.default_rng(0).normal(0, 1e-5, (24, 24))
    return write_heightmap_zarr(d / name, z, z, chunk=16, levels=1,
                                attrs=grid_attrs(0.001, (0.0, 0.0), {}, {}))


def test_a_plain_store_is_read(tmp_path):
    s = _store(tmp_path)
    check_store_tree(s)
    assert ZarrHeightMap(s).read("machined").shape == (24, 24)


@pytest.mark.parametrize("what", ["machined", "levels", "levels/1/design",
                                  "machined/zarr.json", "machined/c/0/0"])
def test_a_symbolic_link_inside_a_store_is_refused(tmp_path, what):
    """A link to another store's array: zarr would read it as this store's."""
    s = _store(tmp_path)
    other = _store(tmp_path, "other.zarr", value=1.0)
    target = s / what
    if target.is_dir():
        shutil.rmtree(target)
    else:
        target.unlink()
    os.symlink(other / what, target)
    with pytest.raises(InputError, match=r"is a symbolic link.*refused") as info:
        ZarrHeightMap(s)
    assert repr(what) in str(info.value) and "\n" not in str(info.value)
    with pytest.raises(InputError, match="symbolic link"):
        read_measured(s)


def test_a_pipe_inside_a_store_is_refused(tmp_path):
    s = _store(tmp_path)
    (s / "machined" / "c" / "0" / "1").unlink()
    os.mkfifo(s / "machined" / "c" / "0" / "1")
    with pytest.raises(InputError, match="not a regular file"):
        ZarrHeightMap(s)


@pytest.mark.parametrize("where", ["zarr.json", "machined/zarr.json"])
def test_a_huge_metadata_file_is_refused_by_its_size(tmp_path, where):
    s = _store(tmp_path)
    f = s / where
    size = MAX_ROOT_METADATA_BYTES + 1 if where == "zarr.json" else 2 ** 20 + 1
    with open(f, "r+b") as fh:  # a sparse file: the size without the bytes
        fh.truncate(size)
    with pytest.raises(InputError, match=rf"{where!r} is {size} bytes; metadata files are at most"):
        ZarrHeightMap(s)


@pytest.mark.slow
def test_a_300_mb_zarr_json_is_refused_without_reading_it(tmp_path):
    """The reproduction: a root ``zarr.json`` of 300 MB (valid JSON, a long attribute):
    refused by ``analyze`` in one line, the process's peak memory far below the file."""
    s = _store(tmp_path)
    f = s / "zarr.json"
    head, tail = f.read_text().split('"attributes": {', 1)
    with open(f, "w") as fh:  # written in pieces: this process stays small
        fh.write(head + '"attributes": {"pad": "')
        for _ in range(300):
            fh.write("x" * 2 ** 20)
        fh.write('", ' + tail)
    assert f.stat().st_size > 300 * 2 ** 20
    # the peak of the command's own address space (VmHWM starts anew at exec)
    code = ("import re, sys\nfrom render_inspect import cli\nrc = cli.main(sys.argv[1:])\n"
            "hwm = re.search(r'VmHWM:\\s+(\\d+)', open('/proc/self/status').read()).group(1)\n"
            "print(hwm, file=sys.stderr)\nsys.exit(rc)\n")
    env = dict(os.environ, PYTHONPATH=str(REPO))
    r = subprocess.run([sys.executable, "-c", code, "analyze", str(s), "--out",
                        str(tmp_path / "o"), "-q"], capture_output=True, text=True, env=env,
                       timeout=300)
    err = r.stderr.strip().splitlines()
    assert r.returncode == 1 and "metadata files are at most" in err[0], r.stderr[-500:]
    peak_kib = int(err[-1])
    assert peak_kib < 300 * 1024, peak_kib  # the file was not read
    assert not (tmp_path / "o").exists()
