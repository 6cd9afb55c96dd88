"""``fit`` on a measured profile with a random part's amplitude free: the profile's ``psd``
bands (its non-periodic part against the prediction plus the random parts' power) recover a
known amplitude, say when the amplitude is below the noise floor, and refuse a part the
profile does not see."""

from __future__ import annotations

import sys
import tomllib
from pathlib import Path

import numpy as np
import pytest

from render_inspect.core.errors import InputError
from render_inspect.fit._profile import (ProfileSpec, make_profile_target,
                                         predict_profile_features, profile_residual_vector)
from render_inspect.fit import set_profile_psd
from render_inspect.fit._profile_psd import effective_cells, predicted_bands

sys.path.insert(0, str(Path(__file__).resolve().parent))
from test_fit_profile import _write_profile  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
SCENE = REPO / "docs" / "examples" / "turned" / "scene.toml"
SPACING = 0.00087


def _turned(feed=3.96, nose=0.2, z_noise_nm=0.0):
    """The example turned scene with a planned spiral (its program left out), seen in
    white light, its Z slide a 100 Hz servo loop with following-error noise
    ``z_noise_nm`` rms."""
    from render_inspect.scene import scene_from_dict

    d = tomllib.loads(SCENE.read_text())
    d["process"].pop("program", None)
    d["process"]["feed_mm_per_min"] = feed
    d["tool"]["nose_radius"] = nose
    d["render"]["interferometer"]["mode"] = "csi"
    d["machine"]["z"] = {"bandwidth_hz": 100.0, "noise_nm": z_noise_nm}
    return scene_from_dict(d, "turned (planned spiral, Z noise)")




# ----------------------------------------------------------------------- the feature
def _cusps(n, period=0.036, radius=0.25, phase=0.0):
    x = np.arange(n) * SPACING + phase
    u = np.mod(x, period) - period / 2
    return u * u / (2 * radius)


def _steps(n, sigma_mm, rng, period=0.036, phase=0.0):
    """One independent offset per feed period: what a slide's following-error noise, cut
    once a revolution, leaves along a radial line."""
    x = np.arange(n) * SPACING + phase
    k = np.floor(x / period).astype(int)
    return rng.normal(0.0, sigma_mm, k.max() + 1)[k]


def test_effective_cells_of_a_hann_periodogram():
    assert effective_cells(1) == 1.0
    # many cells: the Hann window's correlated neighbours make each worth about half
    assert 0.45 < effective_cells(400) / 400 < 0.55


def test_psd_bands_recover_a_step_noise_amplitude():
    """Cusps with per-period offsets of 5 nm rms and 2 nm of white camera noise: the
    ``psd`` term, its random part's power measured at 2.5 nm, is lowest near 5 nm, and the
    amplitude read from it over independent profiles scatters as its residuals' scales
    say (the bands' Gamma statistics)."""
    rng = np.random.default_rng(3)
    lag, n = 30, 345
    m = n + 2 * lag
    clean = _cusps(m)
    cam = 2e-6
    spec = ProfileSpec(weights={"profile": 0.0, "params": 0.0, "harmonics": 0.0, "psd": 1.0})
    grid = np.linspace(0.5, 12.0, 231)
    found, widths = [], []
    for trial in range(24):
        meas = clean + _steps(m, 5e-6, rng) + rng.normal(0, cam, m)
        t = make_profile_target(meas[lag:lag + n], spacing=SPACING, lag=lag, spec=spec)
        noisy = [clean + rng.normal(0, cam, m) for _ in range(6)]
        alone = [clean + _steps(m, 2.5e-6, rng) for _ in range(6)]
        set_profile_psd(t, clean, noisy, [(0, 2.5, alone)], draws=6)
        assert t.psd_use.sum() >= 4
        # the clean prediction's bands once; the amplitude only scales the power added
        pred = predict_profile_features(clean, t, [2.5])
        raw = pred.psd - predicted_bands(np.zeros_like(pred.psd), t, [2.5])
        cost = []
        for v in grid:
            pred.psd = predicted_bands(raw, t, [v])
            d, a, terms = profile_residual_vector(pred, t)
            cost.append(float(np.sum(d * d)))
        cost = np.array(cost)
        i = int(np.argmin(cost))
        found.append(grid[i])
        # the least-squares curvature: the amplitude's standard error
        ok = cost <= cost[i] + 1.0
        widths.append(0.5 * (grid[ok].max() - grid[ok].min()))
    found = np.array(found)
    assert abs(np.median(found) - 5.0) < 0.6, found
    # the spread over realisations is what the residuals' scales give (within a factor 1.6)
    ratio = float(np.std(found) / np.median(widths))
    print(f"amplitude {np.median(found):.3g} nm, spread {np.std(found):.3g} nm, "
          f"scale {np.median(widths):.3g} nm")
    assert 0.6 < ratio < 1.6, (ratio, found, widths)


def test_amplitude_scan_tells_a_measured_amplitude_from_one_below_the_floor():
    """The ``psd`` term's chi-square along the amplitude: 6 nm of offsets per period stand
    clear of 0 (their chi-square at 0 is far above the least); 0.3 nm under 2 nm of white
    noise does not, and the upper limit lies between."""
    from render_inspect.fit._profile_psd import amplitude_scan

    rng = np.random.default_rng(5)
    lag, n = 30, 345
    m = n + 2 * lag
    clean = _cusps(m)
    spec = ProfileSpec()
    scans = {}
    for truth in (6.0, 0.3):
        meas = clean + _steps(m, truth * 1e-6, rng) + rng.normal(0, 2e-6, m)
        t = make_profile_target(meas[lag:lag + n], spacing=SPACING, lag=lag, spec=spec)
        noisy = [clean + rng.normal(0, 2e-6, m) for _ in range(6)]
        alone = [clean + _steps(m, 3e-6, rng) for _ in range(6)]
        set_profile_psd(t, clean, noisy, [(0, 3.0, alone)], draws=6)
        pred = predict_profile_features(clean, t, [3.0])
        scans[truth] = amplitude_scan(pred, t, [3.0], 0)
    assert scans[6.0]["chi2_at_zero_rise"] > 4.0, scans
    assert scans[0.3]["chi2_at_zero_rise"] < 4.0, scans
    assert 0.3 < scans[0.3]["upper_2se"] < 6.0, scans


def test_a_fitted_random_amplitude_is_part_of_the_evaluations_key():
    """The simulation holds the random parts at 0, but the features scale the fitted part's
    power with its amplitude: two amplitudes are two evaluations (one would otherwise be
    taken for the other, and the amplitude would never move from its start)."""
    from render_inspect.fit import task_hash
    from render_inspect.pipeline._fit_model import ForwardModel, SameSimulation

    base = _turned(z_noise_nm=2.5).to_dict()
    model = ForwardModel(base, None, [0.2, -0.01, 0.3, 0.01], 0.001,
                         {"objective": "20x", "noise": True}, 3,
                         {"machine.z.noise_nm": 2.5}, ("machine.z.noise_nm",))
    a, b = (model.task({"machine.z.noise_nm": v}) for v in (2.5, 3.0))
    assert a["scene"] == b["scene"] and a["scene"]["machine"]["z"]["noise_nm"] == 0.0
    assert task_hash(a) != task_hash(b)
    # ... and one simulation: the map's and the profile's fits run their forward model
    # through SameSimulation, which runs tasks that differ only in that amplitude once
    calls: list = []
    same = SameSimulation(lambda t: calls.append(t) or len(calls))
    assert same(a) == same(b) == 1 and len(calls) == 1
    assert same(model.task({"machine.z.noise_nm": 2.5, "process.feed_mm_per_min": 3.0})) == 2


# ---------------------------------------------------------------------- refusals
def test_a_random_part_started_at_zero_is_refused(tmp_path):
    from render_inspect.pipeline import run_fit_profile

    p = tmp_path / "slice.csv"
    _write_profile(p, np.arange(400) * SPACING, _cusps(400))
    with pytest.raises(InputError, match="--free machine.z.noise_nm.*start it above 0"):
        run_fit_profile(p, _turned(), ["machine.z.noise_nm"], tmp_path / "o",
                        line="0.1,0,0.5,0", window_mm=0.3)
    assert not (tmp_path / "o").exists()


# -------------------------------------------------------------------- known answer
@pytest.mark.slow
def test_fit_profile_recovers_the_z_noise_and_the_feed(tmp_path):
    """A profile simulated with a 36 um/rev feed and 5 nm rms of Z following-error noise
    (camera noise on) is fitted from 39.6 um/rev and 2.5 nm: both within two of their
    standard errors."""
    from render_inspect.pipeline import run_fit_profile
    from render_inspect.pipeline._fit_profile import simulate_profile

    truth = {"process.feed_mm_per_min": 3.6, "machine.z.noise_nm": 5.0}
    s, z = simulate_profile(_turned(feed=3.6, z_noise_nm=5.0), (0.1, 0.0), (0.5, 0.0),
                            SPACING, seed=7)
    p = tmp_path / "simulated.csv"
    _write_profile(p, s, z)
    rec = run_fit_profile(p, _turned(z_noise_nm=2.5),
                          ["process.feed_mm_per_min,machine.z.noise_nm"], tmp_path / "fit",
                          line="0.1,0,0.5,0", at=(0.3, 0.0), window_mm=0.3,
                          global_points=0, max_evaluations=60, profile_points=0,
                          cache=tmp_path / "cache")
    print({k: (v["value"], v["stderr"]) for k, v in rec["parameters"].items()})
    assert rec["random_parts"]["fitted_through_their_power"] == ["machine.z.noise_nm"]
    assert rec["random_parts"]["psd_bands"]["bands"] >= 4
    for k, v in truth.items():
        par = rec["parameters"][k]
        assert par["stderr"] is not None and par["stderr"] > 0, par
        assert abs(par["value"] - v) <= 2 * par["stderr"], (k, par)
    noise = rec["parameters"]["machine.z.noise_nm"]
    assert noise["stderr"] < 0.5 * noise["value"], noise
    assert noise["confident"] and noise["psd_scan"]["chi2_at_zero_rise"] > 4.0, noise
    assert not any("not determined" in line for line in rec["summary"]), rec["summary"]
    assert "psd" in rec["misfit"]["terms"]


@pytest.mark.slow
def test_fit_profile_says_a_z_noise_below_the_floor_is_not_determined(tmp_path):
    """The same cut with 0.3 nm of Z noise, below what the camera's noise leaves in the
    profile's bands, fitted from 3 nm: no confident number, an upper limit instead (its
    spectrum's misfit at 0 within 4 of its least)."""
    from render_inspect.pipeline import run_fit_profile
    from render_inspect.pipeline._fit_profile import simulate_profile

    s, z = simulate_profile(_turned(feed=3.6, z_noise_nm=0.3), (0.1, 0.0), (0.5, 0.0),
                            SPACING, seed=11)
    p = tmp_path / "quiet.csv"
    _write_profile(p, s, z)
    rec = run_fit_profile(p, _turned(feed=3.6, z_noise_nm=3.0), ["machine.z.noise_nm"],
                          tmp_path / "fit", line="0.1,0,0.5,0", at=(0.3, 0.0), window_mm=0.3,
                          global_points=0, max_evaluations=30, profile_points=0,
                          cache=tmp_path / "cache")
    par = rec["parameters"]["machine.z.noise_nm"]
    print(par)
    assert par["stderr"] is None and not par["confident"], par
    # eight periods hold eight values of the noise: the limit is wide, but above the truth
    assert par["upper_limit_2se"] is not None and 0.3 <= par["upper_limit_2se"] < 10.0, par
    assert par["psd_scan"]["chi2_at_zero_rise"] < 4.0, par
    assert any("not determined by this profile" in line for line in rec["summary"])


@pytest.mark.slow
@pytest.mark.filterwarnings("error::RuntimeWarning")
def test_fit_profile_refuses_a_random_part_the_line_does_not_see(tmp_path):
    """The spindle's angle noise moves the tool along the cut: on the rotationally
    symmetric part the radial line does not see it, and freeing it is refused in one line
    naming the key (and no warning of numpy's about the bands it leaves empty)."""
    from render_inspect.pipeline import run_fit_profile
    from render_inspect.pipeline._fit_profile import simulate_profile
    from render_inspect.scene import scene_from_dict

    s, z = simulate_profile(_turned(feed=3.6), (0.1, 0.0), (0.5, 0.0), SPACING, seed=5)
    p = tmp_path / "slice.csv"
    _write_profile(p, s, z)
    d = _turned(feed=3.6).to_dict()
    d["machine"]["c"] = {"bandwidth_hz": 60.0, "noise_urad": 5.0}
    scene = scene_from_dict(d, "turned (spindle angle noise)")
    # (a rotationally symmetric part: no window of the radial line sees it; 0.15 mm is enough)
    with pytest.raises(InputError, match="--free machine.c.noise_urad: this profile does not "
                                         "see that random part"):
        run_fit_profile(p, scene, ["machine.c.noise_urad"], tmp_path / "fit",
                        line="0.1,0,0.5,0", at=(0.3, 0.0), window_mm=0.15, global_points=0,
                        max_evaluations=20, profile_points=0, cache=tmp_path / "cache")
    assert not (tmp_path / "fit").exists()


def test_band_means_are_numpys_without_its_warning():
    """A band that is NaN in every simulated profile has a NaN mean, without numpy's
    "Mean of empty slice"; the others are ``np.nanmean``'s to the bit (an infinite value
    counts, as there)."""
    import warnings

    from render_inspect.fit._profile import _band_mean

    rng = np.random.default_rng(3)
    for _ in range(50):
        a = rng.normal(size=(int(rng.integers(1, 6)), 30))
        a[rng.random(a.shape) < 0.3] = np.nan
        a[rng.random(a.shape) < 0.05] = np.inf
        a[:, :2] = np.nan
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            expected = np.nanmean(a, axis=0)
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            got = _band_mean(list(a))
        assert np.array_equal(got, expected, equal_nan=True)
        assert np.isnan(got[:2]).all()
