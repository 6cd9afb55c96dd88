"""X3P export verified with a third-party reader (surfalize), and read_measured for every
format we can produce here (X3P, our EXR, .npy/.npz, and .sur written by surfalize)."""

from __future__ import annotations

import json

import numpy as np
import pytest
from numpy.testing import assert_allclose

from render_inspect.errors import InputError
from render_inspect.io import read_measured, read_x3p, write_heightmap_exr, write_x3p
from render_inspect.machining import HeightMap


def _map(ny=12, nx=17, seed=0):
    rng = np.random.default_rng(seed)
    x = np.arange(nx) * 0.002
    z = 1e-3 * np.sin(x / 0.01)[None, :] + rng.normal(0, 1e-5, (ny, nx))
    z[0, 0] = z[0, 0] + 5e-4  # an asymmetric marker: catches flipped rows or columns
    return z


def test_x3p_roundtrip_and_third_party_reader(tmp_path):
    import surfalize

    z = _map()
    z[3, 4] = np.nan
    p = write_x3p(tmp_path / "m.x3p", z, pixel=0.002, origin=(1.25, -0.5), comment="unit test")
    zz, pixel, origin, meta = read_x3p(p)
    assert_allclose(zz, z, atol=1e-15, equal_nan=True)
    assert pixel == pytest.approx(0.002) and origin == pytest.approx((1.25, -0.5))
    assert meta["comment"] == "unit test" and meta["instrument"].startswith("render_inspect")
    assert meta["instrument_fields"]["manufacturer"] == "render_inspect"
    # third-party reader: surfalize (its own X3P parser) gives micrometres
    s = surfalize.Surface.load(str(p))
    assert s.step_x == pytest.approx(2.0) and s.step_y == pytest.approx(2.0)
    assert_allclose(np.asarray(s.data) * 1e-3, z, atol=1e-15, equal_nan=True)
    # same inputs -> same bytes
    p2 = write_x3p(tmp_path / "m2.x3p", z, pixel=0.002, origin=(1.25, -0.5), comment="unit test")
    assert p.read_bytes() == p2.read_bytes()


def test_x3p_written_by_surfalize_is_read(tmp_path):
    import surfalize

    z = _map()
    surfalize.Surface(z * 1e3, 3.0, 3.0).save(str(tmp_path / "s.x3p"))
    zz, pixel, origin, meta = read_measured(tmp_path / "s.x3p")
    assert_allclose(zz, z, atol=1e-15)
    assert pixel == pytest.approx(0.003) and origin == (0.0, 0.0)


def test_read_measured_sur_written_by_surfalize(tmp_path):
    import surfalize

    z = _map()
    surfalize.Surface(z * 1e3, 2.5, 2.5).save(str(tmp_path / "m.sur"))
    zz, pixel, origin, meta = read_measured(tmp_path / "m.sur")
    assert_allclose(zz, z, atol=1e-9)  # .sur stores 32-bit integers: ~pm steps
    assert pixel == pytest.approx(0.0025) and meta["format"] == "sur"
    with pytest.warns(UserWarning, match="different pixel size"):
        surfalize.Surface(z * 1e3, 2.5, 3.5).save(str(tmp_path / "r.sur"))
    with pytest.raises(InputError, match="pixel sizes differ"):
        read_measured(tmp_path / "r.sur")


def test_read_measured_exr_npy_npz(tmp_path):
    z = _map()
    hm = HeightMap(np.zeros_like(z), z, 0.002, (0.1, 0.2))
    write_heightmap_exr(tmp_path / "heightmap.exr", hm)
    zz, pixel, origin, meta = read_measured(tmp_path / "heightmap.exr")
    assert_allclose(zz, z.astype(np.float32), atol=0)
    assert pixel == 0.002 and origin == (0.1, 0.2) and meta["channel"] == "machined"
    np.save(tmp_path / "m.npy", z * 1e3)
    (tmp_path / "m.json").write_text(json.dumps({"pixel_mm": 0.004, "origin_mm": [1, 2],
                                                 "units": "um"}))
    zz, pixel, origin, _ = read_measured(tmp_path / "m.npy")
    assert_allclose(zz, z, rtol=1e-12) and pixel == 0.004 and origin == (1.0, 2.0)
    np.savez(tmp_path / "m.npz", z=z * 1e6, pixel_mm=0.001, units="nm")
    zz, pixel, origin, _ = read_measured(tmp_path / "m.npz")
    assert_allclose(zz, z, rtol=1e-12) and pixel == 0.001


def test_read_measured_bad_input(tmp_path):
    with pytest.raises(InputError, match="unknown measured file format '.xyz2'"):
        read_measured(tmp_path / "a.xyz2")
    (tmp_path / "a.datx").write_bytes(b"not HDF5")  # Zygo .datx: SurfaceTopography's reader
    with pytest.raises(InputError, match="DATXReader could not read it"):
        read_measured(tmp_path / "a.datx")
    with pytest.raises(InputError, match="not found"):
        read_measured(tmp_path / "missing.x3p")
    np.save(tmp_path / "b.npy", np.zeros((4, 4)))
    with pytest.raises(InputError, match="pixel size is unknown"):
        read_measured(tmp_path / "b.npy")
    np.save(tmp_path / "c.npy", np.full((4, 4), np.nan))
    with pytest.raises(InputError, match="no valid"):
        read_measured(tmp_path / "c.npy", pixel=0.01)
    np.save(tmp_path / "d.npy", np.zeros((4, 4)))
    with pytest.raises(InputError, match="units must be one of"):
        read_measured(tmp_path / "d.npy", pixel=0.01, units="inch")
    (tmp_path / "e.x3p").write_bytes(b"not a zip")
    with pytest.raises(InputError, match="X3P"):
        read_measured(tmp_path / "e.x3p")
    with pytest.raises(InputError, match="pixel"):
        write_x3p(tmp_path / "f.x3p", np.zeros((3, 3)), pixel=0)
    with pytest.raises(InputError, match="inf"):
        write_x3p(tmp_path / "g.x3p", np.full((3, 3), np.inf), pixel=0.1)


def _with_main(src, dst, edit):
    """A copy of the X3P ``src`` whose main.xml is ``edit(text)``, its MD5 record updated."""
    import hashlib
    import zipfile

    zin = zipfile.ZipFile(src)
    main = edit(zin.read("main.xml").decode()).encode()
    with zipfile.ZipFile(dst, "w", zipfile.ZIP_DEFLATED) as zout:
        for i in zin.infolist():
            data = zin.read(i)
            if i.filename == "main.xml":
                data = main
            elif i.filename == "md5checksum.hex":
                data = (hashlib.md5(main).hexdigest() + " *main.xml\n").encode()
            zout.writestr(i.filename, data)
    return dst


@pytest.mark.parametrize("size", [
    "<SizeX >200000</SizeX>", "<SizeX>200000<!-- a comment --></SizeX>",
    "<SizeX>\n  200000\n</SizeX >", "<SizeX><![CDATA[200000]]></SizeX>",
    "<SizeX>20</SizeX><SizeX>200000</SizeX>",
])
def test_x3p_sizes_are_read_as_xml_whatever_the_spelling(tmp_path, size):
    """Spacing, comments, CDATA or a repeated element in main.xml do not hide the grid it
    declares: the size check (parsed with defusedxml) refuses it before x3pio allocates."""
    from render_inspect.core.errors import MemoryBudgetError
    from render_inspect.io import check_x3p

    src = write_x3p(tmp_path / "a.x3p", _map(20, 20), pixel=0.001)
    f = _with_main(src, tmp_path / "b.x3p", lambda t: t.replace("<SizeX>20</SizeX>", size)
                   .replace("<SizeY>20</SizeY>", "<SizeY>200000</SizeY>"))
    with pytest.raises(MemoryBudgetError, match=r"declares a 200000 x 200000 x 1 grid"):
        check_x3p(f, what="measured file", budget=2 ** 30)
    with pytest.raises(MemoryBudgetError, match=r"200000 x 200000 x 1 grid"):
        read_measured(f)


@pytest.mark.parametrize("edit, match", [
    (lambda t: t.replace("<SizeX>20</SizeX>", "<SizeX>2e5</SizeX>"),
     r"main.xml SizeX must be a whole number >= 0, received '2e5'"),
    (lambda t: t.replace("<SizeX>20</SizeX>", "<SizeX>-3</SizeX>"), r"SizeX must be a whole number"),
    (lambda t: t.replace('<?xml version="1.0" encoding="UTF-8"?>',
                         '<?xml version="1.0"?><!DOCTYPE p [<!ENTITY n "200000">]>')
     .replace("<SizeX>20</SizeX>", "<SizeX>&n;</SizeX>"), r"XML features refused for safety"),
    (lambda t: t[: len(t) // 2], r"main.xml is not well-formed XML"),
])
def test_x3p_main_xml_that_is_not_plain_xml_is_refused(tmp_path, edit, match):
    src = write_x3p(tmp_path / "a.x3p", _map(20, 20), pixel=0.001)
    with pytest.raises(InputError, match=match):
        read_measured(_with_main(src, tmp_path / "b.x3p", edit))
