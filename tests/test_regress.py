"""The image regression suite: its statistics on images with a known answer, the shipped
cases against their references (what ``make test`` runs), and that it catches real
changes (a nose radius 1.5 x larger, another compensation mode, another wavelength) while
a rerun with another seed passes where the statistics say it should."""

from __future__ import annotations

import hashlib
import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from render_inspect.batch import (
    RegressionFailed,
    compare_deterministic,
    image_t_test,
    pass_statistics,
    sidak_threshold,
)
from render_inspect.core.errors import InputError
from render_inspect.pipeline import regression_cases_dir, run_regress

EXE = Path(sys.executable).parent / "render-inspect"
CASES = regression_cases_dir()


# ------------------------------------------------------------------ the statistics
def test_sidak_threshold():
    np.testing.assert_allclose(sidak_threshold(0.01, 1), 0.01)
    thr = sidak_threshold(1e-3, 10_000)
    np.testing.assert_allclose(1 - (1 - thr) ** 10_000, 1e-3, rtol=1e-9)


def test_deterministic_comparison_tolerances_and_nans():
    ref = np.array([[1.0, 2.0, np.nan], [4.0, 5.0, 6.0]])
    assert compare_deterministic(ref + 0.9e-3, ref, atol=1e-3)["passed"]
    r = compare_deterministic(ref + np.array([[0, 0, 0], [0, 2e-3, 0]]), ref, atol=1e-3)
    assert not r["passed"] and r["n_fail"] == 1 and np.isclose(r["max_abs_diff"], 2e-3)
    t = ref.copy()
    t[0, 0] = np.nan
    r = compare_deterministic(t, ref, atol=1.0)
    assert not r["passed"] and r["nan_mismatch"] == 1
    assert not compare_deterministic(ref[:1], ref, atol=1.0)["passed"]


@pytest.mark.parametrize("variance", ["pooled", "welch"])
def test_t_test_false_alarm_rate_and_power_on_known_images(variance):
    """Passes of a known image with Gaussian noise: under the null hypothesis the image
    fails with probability alpha (Sidak); a shift of 2.5 standard deviations of one pass
    in a 4 x 4 patch is found (t = 2.5 / sqrt(1/16 + 1/64) = 8.9 against a threshold of
    about 5.3 for alpha = 1e-3 over 3072 values) and nothing else is."""
    rng = np.random.default_rng(12)
    truth = rng.uniform(0.2, 0.8, size=(3, 32, 32))
    sigma = 0.05 * truth
    ref = pass_statistics(truth + sigma * rng.standard_normal((64, *truth.shape)))
    alpha, trials = 0.1, 200
    fails = 0
    for _ in range(trials):
        test = pass_statistics(truth + sigma * rng.standard_normal((16, *truth.shape)))
        fails += not image_t_test(test, ref, n_test=16, n_ref=64, alpha=alpha,
                                      variance=variance)["passed"]
    # binomial(200, 0.1): mean 20, sd 4.2; the bounds are 3 sd wide
    assert 7 <= fails <= 33, fails
    shifted = truth.copy()
    shifted[:, 10:14, 10:14] += 2.5 * sigma[:, 10:14, 10:14]
    for _ in range(10):
        test = pass_statistics(shifted + sigma * rng.standard_normal((16, *truth.shape)))
        r = image_t_test(test, ref, n_test=16, n_ref=64, alpha=1e-3, variance=variance)
        assert not r["passed"]
        assert r["reject"][:, 10:14, 10:14].sum() >= 40  # of 48
        assert r["reject"].sum() == r["reject"][:, 10:14, 10:14].sum()


def test_t_test_constant_pixels_and_dropouts():
    rng = np.random.default_rng(3)
    ref_p = np.broadcast_to(np.linspace(0, 1, 100).reshape(1, 1, 10, 10), (64, 1, 10, 10)).copy()
    test_p = ref_p[:16].copy()
    ref, test = pass_statistics(ref_p), pass_statistics(test_p)
    assert image_t_test(test, ref, n_test=16, n_ref=64)["passed"]  # constant, equal
    test_p[:, 0, 3, 3] += 1e-3
    assert not image_t_test(pass_statistics(test_p), ref, n_test=16, n_ref=64)["passed"]
    # a pixel that drops out (NaN) in 30 % of the passes on both sides: Fisher's test passes
    ref_p = rng.normal(1.0, 0.1, (64, 1, 10, 10))
    test_p = rng.normal(1.0, 0.1, (16, 1, 10, 10))
    ref_p[rng.random(64) < 0.3, 0, 5, 5] = np.nan
    test_p[:5, 0, 5, 5] = np.nan
    r = image_t_test(pass_statistics(test_p), pass_statistics(ref_p), n_test=16, n_ref=64)
    assert r["passed"] and r["n_tests"] == 100
    test_p[:, 0, 5, 5] = np.nan  # ... but not when it always drops out in the new render
    r = image_t_test(pass_statistics(test_p), pass_statistics(ref_p), n_test=16, n_ref=64)
    assert not r["passed"] and r["reject"][0, 5, 5]


# ------------------------------------------------------------------ the suite itself
def _tree_digest(folder: Path) -> str:
    h = hashlib.sha256()
    for p in sorted(folder.rglob("*")):
        if p.is_file():
            h.update(str(p.relative_to(folder)).encode())
            h.update(p.read_bytes())
    return h.hexdigest()


@pytest.mark.mitsuba
def test_every_case_matches_its_reference(tmp_path):
    """``render-inspect regress``: the whole suite, as `make test` runs it; references are
    only read."""
    refs = CASES / "references"
    before = _tree_digest(refs)
    res = subprocess.run([str(EXE), "regress", "--out", str(tmp_path / "regress")],
                         capture_output=True, text=True, timeout=900)
    summary_p = tmp_path / "regress" / "summary.json"
    detail = summary_p.read_text() if summary_p.exists() else ""
    assert res.returncode == 0, res.stderr[-4000:] + detail[-4000:]
    summary = json.loads(summary_p.read_text())
    cases = {p.stem for p in CASES.glob("*.toml")}
    assert set(summary["cases"]) == cases and summary["failed"] == 0
    kinds = {(r["image"], r["kind"]) for r in summary["results"]}
    assert ("diffuse_micro", "monte_carlo") in kinds and ("interferogram", "deterministic") in kinds
    assert ("interferogram", "monte_carlo") in kinds and ("residual", "deterministic") in kinds
    assert (tmp_path / "regress" / "summary.html").stat().st_size > 2000
    assert _tree_digest(refs) == before
    for case in cases:
        meta = json.loads((refs / case / "reference.json").read_text())
        assert meta["software_version"] and meta["mitsuba_variant"] and meta["case_hash"]
    size = sum(p.stat().st_size for p in refs.rglob("*") if p.is_file())
    assert size < 3_000_000, size  # references stay small


def _failing(summary):
    return {(r["case"], r["image"]) for r in summary["results"] if not r["passed"]}


def _run_expect(tmp_path, only, overrides, *, fails: bool):
    out = tmp_path / "o"
    if fails:
        with pytest.raises(RegressionFailed, match="differ from their references"):
            run_regress(only=only, out=out, overrides=overrides)
    else:
        run_regress(only=only, out=out, overrides=overrides)
    return json.loads((out / "summary.json").read_text()), out


@pytest.mark.mitsuba
def test_a_larger_nose_radius_is_caught(tmp_path):
    summary, out = _run_expect(tmp_path, "sts_grid_z", ["tool.nose_radius=0.771"], fails=True)
    # 1.5 x Rc: shallower scallops everywhere: every image of the case differs
    assert _failing(summary) == {("sts_grid_z", n) for n in
                                 ("residual", "interferogram", "measured_height", "diffuse_micro",
                                  "diffuse_macro")}
    rows = {r["image"]: r for r in summary["results"]}
    assert rows["residual"]["max_abs_diff"] > 5  # nm
    assert rows["diffuse_micro"]["min_p"] < 1e-20
    # what a user opens: image, reference, difference, p-values side by side
    pngs = {p.name for p in (out / "sts_grid_z").glob("*.png")}
    assert {"diffuse_micro_test.png", "diffuse_micro_reference.png", "diffuse_micro_difference.png",
            "diffuse_micro_pvalue.png", "residual_test.png", "residual_reference.png",
            "residual_difference.png"} <= pngs
    page = (out / "summary.html").read_text()
    assert "sts_grid_z/diffuse_micro_pvalue.png" in page and "FAIL" in page


@pytest.mark.mitsuba
def test_another_compensation_mode_is_caught(tmp_path):
    summary, _ = _run_expect(tmp_path, "sts_grid_z", ["process.compensation='normal'"], fails=True)
    # as docs/batch.md says: all five; the macro view (the whole part in the studio) sees
    # the compensation too, in the mirror reflections of the feed marks' slopes
    assert _failing(summary) == {("sts_grid_z", n) for n in
                                 ("residual", "interferogram", "measured_height", "diffuse_micro",
                                  "diffuse_macro")}
    rows = {r["image"]: r for r in summary["results"]}
    assert 10 < rows["residual"]["max_abs_diff"] < 25  # nm (16 nm measured)


@pytest.mark.mitsuba
def test_another_wavelength_changes_the_frames_but_not_the_surface(tmp_path):
    summary, _ = _run_expect(tmp_path, "sts_grid_z,sts_grid_psi_noise",
                             ["render.interferometer.wavelength_nm=650"], fails=True)
    # the fringes move; the surface and its diffuse images do not.  The height the
    # instrument reports may change a little: the objective's transfer function cuts off
    # at NA / lambda, so a longer wavelength passes less of the feed scallop.
    failing = _failing(summary)
    assert {("sts_grid_z", "interferogram"), ("sts_grid_psi_noise", "interferogram")} <= failing
    assert not {name for _, name in failing} & {"residual", "diffuse_micro", "diffuse_macro"}
    # docs/batch.md: without camera noise the measured height moves by a fraction of a
    # nanometre (0.28 nm measured), beyond the 0.02 nm tolerance
    rows = {(r["case"], r["image"]): r for r in summary["results"]}
    assert ("sts_grid_z", "measured_height") in failing
    assert 0.05 < rows[("sts_grid_z", "measured_height")]["max_abs_diff"] < 1.0


@pytest.mark.mitsuba
def test_another_seed_passes(tmp_path):
    """``--set simulation.seed=7`` is the seed of the Monte-Carlo passes only: new camera
    noise and new path-tracing samples in every Monte-Carlo image, the same surface (the
    machine's error motions, the material and the burrs keep the case's seed) and so the
    same deterministic images; the statistics say they all match, on the shipped cases
    with their lathe and material as they are."""
    names = "sts_grid_z,sts_grid_psi_noise,sculpt_quad_mla"
    summary, _ = _run_expect(tmp_path, names, ["simulation.seed=7"], fails=False)
    assert summary["failed"] == 0 and summary["pass_seed"] == 7
    assert {r["case"] for r in summary["results"]} == set(names.split(","))
    mc = [r for r in summary["results"] if r["kind"] == "monte_carlo"]
    assert len(mc) == 5 and all(r["min_p"] < 1.0 for r in mc)  # p = 1 only for identical passes
    det = {(r["case"], r["image"]): r for r in summary["results"] if r["kind"] == "deterministic"}
    assert det[("sculpt_quad_mla", "residual")]["max_abs_diff"] == 0.0  # the same burrs
    assert det[("sts_grid_z", "residual")]["max_abs_diff"] == 0.0  # the same servo noise


def test_the_passes_seed_is_checked(tmp_path):
    for bad in ("-1", "2000000", "1.5", "'x'"):
        with pytest.raises(InputError, match=r"--set simulation.seed must be a whole number in "
                                             r"\[0, 1999999\]"):
            run_regress(only="sts_grid_z", out=tmp_path / "o", overrides=[f"simulation.seed={bad}"])
    assert not (tmp_path / "o").exists()


@pytest.mark.mitsuba
def test_another_surface_seed_is_another_surface(tmp_path):
    """The surface's own draws (the lathe's servo noise, the burrs along the ridges) come
    from the case's seed: a case whose seed changes is another surface, and the suite says
    so.  (The residual alone is rendered: it is the surface; the other images follow it.)"""
    cases = tmp_path / "cases"
    (cases / "references").mkdir(parents=True)
    for name in ("sts_grid_z", "sculpt_quad_mla"):
        text = (CASES / f"{name}.toml").read_text()
        assert text.count("\n[set]\n") == 1
        text, n = re.subn(r"(?m)^images = \[.*\]$", 'images = ["residual"]', text)
        assert n == 1 and '"residual"' in (CASES / f"{name}.toml").read_text()
        (cases / f"{name}.toml").write_text(text.replace("\n[set]\n", '\n[set]\n"simulation.seed" = 7\n'))
        shutil.copytree(CASES / "references" / name, cases / "references" / name)
    with pytest.raises(RegressionFailed, match="differ from their references"):
        run_regress(cases=cases, out=tmp_path / "o")
    summary = json.loads((tmp_path / "o" / "summary.json").read_text())
    assert {("sts_grid_z", "residual"), ("sculpt_quad_mla", "residual")} == _failing(summary)


@pytest.mark.mitsuba
def test_update_makes_references_and_a_missing_one_is_reported(tmp_path):
    cases = tmp_path / "cases"
    cases.mkdir()
    shutil.copy(CASES / "sts_grid_normal.toml", cases / "a.toml")
    with pytest.raises(RegressionFailed, match=r"no reference for a/residual: run "
                                               r"`render-inspect regress --update --only a`"):
        run_regress(cases=cases, out=tmp_path / "o")
    run_regress(cases=cases, out=tmp_path / "o", update=True)
    meta = json.loads((cases / "references" / "a" / "reference.json").read_text())
    assert meta["software_version"] == __import__("render_inspect").__version__
    assert meta["mitsuba_variant"] and meta["images"]["residual"]["kind"] == "deterministic"
    run_regress(cases=cases, out=tmp_path / "o")
    with pytest.raises(InputError, match="--only 'nope' matches no regression case"):
        run_regress(cases=cases, only="nope", out=tmp_path / "o")
    with pytest.raises(InputError, match="--set cannot be used with --update"):
        run_regress(cases=cases, update=True, overrides=["simulation.seed=1"], out=tmp_path / "o")
    res = subprocess.run([str(EXE), "regress", "--only", "nope"], capture_output=True, text=True,
                         timeout=300, env={**os.environ}, cwd=tmp_path)  # default --out out/regress
    assert res.returncode == 1 and "matches no regression case" in res.stderr
