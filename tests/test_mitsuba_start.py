"""Mitsuba started in a thread while a render prepares what it traces
(``render.start_mitsuba``): the variant is chosen once whoever asks first, a thread asking
meanwhile waits for that choice, nothing is started outside a process's main thread or
once the variant is chosen, and a failure in the thread is raised by the render's own
call.  The choice itself is replaced here by a stand-in (no Mitsuba is imported)."""

from __future__ import annotations

import threading
import time

import pytest

from render_inspect.render import _variant, mitsuba_variant, start_mitsuba


@pytest.fixture
def chooser(monkeypatch):
    """A stand-in for the variant's choice that takes a while and counts its calls; the
    process's real choice (if any) is put back afterwards."""
    monkeypatch.setitem(_variant._STATE, "variant", None)
    monkeypatch.setitem(_variant._STATE, "message", None)
    monkeypatch.setattr(_variant, "_point_at_llvm", lambda: None)
    monkeypatch.setattr(_variant, "check_address_space", lambda *a, **k: None)
    calls = {"n": 0, "fail": 0}

    def choose():
        calls["n"] += 1
        time.sleep(0.2)
        if calls["fail"]:
            calls["fail"] -= 1
            raise RuntimeError("no variant works here")
        _variant._STATE["variant"] = "llvm_ad_rgb"
        return "llvm_ad_rgb"

    monkeypatch.setattr(_variant, "_choose_variant", choose)
    return calls


def test_the_variant_is_chosen_once_while_a_second_thread_waits_for_it(chooser):
    started = start_mitsuba()
    assert started is not None and started.daemon
    # (asked while the thread is still choosing: waits for its choice, chooses nothing)
    assert mitsuba_variant() == "llvm_ad_rgb"
    started.join()
    assert chooser["n"] == 1


def test_many_threads_asking_at_once_choose_once(chooser):
    got = []
    threads = [threading.Thread(target=lambda: got.append(mitsuba_variant())) for _ in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert got == ["llvm_ad_rgb"] * 4 and chooser["n"] == 1


def test_nothing_is_started_once_chosen_or_outside_the_main_thread(chooser):
    seen = []
    t = threading.Thread(target=lambda: seen.append(start_mitsuba()))
    t.start()
    t.join()
    assert seen == [None] and chooser["n"] == 0
    assert mitsuba_variant() == "llvm_ad_rgb"
    assert start_mitsuba() is None and chooser["n"] == 1


def test_a_failure_in_the_thread_is_raised_by_the_renders_own_call(chooser):
    chooser["fail"] = 2
    started = start_mitsuba()
    assert started is not None
    started.join()  # (the thread's failure is kept quiet there)
    with pytest.raises(RuntimeError, match="no variant works here"):
        mitsuba_variant()
    assert chooser["n"] == 2
    assert mitsuba_variant() == "llvm_ad_rgb"
