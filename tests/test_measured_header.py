"""What ``read_surface`` (and so ``analyze``, ``compare --measured``) says it read: the
instrument a measured file's header names, the units the file itself declares, and the
one-screen summary of ``analyze`` (format, reader, instrument, field, pixel, invalid
points).  Files written here with known headers, and the real files of
../shared/realdata checked against what its SOURCES.md says of them."""

from __future__ import annotations

import json
import struct

import numpy as np
import pytest
from conftest import real_file
from numpy.testing import assert_allclose

from render_inspect.cli import main as cli_main
from render_inspect.io import read_surface, write_x3p
from render_inspect.report import analysis_summary

NOT_STATED = "not stated in the file"


# -- files written here ---------------------------------------------------------------------

def _opd_bytes(counts: np.ndarray, *, wavelength_nm: float, mult: int, pixel_mm: float,
               texts: dict[str, str]) -> bytes:
    """A Wyko Vision ``.opd`` file: a block directory (name, type, length, attribute),
    then the blocks' data in the same order; 16-bit heights stored column by column."""
    ny, nx = counts.shape
    raw = struct.pack("<HHH", nx, ny, 2) + np.ascontiguousarray(counts[::-1].T,
                                                                dtype="<i2").tobytes()
    blocks = [("RAW_DATA", 3, raw), ("Wavelength", 7, struct.pack("<f", wavelength_nm)),
              ("Mult", 6, struct.pack("<H", mult)), ("Pixel_size", 7, struct.pack("<f", pixel_mm))]
    blocks += [(k, 5, v.encode("latin-1") + b"\0" * (30 - len(v))) for k, v in texts.items()]
    entries = [("Directory", 1, 24 * (len(blocks) + 1))] + [(n, t, len(d)) for n, t, d in blocks]
    head = b"\x01\x00" + b"".join(n.encode().ljust(16, b"\0") + struct.pack("<hlH", t, n_bytes, 0)
                                  for n, t, n_bytes in entries)
    return head + b"".join(d for _, _, d in blocks)


def test_opd_header_names_the_instrument_and_heights_are_declared_in_nm(tmp_path):
    rng = np.random.default_rng(3)
    counts = rng.integers(-2000, 2000, size=(12, 16)).astype(np.int16)
    counts[2, 5] = 32767  # a point the instrument did not measure
    p = tmp_path / "m.opd"
    p.write_bytes(_opd_bytes(counts, wavelength_nm=80.0, mult=236, pixel_mm=0.0016,
                             texts={"MachineID": "NT9100", "SerialNum": "NT0000042",
                                    "ObjectiveLabel": "10 X", "FOVLabel": "0.5 X",
                                    "MeasMode": "VSI", "Date": "3/14/2021", "Time": "09:26:53"}))
    m = read_surface(p)
    # the heights: counts x Wavelength (nm) / Mult, in mm
    expect = counts * 80.0 / 236 * 1e-6
    expect[2, 5] = np.nan
    assert_allclose(m.z, expect, rtol=1e-6, equal_nan=True)
    assert m.meta["units_in_file"] == {"lateral": "mm", "vertical": "nm"}
    assert m.meta["library_units"] == {"lateral": "mm", "vertical": "mm"}
    f = m.meta["instrument_fields"]
    assert f == {"model": "NT9100", "serial": "NT0000042", "objective": "10 X, field lens 0.5 X",
                 "technique": "VSI", "acquired": "2021-03-14 09:26:53"}
    assert m.meta["instrument"] == "NT9100, serial NT0000042, objective 10 X, field lens 0.5 X, VSI"
    assert m.meta["date"] == "2021-03-14 09:26:53"
    assert m.meta["format_name"] == "Wyko / Bruker Vision .opd"


def test_opd_without_instrument_blocks_says_not_stated(tmp_path):
    p = tmp_path / "m.opd"
    p.write_bytes(_opd_bytes(np.arange(12, dtype=np.int16).reshape(3, 4), wavelength_nm=600.0,
                             mult=1, pixel_mm=0.001, texts={}))
    m = read_surface(p)
    assert m.meta["instrument"] == NOT_STATED and m.meta["instrument_fields"] == {}


def test_x3p_instrument_record_and_numpy_sidecar(tmp_path):
    z = np.outer(np.linspace(0, 1e-4, 6), np.ones(5))
    m = read_surface(write_x3p(tmp_path / "m.x3p", z, pixel=(0.001, 0.002)))
    f = m.meta["instrument_fields"]
    assert f["manufacturer"] == f["model"] == "render_inspect" and "probing" in f
    assert m.meta["instrument"].startswith("render_inspect, probing system type Software")
    assert m.meta["units_in_file"] == {"lateral": "m", "vertical": "m"}
    np.save(tmp_path / "h.npy", z)
    (tmp_path / "h.json").write_text(json.dumps({"pixel_mm": 0.001, "units": "um"}))
    m = read_surface(tmp_path / "h.npy")
    assert m.meta["instrument"] == NOT_STATED
    assert m.meta["units_in_file"] == {"lateral": "mm", "vertical": "um"}
    assert m.meta["units_in_file_from"] == "h.json: units"


def test_metropro_serial_from_the_16_bit_field_when_the_full_one_is_absent():
    from render_inspect.io._instrument import metropro_header

    head = metropro_header({"raw_metadata": {"sys_type": 22, "sys_serial": -6129, "phase_res": 2,
                                             "obj_name": "50X Mirau  ", "time_stamp": 0}})
    f = head["fields"]
    assert f["serial"] == "59407"  # 65536 - 6129: the field is unsigned
    assert f["phase_resolution"] == "phase_res 2: 131072 counts per fringe"
    assert f["objective"] == "50X Mirau" and f["acquired"] is None


def test_plu_hardware_code_names_the_model_only_from_format_2012(tmp_path):
    from render_inspect.io._instrument import plu_header

    def head(version, hardware):
        b = bytearray(496)
        b[:24] = b"Mon Apr 19 11:40:13 2021"
        struct.pack_into("<I", b, 440, 0)
        b[490], b[491] = version, hardware
        (tmp_path / "h.plu").write_bytes(bytes(b))
        return plu_header(tmp_path / "h.plu")["fields"]

    assert head(251, 9)["model"] == "S neox (hardware code 9)"
    assert head(251, 9)["acquired"] == "Mon Apr 19 11:40:13 2021"
    old = head(250, 9)
    assert "model" not in old and old["system"] == "hardware code 9 (format version 250)"


def test_summary_names_file_instrument_field_pixel_and_invalid_points(tmp_path, capsys):
    counts = (np.arange(20 * 30).reshape(20, 30) % 97).astype(np.int16)
    counts[0, :3] = 32767
    p = tmp_path / "m.opd"
    p.write_bytes(_opd_bytes(counts, wavelength_nm=600.0, mult=10, pixel_mm=0.002,
                             texts={"MachineID": "NT9100", "SerialNum": "S1", "Date": "1/2/2020"}))
    out = tmp_path / "a"
    assert cli_main(["analyze", str(p), "--out", str(out)]) == 0
    text = capsys.readouterr().out
    m = json.loads((out / "metrics.json").read_text())
    inp = m["input"]
    assert inp["instrument"] == "NT9100, serial S1" and inp["date"] == "2020-01-02"
    assert inp["units_in_file"] == {"lateral": "mm", "vertical": "nm"}
    rows = dict(analysis_summary(m))
    assert rows["file"] == ("Wyko / Bruker Vision .opd, read by " + inp["reader"]
                            + "; in the file: lateral mm, heights nm")
    assert rows["instrument"] == "NT9100, serial S1; acquired 2020-01-02"
    assert rows["map"] == ("30 x 20 points, pixel 2 x 2 um, field 0.06 x 0.04 mm (x by y); "
                           "3 invalid (0.5 %)")
    for part in ("NT9100, serial S1", "0.06 x 0.04 mm", "3 invalid"):
        assert part in " ".join(text.split())


# -- real files: what SOURCES.md says of them -----------------------------------------------

#: file: (the instrument line starts with, fields that must be as given, date starts with)
REAL = {
    "zygo_metropro-1.dat": ("MetroPro system type 22, serial 59407, objective 20X Mirau",
                            {"phase_resolution": "phase_res 1: 32768 counts per fringe"},
                            "2011-07-23 16:49:36 UTC"),
    "more/prysm_zygo.dat": ("MetroPro system type 23, serial 652222", {}, "2015-04-24"),
    "wyko_opd-int16.opd": ("NT1100, serial NT1106279, objective 5 X", {"technique": "VSI"},
                           "2009-10-26 11:16:55"),
    "more/sf_test_2.opd": ("NT1100, serial NT1106279", {}, "2009-10-26 12:34:30"),
    "wyko_opd-1.opd": (NOT_STATED, {"technique": "PSI", "objective": "magnification 50.32x"},
                       "2015-07-07 16:19:48"),
    "sensofar_plu_neox.plu": ("Sensofar PLu neox (hardware code 6), objective Nikon CFI Plan "
                              "Interferential 10X", {}, "Fri Mar 10 16:35:59 2023"),
    "more/sf_test_1.plu": ("Sensofar DCM 3D rev. 2", {}, "Mon Apr 19 11:40:13 2021"),
    "more/st_al3d-1.al3d": ("Alicona Imaging, software MeasureSuite 5.3.6", {}, None),
    "more/st_frt-1.frt": ("FRT, product id 2, series number 1049, serial SN_1036", {},
                          "2023-03-10"),
    "more/st_frt-2.frt": ("FRT", {"title": "TexSimEx_Pin_New", "serial": "SN_1036"},
                          "2023-06-26"),
    "alicona_ski.x3p": ("Alicona Imaging GmbH OpenGPS Export, serial H271106000", {},
                        "2009-06-09"),
    "more/alicona_kautschuk.x3p": ("Alicona Imaging GmbH OpenGPS Export, serial H271106000", {},
                                   "2009-06-09"),
    "sensofar_bullet_land.x3p": ("Sensofar Sneox1, serial 350262016, probing system Nikon - EPI "
                                 "20X", {}, "2018-09-15"),
    "mountainsmap_x3p-2.x3p": ("DIGITAL SURF Mountains Map Technology Software, probing system "
                               "type Software", {"version": "6.2"}, "1970-01-01"),
    "digitalsurf_sur-2.sur": (NOT_STATED, {}, None),
    "more/sf_test_uncompressed.sur": (NOT_STATED, {}, None),
    "more/st_sur-3.sur": (NOT_STATED, {}, "2023-06-22 10:08:53"),
    "nanofocus_nms-1.nms": (NOT_STATED + " (Confocal Height Image)", {}, "2022-02-09"),
    "truemap_tmd-1.tmd": (NOT_STATED, {}, None),
}


@pytest.mark.parametrize("name", sorted(REAL))
def test_real_file_header_as_sources_md_describes_it(name):
    start, fields, date = REAL[name]
    m = read_surface(real_file(*name.split("/")))
    assert m.meta["instrument"].startswith(start)
    for k, v in fields.items():
        assert m.meta["instrument_fields"][k] == v
    if date is None:
        assert not m.meta.get("date")
    else:
        assert str(m.meta["date"]).startswith(date)
    assert m.meta["units_in_file_from"]


#: the units the files declare (SurfaceTopography's converted unit beside them)
UNITS = {"wyko_opd-1.opd": ("mm", "nm", "mm"), "more/sf_test_1.opd": ("mm", "nm", "mm"),
         "sensofar_plu_neox.plu": ("um", "um", "µm"), "zygo_metropro-1.dat": ("m", "m", "m"),
         "more/st_al3d-1.al3d": ("m", "m", "m"), "more/st_frt-2.frt": ("m", "m", "m"),
         "more/st_sur-3.sur": ("nm", "m", None), "nanofocus_nms-1.nms": ("nm", "um", None)}


@pytest.mark.parametrize("name", sorted(UNITS))
def test_real_file_units_are_the_files_own(name):
    lateral, vertical, library = UNITS[name]
    m = read_surface(real_file(*name.split("/")))
    assert m.meta["units_in_file"] == {"lateral": lateral, "vertical": vertical}
    assert (m.meta.get("library_units") or {}).get("vertical") == library
