"""The paraboloid design of the shipped example scene for the published diamond-turning
programs (docs/examples/turned/scene.toml), fitted to the programs' own Z.

    python tools/fit_program_design.py            # print the fit and the [design] table
    python tools/fit_program_design.py --write    # also write it into the scene

The programs (``../shared/realdata/turned/*.nc``, bare ``C X Z`` point lists) are read as
``simulate`` reads them (:func:`render_inspect.io.read_program`); the paraboloid
``z = offset - r^2 / (2 R)`` is the least-squares fit over every point of the three
(:func:`render_inspect.processes.fit_paraboloid`, Z taken as the design: the programs do not
say whether their Z is compensated for the 0.2 mm nose).
"""

from __future__ import annotations

import argparse
import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from render_inspect.io import read_program  # noqa: E402
from render_inspect.processes import fit_paraboloid  # noqa: E402

REALDATA = ROOT / ".." / "shared" / "realdata" / "turned"
SCENE = ROOT / "docs" / "examples" / "turned" / "scene.toml"
#: the part radius the programs are read against (their X reaches 1.031 mm)
PART_RADIUS = 1.1


def fit(folder: Path = REALDATA) -> dict:
    """The fit over the three programs in ``folder`` (see the module docstring)."""
    files = sorted(Path(folder).glob("*.nc"))
    if not files:
        raise SystemExit(f"no programs in {folder} (give --realdata FOLDER)")
    paths = [read_program(f, part_radius=PART_RADIUS).program for f in files]
    out = fit_paraboloid(paths)
    out["files"] = [f.name for f in files]
    return out


def design_table(f: dict) -> str:
    return (f'[design]                 # fitted by tools/fit_program_design.py: least squares over '
            f'{f["points"]} program points, residual rms {f["rms_nm"]:.1f} nm, max {f["max_nm"]:.1f} nm\n'
            f'type = "paraboloid"\n'
            f'radius_x = {f["radius_mm"]:.6f}\n'
            f'radius_y = {f["radius_mm"]:.6f}\n'
            f'offset = {f["offset_mm"]:.9f}\n')


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--write", action="store_true", help="write the [design] table into the scene")
    ap.add_argument("--realdata", type=Path, default=REALDATA,
                    help="the folder of the programs (default ../shared/realdata/turned)")
    args = ap.parse_args(argv)
    f = fit(args.realdata)
    table = design_table(f)
    print(table)
    if args.write:
        text = SCENE.read_text()
        text = re.sub(r"\[design\][^\[]*", table + "\n", text, count=1)
        SCENE.write_text(text)
        print(f"wrote {SCENE}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
