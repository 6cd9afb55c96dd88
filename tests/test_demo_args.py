"""``demo``'s options: ``--set`` reaches the demo's scene after ``--quick``'s window, and a
wrong key is refused in one line before anything runs."""

from __future__ import annotations

from render_inspect.cli import main
from render_inspect.pipeline import _demo


def test_set_is_applied_after_the_quick_window(tmp_path, monkeypatch):
    seen = {}

    def fake_compare(scene, out, *, overwrite=False, **kw):
        seen.update(scene=scene, out=out, overwrite=overwrite, **kw)
        return {}

    monkeypatch.setattr(_demo, "run_compare", fake_compare)
    _demo.run_demo(tmp_path / "d", quick=True,
                   overrides=["simulation.pixel=0.004", "render.diffuse.spp=4"])
    sc = seen["scene"]
    assert sc.name == "sts_sinusoidal_grid"
    assert tuple(sc.simulation.region) == (-0.25, -0.25, 0.25, 0.25)  # --quick's window kept
    assert sc.simulation.pixel == 0.004  # the override wins over --quick's 2 um
    assert sc.render.diffuse.spp == 4


def test_a_wrong_key_is_one_line_and_nothing_is_written(tmp_path, capsys):
    out = tmp_path / "demo"
    assert main(["demo", "--out", str(out), "--set", "simulation.pixle=0.004"]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "pixle" in err[0] and "demo" in err[0]
    assert not out.exists()
