"""``characterise``: the virtual instrument's own metrological characteristics
(:func:`render_inspect.instruments.characterise_instrument`: transfer function, step
response, slope limit, noise), their figures, tables and metrics."""

from __future__ import annotations

import time
from pathlib import Path

from ..instruments import InterferometerConfig
from ..instruments import characterise_instrument as _characterise
from ..io import atomic_output_dir, atomic_write_bytes, atomic_write_text, table_csv
from ..report import characterise_figures
from ._metrics import characterisation_metrics, write_metrics

__all__ = ["characterise_instrument", "run_characterise"]


def characterise_instrument(icfg: InterferometerConfig, *, quick: bool = False,
                            seed: int = 0) -> tuple[dict, dict]:
    """Characterise the instrument of ``[render.interferometer]``
    (:func:`render_inspect.instruments.characterise_instrument`) and draw its figures.

    Returns
    -------
    metrics : dict
        ``objective``, ``mode``, ``itf``, ``step``, ``slope``, ``flat``, ``seed``,
        ``timing_s``.
    figures : dict name -> PNG bytes
    """
    metrics, curves = _characterise(icfg, quick=quick, seed=seed)
    return metrics, characterise_figures(metrics, curves)


def run_characterise(icfg: InterferometerConfig, out: str | Path, *, quick: bool = False,
                     seed: int = 0,
                     overwrite: bool = False) -> dict:
    """``render-inspect characterise``: the instrument ``icfg`` (an
    :class:`~render_inspect.scene.InterferometerConfig`, e.g.
    ``InterferometerConfig(objective="20x")``) characterised into ``out``.

    Parameters
    ----------
    icfg : InterferometerConfig
        The instrument (objective preset, overrides, source, camera, disturbances).
    out : path
        Output folder (atomic): ``metrics.json``, ``itf.csv``, ``itf.png``, ``step.csv``,
        ``step.png``, ``slope.csv``, ``slope.png``, ``flat_noise.png``.
    quick : bool
        Fewer points and smaller fields (for tests).
    seed : int
        Seed of the camera noise.
    overwrite : bool
        Replace ``out`` even if render_inspect did not write it (``out`` is checked and
        locked before the instrument is characterised).

    Returns
    -------
    dict
        ``metrics.json``: ``characterise`` (see :func:`characterise_instrument`),
        ``instrument_settings``, ``timing_s``, ``software_version``.
    """
    t0 = time.perf_counter()
    with atomic_output_dir(out, overwrite=overwrite, command="characterise") as tmp:
        metrics, figs = characterise_instrument(icfg, quick=quick, seed=seed)
        tmp = Path(tmp)
        atomic_write_text(tmp / "itf.csv", table_csv(metrics["itf"]["table"], [
            "frequency_per_mm", "period_um", "itf_optics", "itf_instrument", "itf_model",
            "itf_textbook", "aliased_instrument"]))
        atomic_write_text(tmp / "step.csv", table_csv(metrics["step"]["csi"]["table"], [
            "step_nm", "batwing_pv_nm", "batwing_height_nm", "batwing_width_um",
            "batwing_low_side_nm", "batwing_low_side_width_um", "batwing_high_side_nm",
            "batwing_high_side_width_um", "valid_fraction"]))
        atomic_write_text(tmp / "slope.csv", table_csv(
            [dict(r, series=k) for k, sl in metrics["slope"].items() for r in sl["table"]],
            ["series", "slope_deg", "pixels", "valid_fraction", "contrast", "error_rms_nm"]))
        for name, png in figs.items():
            atomic_write_bytes(tmp / name, png)
        timing = {**metrics.pop("timing_s"), "total": time.perf_counter() - t0}
        out_m = characterisation_metrics(metrics, icfg.model_dump(mode="json"), timing)
        write_metrics(tmp, out_m)
    return out_m
