"""Reading a machine program streams it: the peak memory of :func:`read_program` grows with
the points it returns, not with the file's text.  Measured in a fresh process (peak
resident set above what the process held after a warm-up read, and the numpy/Python
allocations traced) at two program sizes and at two text sizes of one program."""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap

import numpy as np
import pytest

_PROBE = textwrap.dedent('''
    import json, sys, tracemalloc
    import numpy as np
    from render_inspect.io import read_program

    def status(key):
        for line in open("/proc/self/status"):
            if line.startswith(key):
                return int(line.split()[1]) * 1024

    path, warm = sys.argv[1], sys.argv[2]
    read_program(warm, part_radius=50.0, spindle_rpm=100.0)  # libraries and kernels loaded
    base = status("VmRSS")
    tracemalloc.start()
    imp = read_program(path, part_radius=50.0, spindle_rpm=100.0)
    _, traced = tracemalloc.get_traced_memory()
    p = imp.program
    # what the reader must return: the path (theta, rho, z, t) and each point's file line
    # and motion
    held = sum(np.asarray(getattr(p, k)).nbytes for k in ("theta", "rho", "z", "t"))
    held += imp.file_line.nbytes + imp.motion.nbytes
    print(json.dumps({"rss": status("VmHWM") - base, "traced": traced, "held": held,
                      "points": int(p.points)}))
''')


def _point_list(path, n: int, pad: int = 0):
    """A spiral point list of ``n`` blocks (0.5 deg a point, from X 50 mm to the centre);
    ``pad`` > 0 adds a comment of that many characters to every block (more text, the same
    points)."""
    tail = f" ({'x' * pad})" if pad else ""
    with open(path, "w") as fh:
        for a in range(0, n, 200_000):
            k = np.arange(a, min(a + 200_000, n))
            c = (k * 0.5) % 360.0
            x = 50.0 - 50.0 * k / n
            z = x * x / 200.0
            fh.write("".join(f"C{ci:.6f} X{xi:.6f} Z{zi:.6f}{tail}\n"
                             for ci, xi, zi in zip(c, x, z)))
    return path


def _measure(path, warm, cwd) -> dict:
    p = subprocess.run([sys.executable, "-c", _PROBE, str(path), str(warm)], capture_output=True,
                       text=True, cwd=cwd, timeout=900)
    assert p.returncode == 0, p.stderr[-800:]
    r = json.loads(p.stdout.strip().splitlines()[-1])
    r["file"] = path.stat().st_size
    return r


@pytest.mark.slow
def test_program_reading_memory_follows_the_points_not_the_text(tmp_path):
    warm = _point_list(tmp_path / "warm.nc", 2000)
    n = 1_000_000
    small = _measure(_point_list(tmp_path / "a.nc", n), warm, tmp_path)
    (tmp_path / "a.nc").unlink()
    large = _measure(_point_list(tmp_path / "b.nc", 2 * n), warm, tmp_path)
    (tmp_path / "b.nc").unlink()
    wordy = _measure(_point_list(tmp_path / "c.nc", n, pad=100), warm, tmp_path)
    (tmp_path / "c.nc").unlink()
    assert small["points"] == wordy["points"] == n and large["points"] == 2 * n
    print("program reading memory:", json.dumps({"1M": small, "2M": large, "1M_wordy": wordy}))
    # four times the text, the same points: the same allocations (traced), and the
    # resident set does not follow the text: a reader holding it would grow by at least
    # the whole extra file (103 MB); the allocator's own pages vary by some tens of MB
    # between runs (measured 0 and 33 MB here), well under half of it
    extra_text = wordy["file"] - small["file"]
    assert extra_text > 3 * small["file"]
    assert abs(wordy["traced"] - small["traced"]) < 0.01 * small["traced"], (small, wordy)
    assert wordy["rss"] - small["rss"] < 0.5 * extra_text, (small, wordy)
    # twice the points: the peak grows by a few times what the reader returns (41 bytes a
    # point; measured 102 bytes a block traced, 138-160 resident: the scanned blocks and the
    # whole-program steps, C unwrapped, each move's time)
    grow_held = large["held"] - small["held"]
    for key in ("traced", "rss"):
        grow = large[key] - small[key]
        assert 0 < grow < 6 * grow_held, (key, small, large)
