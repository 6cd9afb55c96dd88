"""Inputs that are not what their name says get the message that says what they are: a
scene with a UTF-8 byte-order mark is read as the scene; a named pipe (FIFO) or a device
(``/dev/zero``) given as a measured file is refused as such (not "not found", not an
unknown format) without being read; the interferometer's memory message names its
automatic sub-sampling instead of printing ``None^2``."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from render_inspect import cli
from render_inspect.io import not_a_file
from render_inspect.scene import load_scene

SCENES = Path(__file__).resolve().parents[1] / "scenes"


def test_a_scene_with_a_byte_order_mark_is_the_scene(tmp_path):
    raw = (SCENES / "sts_sinusoidal_grid.toml").read_bytes()
    (tmp_path / "bom.toml").write_bytes(b"\xef\xbb\xbf" + raw)
    (tmp_path / "plain.toml").write_bytes(raw)
    assert load_scene(str(tmp_path / "bom.toml")).to_dict() == \
        load_scene(str(tmp_path / "plain.toml")).to_dict()


@pytest.mark.parametrize("kind", ["fifo", "fifo.npy", "zero.exr", "/dev/zero", "folder.x3p"])
def test_a_pipe_a_device_or_a_folder_is_refused_as_such(tmp_path, capsys, kind):
    if kind.startswith("fifo"):
        path = tmp_path / kind
        os.mkfifo(path)  # reading it would block: the refusal must not open it
        want = "named pipe"
    elif kind == "zero.exr":
        path = tmp_path / kind
        os.symlink("/dev/zero", path)
        want = "device"
    elif kind == "folder.x3p":
        path = tmp_path / kind
        path.mkdir()
        want = "folder"
    else:
        path, want = Path(kind), "device"
    rc = cli.main(["analyze", str(path), "--out", str(tmp_path / "o"), "-q"])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 1 and len(err) == 1 and want in err[0] and "not found" not in err[0], err
    assert not (tmp_path / "o").exists()


def test_not_a_file_says_what_the_path_is(tmp_path):
    (tmp_path / "f").write_text("x")
    os.mkfifo(tmp_path / "p")
    assert not_a_file(tmp_path / "f") is None
    assert not_a_file(tmp_path / "missing") == "not found"
    assert "named pipe" in not_a_file(tmp_path / "p")
    assert "device" in not_a_file("/dev/null")
    assert "folder" in not_a_file(tmp_path)


def test_the_interferometer_memory_message_names_automatic_sub_sampling():
    from render_inspect.core.errors import MemoryBudgetError
    from render_inspect.pipeline import check_render_limits

    scene = load_scene("sts_sinusoidal_grid", ["simulation.max_memory_gb=0.01"])
    assert scene.render.interferometer.subsamples is None
    with pytest.raises(MemoryBudgetError) as info:
        check_render_limits(scene, kind="interferometer")
    msg = str(info.value)
    assert "None" not in msg and "sub-sampled by the design's slopes" in msg, msg
