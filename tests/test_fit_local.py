"""Evaluations run several at once in this process: the same results, in the same order,
as one at a time (the fit's values must not depend on how its evaluations were run)."""

from __future__ import annotations

import os
import threading
import time

import numpy as np
import pytest

from render_inspect.core.errors import InputError
from render_inspect.fit import run_local


def _model(task):
    """A forward model that takes a while and whose result depends on its task only."""
    rng = np.random.default_rng(task["seed"])
    time.sleep(0.05 * (3 - task["seed"] % 3))  # the later tasks finish first
    if task["seed"] == 4:
        raise InputError("tool.nose_radius must be > 0 mm, received -1")
    return rng.normal(size=(16, 16)), {"seed": task["seed"], "thread": threading.get_ident()}


def test_tasks_run_at_once_come_back_in_order_with_the_results_of_one_at_a_time():
    tasks = [{"seed": s} for s in range(6)]
    alone = list(run_local(_model, tasks, 1))
    together = list(run_local(_model, tasks, 2))
    assert len(together) == len(alone) == 6
    for a, b in zip(alone, together):
        assert a[3] == b[3]  # the same error text (or None)
        if a[3] is None:
            assert np.array_equal(a[0], b[0]) and a[1]["seed"] == b[1]["seed"]
    assert together[4][0] is None and "nose_radius" in together[4][3]
    # two threads did the work
    assert len({r[1]["thread"] for r in together if r[3] is None}) == 2


def test_an_error_outside_the_models_own_is_raised_and_the_rest_dropped():
    started = []

    def model(task):
        started.append(task["seed"])
        if task["seed"] == 1:
            raise ValueError("a bug")
        time.sleep(0.05)
        return np.zeros(2), {}

    with pytest.raises(ValueError, match="a bug"):
        list(run_local(model, [{"seed": s} for s in range(8)], 2))
    time.sleep(0.2)
    assert len(started) < 8  # the tasks not started when it failed never ran
    with pytest.raises(InputError):  # catch=False: the model's own error is raised too
        list(run_local(_model, [{"seed": 4}, {"seed": 5}], 2, catch=False))


def test_a_local_evaluation_leaves_numba_num_threads_unset(monkeypatch):
    """An evaluation in the user's own process leaves NUMBA_NUM_THREADS as it found it
    (unset), so a LocalCluster started from that process later does not inherit it; where a
    worker has the variable, it is made to agree with numba's running count."""
    import numba

    from render_inspect.pipeline import _fit_model

    monkeypatch.delenv("NUMBA_NUM_THREADS", raising=False)
    _fit_model._numba_threads_as_launched()
    assert "NUMBA_NUM_THREADS" not in os.environ
    monkeypatch.setenv("NUMBA_NUM_THREADS", "999")
    _fit_model._numba_threads_as_launched()
    assert os.environ["NUMBA_NUM_THREADS"] == str(numba.config.NUMBA_NUM_THREADS)


#: a worker's evaluation in miniature: arrays of 1 MiB made and freed, counting the pages
#: the process faults in, plainly and through ``call_with_threads``
_FAULTS = """
import json, resource
import numpy as np
from render_inspect.batch import call_with_threads

def arrays(task):
    for _ in range(task["n"]):
        a = np.ones(1 << 17)  # 1 MiB: over glibc's mmap threshold of 128 KiB
        del a
    return task["n"]

def faults(run):
    f0 = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
    assert run() == 200
    return resource.getrusage(resource.RUSAGE_SELF).ru_minflt - f0

print(json.dumps({"plain": faults(lambda: arrays({"n": 200})),
                  "on_worker": faults(lambda: call_with_threads(None, arrays, {"n": 200})),
                  "plain_after": faults(lambda: arrays({"n": 200}))}))
"""


@pytest.mark.slow
def test_a_task_on_a_worker_keeps_its_arrays_on_the_heap(tmp_path):
    """A Dask nanny starts its workers with ``MALLOC_TRIM_THRESHOLD_`` set, which pins
    glibc's mmap threshold: every array over 128 KiB is mapped afresh and its pages fault
    in again (256 faults per MiB).  ``call_with_threads`` (every task the package runs
    on a worker: a fit's evaluation, a sweep's case, a tile) keeps them on the heap while
    it runs (a few faults in all), and the worker's own setting holds again after
    it (the arrays after it fault in as before)."""
    import json
    import subprocess
    import sys

    env = {**os.environ, "MALLOC_TRIM_THRESHOLD_": "65536"}
    out = subprocess.run([sys.executable, "-c", _FAULTS], env=env, capture_output=True,
                         text=True, timeout=300, cwd=tmp_path)
    assert out.returncode == 0, out.stderr[-2000:]
    n = json.loads(out.stdout.strip().splitlines()[-1])
    assert n["plain"] > 200 * 200 and n["plain_after"] > 200 * 200, n  # each array maps afresh
    assert n["on_worker"] < 2000, n  # the heap reused
