"""The imaging model's tables (the transfer function's, the pupil's unit table, the facets'
acceptance) are kept on disk: a second process reads them back instead of building them,
bit for bit the tables built; a damaged or altered entry is built again."""

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from render_inspect.instruments import led, monochromatic
from render_inspect.instruments import _table_cache as tc
from render_inspect.instruments._transfer import (
    _acceptance_table,
    _transfer_arrays,
    _unit_transfer_table,
    acceptance_table,
    transfer_function,
    unit_transfer_table,
)

ROOT = Path(__file__).resolve().parents[1]

_CODE = """
import hashlib, json
from render_inspect.instruments import led
from render_inspect.instruments._table_cache import STATS
from render_inspect.instruments._transfer import acceptance_table, transfer_function
tf = transfer_function(0.3, 0.3, 0.0, led(600.0, bandwidth_nm=120.0), dK=2000.0)
alpha, frac = acceptance_table(0.3, 0.3, 0.0, n_alpha=257, n_grid=48)
h = hashlib.sha256(tf.table.tobytes() + tf.K.tobytes() + tf.support.tobytes()
                   + frac.tobytes()).hexdigest()
print(json.dumps({"stats": STATS, "sha": h, "floats": [tf.dq, tf.q_max, tf.k_eff, tf.sigma_k]}))
"""


def _run(env):
    out = subprocess.run([sys.executable, "-c", _CODE], env=env, capture_output=True, text=True,
                         check=True, cwd=ROOT)
    return json.loads(out.stdout.strip().splitlines()[-1])


@pytest.mark.slow
def test_second_process_loads_the_tables_from_the_cache(tmp_path):
    env = {**os.environ, "XDG_CACHE_HOME": str(tmp_path / "cache"),
           "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])}
    env.pop(tc.TABLE_CACHE_ENV, None)
    first = _run(env)
    # the transfer function, the unit table it is made from, the acceptance table
    assert first["stats"] == {"built": 3, "loaded": 0, "rebuilt": 0}
    files = sorted((tmp_path / "cache" / "render_inspect" / "tables").glob("*.npz"))
    assert len(files) == 3
    second = _run(env)
    # (the unit table is needed only to build the transfer function)
    assert second["stats"] == {"built": 0, "loaded": 2, "rebuilt": 0}
    assert second["sha"] == first["sha"] and second["floats"] == first["floats"]
    off = _run({**env, tc.TABLE_CACHE_ENV: "off"})
    assert off["stats"] == {"built": 3, "loaded": 0, "rebuilt": 0}
    assert off["sha"] == first["sha"] and off["floats"] == first["floats"]


@pytest.fixture
def cache(tmp_path, monkeypatch):
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    monkeypatch.delenv(tc.TABLE_CACHE_ENV, raising=False)
    return tmp_path / "render_inspect" / "tables"


def _same(a, b):
    return a.dtype == b.dtype and a.shape == b.shape and a.tobytes() == b.tobytes()


def test_a_table_read_back_is_the_table_built(cache):
    src = monochromatic(550.0, bandwidth_nm=10.0)
    args = dict(na=0.25, na_ill=0.2, obscuration=0.1)
    built = _transfer_arrays(0.25, 0.2, 0.1, src, dK=3000.0, n_q=256)
    tf = transfer_function(0.25, 0.2, 0.1, src, dK=3000.0, n_q=256)  # built and written
    before = dict(tc.STATS)
    again = transfer_function(0.25, 0.2, 0.1, src, dK=3000.0, n_q=256)  # read back
    assert tc.STATS["loaded"] == before["loaded"] + 1
    for t in (tf, again):
        assert _same(t.table, built["table"]) and _same(t.K, built["K"])
        assert _same(t.support, built["support"])
        assert (t.dq, t.q_max, t.k_eff, t.sigma_k, t.dK) == tuple(
            float(built[k]) for k in ("dq", "q_max", "k_eff", "sigma_k", "dK"))
    u, kappa, g = _unit_transfer_table(**args, n_u=65, n_kappa=96, n_grid=24)
    for _ in range(2):
        got = unit_transfer_table.__wrapped__(0.25, 0.2, 0.1, n_u=65, n_kappa=96, n_grid=24)
        assert all(_same(x, y) for x, y in zip(got, (u, kappa, g)))
    alpha, frac = _acceptance_table(**args, n_alpha=129, n_grid=24)
    for _ in range(2):
        got = acceptance_table.__wrapped__(0.25, 0.2, 0.1, n_alpha=129, n_grid=24)
        assert _same(got[0], alpha) and _same(got[1], frac)


def test_a_damaged_or_altered_entry_is_built_again(cache):
    src = led(600.0, bandwidth_nm=120.0)
    good = transfer_function(0.2, 0.2, 0.0, src, dK=5000.0, n_q=128)
    (entry,) = cache.glob("transfer_function-*.npz")
    # altered: a value changed, the file otherwise whole
    with np.load(entry) as z:
        arrays = {k: z[k] for k in z.files}
    arrays["table"] = arrays["table"] * np.float32(2)
    np.savez(entry, **arrays)
    before = dict(tc.STATS)
    again = transfer_function(0.2, 0.2, 0.0, src, dK=5000.0, n_q=128)
    assert tc.STATS["rebuilt"] == before["rebuilt"] + 1
    assert _same(again.table, good.table)
    # damaged: cut short
    data = entry.read_bytes()
    entry.write_bytes(data[: len(data) // 2])
    before = dict(tc.STATS)
    again = transfer_function(0.2, 0.2, 0.0, src, dK=5000.0, n_q=128)
    assert tc.STATS["rebuilt"] == before["rebuilt"] + 1
    assert _same(again.table, good.table)
    # and written anew: the next read loads it
    before = dict(tc.STATS)
    transfer_function(0.2, 0.2, 0.0, src, dK=5000.0, n_q=128)
    assert tc.STATS["loaded"] == before["loaded"] + 1
    assert not list(cache.glob(".*.tmp"))


def test_other_arguments_or_versions_are_other_entries():
    k = tc.table_key("t", {"na": 0.4, "source": {"wavelength_nm": 550.0}}, __file__)
    assert k != tc.table_key("t", {"na": float(np.nextafter(0.4, 1)),
                                   "source": {"wavelength_nm": 550.0}}, __file__)
    assert k != tc.table_key("t", {"na": 0.4, "source": {"wavelength_nm": 551.0}}, __file__)
    assert k != tc.table_key("u", {"na": 0.4, "source": {"wavelength_nm": 550.0}}, __file__)
    assert k == tc.table_key("t", {"source": {"wavelength_nm": 550.0}, "na": 0.4}, __file__)
    # the code that builds it: another module's text is another entry
    assert k != tc.table_key("t", {"na": 0.4, "source": {"wavelength_nm": 550.0}},
                             (__file__, tc.__file__))


def test_an_unwritable_cache_folder_leaves_the_cache_off(tmp_path, monkeypatch):
    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    monkeypatch.setenv("XDG_CACHE_HOME", str(blocker))
    monkeypatch.delenv(tc.TABLE_CACHE_ENV, raising=False)
    got = tc.cached_arrays("t", {"a": 1}, __file__, lambda: {"x": np.arange(3.0)})
    assert _same(got["x"], np.arange(3.0))
