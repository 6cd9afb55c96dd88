"""Benchmark: reading machine programs (:func:`render_inspect.io.read_program`): written by
others, and the project's own.

Writes a bare C-X-Z point list of ``blocks`` blocks (the published programs' form: one
``C.. X.. Z..`` per line, 6 decimals, C wrapping every revolution), a lathe G-code
program of the same size (a header with a comment, then ``N.. G01 X.. Z.. F..`` blocks)
and the project's own C-X-Z program of the same spiral (:func:`render_inspect.io.write_nc`,
its writing timed: ``write_s``) into a temporary folder, and reads each: seconds (best of
``repeats``), M blocks/s, and the peak memory of the reading (tracemalloc, on a tenth of the blocks) against the bytes
the path it returns holds (theta, rho, z, t: 32 bytes a point).  ``read_cpu_s`` is the
CPU time of one read (on a shared machine the wall time is longer by the load).  The
scanner works on pieces of 1 MiB; the whole-program steps after it (unwrapping C, the
time of each move) hold a few arrays of the program's length.

``python benchmarks/bench_program.py [BLOCKS]`` prints and returns the figures (default
10 M blocks).
"""

from __future__ import annotations

import json
import os
import sys
import tempfile
import time
import tracemalloc
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
from _timing import best_of  # noqa: E402

#: lines formatted and written at a time
_CHUNK = 200_000


def write_point_list(path: Path, n: int) -> Path:
    """A spiral point list of ``n`` blocks: 0.5 deg steps, from X 50 mm to the centre."""
    with path.open("w") as fh:
        for a in range(0, n, _CHUNK):
            k = np.arange(a, min(a + _CHUNK, n))
            c = (k * 0.5) % 360.0
            x = 50.0 - 50.0 * k / n
            z = x * x / 200.0
            fh.write("\n".join(f"C{ci:.6f} X{xi:.6f} Z{zi:.6f}" for ci, xi, zi in zip(c, x, z)))
            fh.write("\n")
    return path


def write_gcode(path: Path, n: int) -> Path:
    """A lathe G-code program of ``n`` blocks: a header, X-Z moves at G94 feed."""
    with path.open("w") as fh:
        fh.write("%\nO1000 (BENCHMARK)\nN1 G71 G90 G18 G94\nN2 G97 S1000 M03\n")
        for a in range(0, n, _CHUNK):
            k = np.arange(a, min(a + _CHUNK, n))
            x = 50.0 - 50.0 * k / n
            z = x * x / 200.0
            fh.write("\n".join(f"N{ki + 3} G01 X{xi:.6f} Z{zi:.6f} F{10.0 + (ki % 3):.1f}"
                               for ki, xi, zi in zip(k, x, z)))
            fh.write("\n")
        fh.write("M30\n%\n")
    return path


def write_own(path: Path, n: int) -> Path:
    """The project's own C-X-Z program of ``n`` cutting blocks (``write_nc``: 6 decimals,
    inverse-time feeds), the same spiral with C cumulative."""
    from render_inspect.core.toolpath import ToolPath
    from render_inspect.io import write_nc

    k = np.arange(n, dtype=np.float64)
    rho = 50.0 - 50.0 * k / n
    return write_nc(path, ToolPath(np.radians(k * 0.5), rho, rho * rho / 200.0, k * 1e-3))


def _read(path, **kw):
    from render_inspect.io import read_program
    return read_program(path, part_radius=50.0, **kw)


def _peak(path, **kw) -> tuple[int, int]:
    tracemalloc.start()
    imp = _read(path, **kw)
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    p = imp.program
    held = sum(np.asarray(getattr(p, k)).nbytes for k in ("theta", "rho", "z", "t"))
    return peak, held


def main(blocks: int = 10_000_000, repeats: int = 1) -> dict:
    res = {"blocks": blocks, "load_average_at_start": os.getloadavg()}
    with tempfile.TemporaryDirectory(prefix="bench_program_") as tmp:
        tmp = Path(tmp)
        cases = {"point_list": (write_point_list, {"spindle_rpm": 100.0}),
                 "lathe_gcode": (write_gcode, {"points_per_rev": 1}),
                 "own_program": (write_own, {})}
        for name, (writer, kw) in cases.items():
            t0 = time.perf_counter()
            path = writer(tmp / f"{name}.nc", blocks)
            write_s = time.perf_counter() - t0
            size = path.stat().st_size
            best, imp = best_of(lambda: _read(path, **kw), repeats)
            c0 = time.process_time()
            _read(path, **kw)
            cpu = time.process_time() - c0
            small = writer(tmp / f"{name}_small.nc", max(blocks // 10, 1000))
            peak, held = _peak(small, **kw)
            n_small = max(blocks // 10, 1000)
            res[name] = {"file_MB": round(size / 1e6, 1), "read_s": round(best, 2),
                         "read_cpu_s": round(cpu, 2),
                         "Mblocks_per_s": round(blocks / best / 1e6, 2),
                         "points": int(imp.program.points),
                         "peak_MB_at_tenth": round(peak / 1e6, 1),
                         "path_MB_at_tenth": round(held / 1e6, 1),
                         "peak_bytes_per_block": round(peak / n_small, 1)}
            if writer is write_own:  # the project's own writer (the others are this script's)
                res[name]["write_s"] = round(write_s, 2)
            print(name, json.dumps(res[name]), flush=True)
            path.unlink()
    res["load_average_at_end"] = os.getloadavg()
    print(json.dumps(res, indent=2))
    return res


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 10_000_000)
