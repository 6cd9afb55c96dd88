"""Every shipped scene's ``compare`` report: its first figure is the difference of the
two variants (non-zero where they differ), no table says "-" for a value a figure states,
and the page renders in headless Chromium.  Small windows keep it quick."""

from __future__ import annotations

import base64
import html as html_lib
import json
import re
import subprocess

import numpy as np
import pytest

from render_inspect.cli import main as cli_main
from render_inspect.scene import shipped_scenes

#: a small window of each scene where its two variants differ, and a grid fine enough to
#: resolve the tool marks there
SMALL = {
    "sts_sinusoidal_grid": ["simulation.region=[-0.15,-0.15,0.15,0.15]", "simulation.pixel=0.002"],
    "sts_fig16_overcut": ["simulation.region=[-0.15,-0.15,0.15,0.15]", "simulation.pixel=0.002"],
    "sts_mla_2x2": ["simulation.region=[0.55,0.55,0.85,0.85]", "simulation.pixel=0.002"],
    "compound_sinusoid": ["simulation.region=[1.0,1.0,1.3,1.3]", "simulation.pixel=0.004"],
    "hts_toric_msa": ["simulation.region=[1.2,1.2,1.8,1.8]", "simulation.pixel=0.005"],
    "sculpt_quad_mla": ["simulation.region=[-0.2,-0.2,0.2,0.2]", "simulation.pixel=0.0025"],
    "rcse_circular_array": ["simulation.region=[3.3,-0.15,3.6,0.15]", "simulation.pixel=0.002"],
}
RENDER = ["render.interferometer.pixel=0.003", "render.diffuse.resolution=64",
          "render.diffuse.spp=4"]

pytestmark = [pytest.mark.mitsuba, pytest.mark.slow]

#: each scene's comparison, run once per process (:func:`_compare`); the three tests of a
#: scene run on one worker, so it is run once per run
_CACHE: dict = {}
NAMES = [pytest.param(n, marks=pytest.mark.xdist_group(f"compare_reports.{n}"))
         for n in sorted(SMALL)]


def test_every_shipped_scene_is_covered():
    assert sorted(SMALL) == sorted(shipped_scenes())


def _compare(name, tmp_path_factory):
    if name not in _CACHE:
        out = tmp_path_factory.mktemp(name) / "out"
        args = ["compare", name, "--out", str(out), "-q"]
        for o in SMALL[name] + RENDER:
            args += ["--set", o]
        assert cli_main(args) == 0
        _CACHE[name] = (out, json.loads((out / "metrics.json").read_text()))
    return _CACHE[name]


def _cells(page: str) -> list[str]:
    return [html_lib.unescape(re.sub(r"<[^>]+>", "", c)).strip()
            for c in re.findall(r"<td[^>]*>(.*?)</td>", page, re.S)]


def _table_rows(page: str, header: str) -> dict:
    """{first cell: other cells} of the table whose first header cell is ``header``."""
    for tab in re.findall(r"<table>(.*?)</table>", page, re.S):
        heads = re.findall(r"<th>(.*?)</th>", tab, re.S)
        if heads and html_lib.unescape(heads[0]) == header:
            rows = {}
            for tr in re.findall(r"<tr>(.*?)</tr>", tab, re.S):
                cells = [html_lib.unescape(re.sub(r"<[^>]+>", "", c)).strip()
                         for c in re.findall(r"<td[^>]*>(.*?)</td>", tr, re.S)]
                if cells:
                    rows[cells[0]] = cells[1:]
            return rows
    raise AssertionError(f"no table headed {header!r}")


def _coloured_fraction(png: bytes, x_from: float, x_to: float) -> float:
    """Fraction of clearly red or blue pixels (a diverging colour map away from zero) in a
    vertical band of a figure."""
    import io

    from PIL import Image

    img = np.asarray(Image.open(io.BytesIO(png)).convert("RGB"), dtype=float)
    w = img.shape[1]
    band = img[:, int(x_from * w):int(x_to * w)]
    return float((np.abs(band[..., 0] - band[..., 2]) > 60).mean())


@pytest.mark.parametrize("name", NAMES)
def test_first_figure_is_the_difference(name, tmp_path_factory):
    out, m = _compare(name, tmp_path_factory)
    page = (out / "report.html").read_text()
    first = re.search(r'<figure><img [^>]*src="data:image/png;base64,([^"]+)"', page)
    assert first is not None
    png = base64.b64decode(first.group(1))
    w = m["difference"]["window"]
    assert not m["pair"]["identical"], name
    assert png == (out / "difference.png").read_bytes()
    # the variants differ: non-zero in the truth and in what the instrument measures
    assert w["true"]["rms_nm"] > 0.01, (name, w)
    if w["measured"].get("status") == "failed":
        # a measurement that lost its fringe orders (these small cases image at 3 um
        # pixels, coarser than the marks' slopes allow) is a failure, said so, never a number
        assert w["measured"]["rms_nm"] is None and w["measured"]["fringe_order"]["reasons"]
        assert "FAILED" in page, name
    else:
        assert w["measured"]["rms_nm"] > 0.01, (name, w)
    # and the figure shows it: the two difference maps are coloured, not blank
    assert _coloured_fraction(png, 0.22, 0.62) > 0.01, name
    # the common window is the interferometer's field and the micro diffuse view's
    win = np.asarray(m["windows"]["common_mm"])
    np.testing.assert_allclose(m["windows"]["diffuse_micro_mm"], win, atol=1e-9)
    ifov = np.asarray(m["windows"]["interferometer_mm"])
    assert ifov[0] >= win[0] - 1e-9 and ifov[2] <= win[2] + 1e-9


@pytest.mark.parametrize("name", NAMES)
def test_tables_state_what_the_figures_state(name, tmp_path_factory):
    out, m = _compare(name, tmp_path_factory)
    page = (out / "report.html").read_text()
    cells = _cells(page)
    assert cells
    bad = [c for c in cells if c in ("-", "nan", "None", "", "none", "n/a", "not computed")]
    assert not bad, (name, bad)
    # the machine and the material of a turned part are parameters of the report
    if "machine" in m[m["variants"][0]["name"]]:
        assert "<th>[machine]</th>" in page and "<th>[material]</th>" in page, name
    ic = _table_rows(page, "[render.interferometer] as rendered")
    for key in ("wavelength_nm", "numerical_aperture", "pixel", "field_of_view"):
        assert re.search(r"\d", ic[key][0]), (key, ic[key])
    a = m["variants"][0]["name"]
    di = _table_rows(page, "[render.diffuse] as rendered")
    for col, view in enumerate(("micro", "macro")):
        ex = m[a]["diffuse"][view]["vertical_exaggeration"]
        assert di["vertical_exaggeration"][col] == f"{ex:g}x"
    # no false precision: at most 4 significant digits in the summary
    summ = _table_rows(page, "quantity")
    for row in summ.values():
        for c in row:
            digits = re.sub(r"[^0-9]", "", c.split(" ")[0].lstrip("-0."))
            assert len(digits) <= 4 or "," in c, c


def test_identical_variants_are_said_so(tmp_path, tiny_scene):
    p = tiny_scene
    out = tmp_path / "out"
    # burr variation without burrs: the two surfaces are the same
    assert cli_main(["compare", str(p), "--out", str(out), "-q",
                     "--vary", "artifacts.burrs.variation=0.3,0.6"]) == 0
    m = json.loads((out / "metrics.json").read_text())
    assert m["pair"]["identical"] is True
    assert not (out / "difference.png").exists() and (out / "windows.png").exists()
    page = (out / "report.html").read_text()
    assert "The two variants are identical" in page
    assert page.count("The two variants are identical") == 1


@pytest.mark.browser
@pytest.mark.parametrize("name", NAMES)
def test_report_renders_in_chromium(name, tmp_path_factory, tmp_path, chromium):
    from PIL import Image

    out, _ = _compare(name, tmp_path_factory)
    shot = tmp_path / "report.png"
    cmd = [chromium, "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic",
           "--no-first-run", "--disable-background-networking", "--disable-component-update",
           "--disable-sync", f"--user-data-dir={tmp_path / 'profile'}", f"--screenshot={shot}",
           "--window-size=1400,1200", (out / "report.html").resolve().as_uri()]
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0 and shot.is_file(), proc.stderr[-2000:]
    img = np.asarray(Image.open(shot).convert("RGB"), dtype=float)
    # the first screen holds the difference figure: red and blue difference maps
    assert (np.abs(img[..., 0] - img[..., 2]) > 60).mean() > 0.005
