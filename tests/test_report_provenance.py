"""What a metrologist needs of a report before signing off a part: every warning the
command said, at the top of the page; where the inputs came from (each file with its
SHA-256, the scene as run, the seed, the software); what each number is of, with its
standard and filters; and a page that needs no network and prints."""

from __future__ import annotations

import hashlib
import html as html_lib
import json
import logging
import re
import shlex
from pathlib import Path

import pytest

from render_inspect.cli import main as cli_main
from render_inspect.core.invocation import command_line, running_command
from render_inspect.io import file_record
from render_inspect.pipeline._provenance import (keeps_warnings, run_inputs,
                                                 said_warnings)
from render_inspect.fit import scene_hash as scene_sha256
from render_inspect.report import HtmlReport, provenance_section, warnings_section
from render_inspect.scene import find_scene, load_scene, unit_warnings

from conftest import real_file

#: SHA-256 of the three bytes b"abc" (FIPS 180-2, appendix B.1)
ABC_SHA256 = "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad"

#: sts_mla_2x2 on a small window at a pixel coarser than half its 10 um feed marks (a
#: sampling the command warns of), rendered small
ALIASED = ["simulation.region=[0.55,0.55,0.85,0.85]", "simulation.pixel=0.006",
           "render.interferometer.pixel=0.003", "render.diffuse.resolution=64",
           "render.diffuse.spp=4"]


def _sections(page: str) -> list[str]:
    return [html_lib.unescape(t) for t in re.findall(r'<h2 id="s\d+">(.*?)</h2>', page)]


def _section_text(page: str, title: str) -> str:
    """The text of the section headed ``title``, tags removed."""
    parts = re.split(r'<h2 id="s\d+">', page)
    for p in parts[1:]:
        head, _, body = p.partition("</h2>")
        if html_lib.unescape(head) == title:
            return html_lib.unescape(re.sub(r"<[^>]+>", " ", body))
    raise AssertionError(f"no section {title!r}: {_sections(page)}")


def _sha(path: str | Path) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def test_input_files_are_recorded_with_their_sha256(tmp_path):
    f = tmp_path / "prog.nc"
    f.write_bytes(b"abc")
    rec = file_record(f, "machine program")
    assert rec == {"role": "machine program", "path": str(f.resolve()), "bytes": 3,
                   "sha256": ABC_SHA256}
    assert file_record(tmp_path, "measured file")["sha256"] is None      # a store folder
    g = tmp_path / "other.nc"
    g.write_bytes(b"abd")
    scene = {"name": "s", "process": {"program": str(f)}, "tool": {"edge_profile": str(g)}}
    inp = run_inputs(scene, scene_file=f, measured=g, seed=7)
    assert inp["seed"] == 7 and inp["scene"]["file"]["sha256"] == ABC_SHA256
    roles = {r["role"]: r["sha256"] for r in inp["files"]}
    assert roles == {"measured file": _sha(g), "machine program": ABC_SHA256,
                     "measured tool edge": _sha(g)}
    # the scene as run: its canonical JSON, whatever the order of its keys
    assert inp["scene"]["sha256_as_run"] == scene_sha256(json.loads(json.dumps(scene)[::1]))
    assert scene_sha256({"a": 1, "b": 2}) == scene_sha256({"b": 2, "a": 1})
    # two variants that read different programs: each named
    inp = run_inputs(scene, variants=[("a", scene), ("b", {"process": {"program": str(g)}})])
    assert sorted(r["role"] for r in inp["files"]) == [
        "machine program (a)", "machine program (b)", "measured tool edge (a)"]


def test_the_command_line_is_recorded_as_typed(tmp_path, monkeypatch):
    """``inputs.command``: the ``render-inspect`` words as typed (a relative path stays
    relative, with the directory it is relative to), None for a run called from Python;
    the provenance table says which."""
    scene = {"name": "s"}
    assert run_inputs(scene)["command"] is None and run_inputs(scene)["working_directory"] is None
    typed = ["compare", "scenes/my part.toml", "--set", "simulation.pixel=0.002", "--out", "o"]
    monkeypatch.chdir(tmp_path)
    with running_command(typed):
        inp = run_inputs(scene, seed=1)
        assert command_line() == ["render-inspect", *typed]
    assert inp["command"] == ["render-inspect", *typed]
    assert inp["working_directory"] == str(tmp_path)
    assert command_line() is None                            # undone when the command ends
    rep = HtmlReport("t")
    provenance_section(rep, {"seed": 1, "scene": {"name": "s"}, "inputs": inp})
    prov = re.sub(r"\s+", " ", _section_text(rep.render(), "Provenance"))
    assert ("render-inspect compare 'scenes/my part.toml' --set simulation.pixel=0.002 --out o"
            in prov) and str(tmp_path) in prov
    rep = HtmlReport("t")
    provenance_section(rep, {"seed": 1, "scene": {"name": "s"}, "inputs": run_inputs(scene)})
    prov = re.sub(r"\s+", " ", _section_text(rep.render(), "Provenance"))
    assert "not recorded: the run was made from Python (the render_inspect API)" in prov


def test_the_program_sets_the_command_line_for_its_command(tmp_path, monkeypatch):
    """``render-inspect`` (here its ``main``) runs each command with its own words set:
    what a command's run_inputs records."""
    import render_inspect.cli._main as cli_module

    seen = []

    def fake_analyze(args, overwrite):
        seen.append(run_inputs({"name": "s"})["command"])
        return {}

    monkeypatch.setitem(cli_module.COMMANDS, "analyze", fake_analyze)
    typed = ["analyze", "../data/trace.csv", "--units", "um", "--out", "a", "-q"]
    assert cli_main(typed) == 0
    assert seen == [["render-inspect", *typed]]
    assert command_line() is None


def test_warnings_said_during_a_run_are_kept():
    scene = load_scene("sts_mla_2x2", ALIASED[:2])
    said = unit_warnings(scene, sampling=True)
    assert said and "pixel" in said[0]                      # the marks alias at 6 um

    @keeps_warnings
    def run(sc, x):
        logging.getLogger("render_inspect").warning("warning: %s", f"the program read {x}")
        return said_warnings(["a line the run found in its numbers"])

    found = run(scene, "p.nc")
    assert found[0] == said[0]                              # before the run, as the CLI says it
    assert "the program read p.nc" in found and found[-1] == "a line the run found in its numbers"
    assert said_warnings() == []                             # nothing outside a run


def test_warnings_and_provenance_sections():
    rep = HtmlReport("t")
    warnings_section(rep, [])
    provenance_section(rep, {"software_version": "9.9", "seed": 3, "scene": {"name": "s"}})
    page = rep.render()
    assert _sections(page) == ["Warnings", "Provenance"]
    assert "None: the command said no warning" in _section_text(page, "Warnings")
    prov = _section_text(page, "Provenance")
    assert "render_inspect 9.9" in prov and "not recorded" in prov
    rep = HtmlReport("t")
    warnings_section(rep, ["the <edge> is used beyond its range"])
    page = rep.render()
    assert '<ul class="warn"><li>the &lt;edge&gt; is used beyond its range</li></ul>' in page
    assert "@media print" in page                            # the page prints without its nav


def _offline(page: str) -> None:
    """No network fetch: every src and href is a data URI or an anchor."""
    for attr in re.findall(r'(?:src|href)="([^"]*)"', page):
        assert attr.startswith(("data:", "#")), attr[:80]
    assert "<script" not in page and "@import" not in page


@pytest.mark.mitsuba
@pytest.mark.slow
def test_compare_report_says_its_warnings_units_and_inputs(tmp_path):
    out = tmp_path / "out"
    args = ["compare", "sts_mla_2x2", "--out", str(out), "-q"]
    for o in ALIASED:
        args += ["--set", o]
    assert cli_main(args) == 0
    page = (out / "report.html").read_text()
    m = json.loads((out / "metrics.json").read_text())
    said = unit_warnings(load_scene("sts_mla_2x2", ALIASED), sampling=True)
    # the warning the command printed, first on the page, before Figure 1
    assert _sections(page)[0] == "Warnings"
    assert said[0] in _section_text(page, "Warnings") and said[0] in m["warnings"]
    assert page.index(html_lib.escape(said[0], quote=False)) < page.index("Figure 1.")
    # each summary number says what it is of, its standard and filters
    summary = _section_text(page, "Summary")
    s_mm = m["filters"]["s_filter_mm"]
    assert summary.count("ISO 25178-2") >= 7 and "of the simulated cut" in summary
    assert "as measured by the virtual interferometer" in summary
    # (marks finer than two pixels get no S-filter: the waviness then names none)
    assert (f"S-filter {s_mm * 1000:.3g} um" if s_mm else "S-filter none, L-filter none") in summary
    assert "no S- or L-filter" in summary
    # provenance: the scene file and its hash, the scene as run, the seed, the software
    prov = _section_text(page, "Scene and provenance")
    scene_file = find_scene("sts_mla_2x2")
    assert str(scene_file) in prov and _sha(scene_file) in prov
    assert m["inputs"]["scene"]["sha256_as_run"] == scene_sha256(m["scene"]) in prov
    assert f"render_inspect {m['software_version']}" in prov
    for name, seed in m["difference"]["window"]["measured"]["noise"]["seeds"].items():
        assert f"camera noise seed, {name} {seed}" in re.sub(r"\s+", " ", prov)
    _offline(page)


@pytest.mark.slow
def test_profile_report_says_its_warnings_and_inputs(tmp_path):
    measured = real_file("turned", "1022-WLI-2D.csv")
    program = real_file("turned", "1022-spiralPath20230418T214917.nc")
    scene = Path(__file__).resolve().parents[1] / "docs" / "examples" / "turned" / "scene.toml"
    out = tmp_path / "out"
    typed = ["compare", str(scene), "--measured", str(measured), "--units", "um",
             "--program", str(program), "--out", str(out), "-q"]
    assert cli_main(typed) == 0
    page = (out / "report.html").read_text()
    m = json.loads((out / "metrics.json").read_text())
    assert _sections(page)[0] == "Warnings"
    warn = _section_text(page, "Warnings")
    # the 20x PSI loses fringe orders on these scallops: said at the top and in the caption
    assert m["virtual_measurement"]["status"] == "failed"
    assert "does not follow the cut it measured" in warn
    assert "The virtual measurement FAILED" in _section_text(page, "Profiles overlaid")
    params = _section_text(page, "Parameters side by side (ISO 21920-2)")
    assert "lambda_c 0.08 mm" in params and "as the real instrument reported it" in params
    prov = _section_text(page, "Provenance")
    # the command line as typed (the paths as given)
    assert m["inputs"]["command"] == ["render-inspect", *typed]
    assert " ".join(["render-inspect", *typed]) in re.sub(r"\s+", " ", prov)
    # the measured file: its format and the instrument it names (none: a text export)
    assert m["input"]["instrument"] == "not stated in the file"
    assert ("measured file: text profile export (.csv), instrument not stated in the file; "
            "951 of 1047 points measured") in re.sub(r"\s+", " ", _section_text(page, "Notes"))
    for f in (measured, program, scene):
        assert str(f.resolve()) in prov and _sha(f) in prov, f
    # the title names the program cut beside the scene
    assert m["run_name"] == f"turned_program_1021, program {program.name}"
    assert f"<title>{m['run_name']}: measured profile against the simulation</title>" in page
    _offline(page)


# ------------------------------------------------------------------------------- fit
def _fit_provenance(out: Path, typed: list[str], files: list[Path]) -> dict:
    """fit.json's ``inputs`` and fit.html's provenance: the command line as typed (paths
    as given) and where it ran, the scene file and each input file with its SHA-256."""
    rec = json.loads((out / "fit.json").read_text())
    inp = rec["inputs"]
    assert inp["command"] == ["render-inspect", *typed]
    assert inp["working_directory"] == str(Path.cwd())
    assert inp["scene"]["sha256_as_run"] == rec["scene_sha256"]
    page = (out / "fit.html").read_text()
    prov = re.sub(r"\s+", " ", _section_text(page, "Provenance"))
    assert shlex.join(["render-inspect", *typed]) in prov and str(Path.cwd()) in prov
    for f in files:
        assert str(f.resolve()) in prov and _sha(f) in prov, f
        assert {"path": str(f.resolve()), "sha256": _sha(f)}.items() <= next(
            r for r in [inp["scene"]["file"], *inp["files"]] if r["path"] == str(f.resolve())).items()
    _offline(page)
    return rec


@pytest.mark.mitsuba
def test_a_fit_of_a_map_records_its_command_line_with_predict(tmp_path, monkeypatch):
    """``fit MAP --predict``: fit.json's ``inputs``, fit.html's provenance and the
    prediction's ``predict/metrics.json`` hold the command line that made them."""
    from test_fit import _measured_file

    monkeypatch.chdir(tmp_path)
    px = 0.00087890625  # the marks' centre on the spindle axis of the scene
    meas = _measured_file(Path("height.exr"), origin=(0.3 - 64 * px, -0.05 - 64 * px))
    typed = ["fit", "height.exr", "--scene", "sts_sinusoidal_grid", "--free", "tool.nose_radius",
             "--window", "0.11", "--global", "0", "--profile-points", "0", "--max-evaluations", "2",
             "--predict", "process.feed_mm_per_min=0.4", "--out", "fit", "-q"]
    assert cli_main(typed) == 0
    rec = _fit_provenance(tmp_path / "fit", typed, [meas, find_scene("sts_sinusoidal_grid")])
    assert [r["role"] for r in rec["inputs"]["files"]] == ["measured file"]
    pred = json.loads((tmp_path / "fit" / "predict" / "metrics.json").read_text())
    assert pred["inputs"]["command"] == ["render-inspect", *typed]
    scene = json.loads((tmp_path / "fit" / "predict" / "scene.json").read_text())
    assert pred["inputs"]["scene"]["sha256_as_run"] == scene_sha256(scene)


@pytest.mark.slow
def test_a_fit_of_a_profile_records_its_command_line(tmp_path, monkeypatch):
    """``fit PROFILE``: fit.json's ``inputs`` and fit.html's provenance (a scene file of
    its own, the profile's file) hold the command line that made them."""
    from test_fit_profile import SCENE, _turned, _write_profile

    from render_inspect.pipeline._fit_profile import simulate_profile

    monkeypatch.chdir(tmp_path)
    s, z = simulate_profile(_turned(feed=3.6, nose=0.25), (0.1, 0.0), (0.5, 0.0), 0.00087, seed=7)
    _write_profile(Path("simulated.csv"), s, z)
    # the example scene with a planned spiral (its program line left out)
    Path("planned.toml").write_text("".join(
        line + "\n" for line in SCENE.read_text().splitlines() if not line.startswith("program =")))
    typed = ["fit", "simulated.csv", "--scene", "planned.toml", "--set",
             "render.interferometer.mode='csi'", "--set", "process.feed_mm_per_min=3.6",
             "--free", "tool.nose_radius", "--line", "0.1,0,0.5,0", "--at", "0.3,0",
             "--window", "0.15", "--global", "0", "--profile-points", "0",
             "--max-evaluations", "2", "--out", "pfit", "-q"]
    assert cli_main(typed) == 0
    rec = _fit_provenance(tmp_path / "pfit", typed, [Path("simulated.csv"), Path("planned.toml")])
    assert rec["kind"] == "profile"
