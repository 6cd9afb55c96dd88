"""Progress of a batch run with an estimate of the time left: a tqdm bar on a terminal,
one log line per finished item otherwise (logs and CI)."""

from __future__ import annotations

import logging
import sys
import time

__all__ = ["Progress"]

log = logging.getLogger("render_inspect")


def _hms(s: float) -> str:
    s = int(round(max(s, 0)))
    h, r = divmod(s, 3600)
    m, s = divmod(r, 60)
    return f"{h}:{m:02d}:{s:02d}" if h else f"{m:02d}:{s:02d}"


class Progress:
    """Count finished items and estimate the time left from the rate since the start.

    Parameters
    ----------
    total : int
        Items in the whole run (finished ones included).
    done : int
        Items already finished before this run (a resumed sweep).
    desc : str
    bar : bool, optional
        A tqdm bar (default: when stderr is a terminal); else log lines.
    """

    def __init__(self, total: int, *, done: int = 0, desc: str = "sweep", bar: bool | None = None):
        self.total, self.done0, self.done, self.failed = int(total), int(done), int(done), 0
        self.desc = desc
        self.t0 = time.monotonic()
        self._bar = None
        if bar is None:
            bar = sys.stderr.isatty()
        if bar:
            from tqdm import tqdm

            self._bar = tqdm(total=self.total, initial=self.done, desc=desc, unit="point",
                             file=sys.stderr, smoothing=0.1, dynamic_ncols=True)

    def eta_s(self) -> float | None:
        """Seconds left at the rate of this run so far (None before the first item)."""
        n = self.done - self.done0
        if n <= 0:
            return None
        return (time.monotonic() - self.t0) / n * (self.total - self.done)

    def update(self, note: str = "", *, failed: bool = False) -> None:
        self.done += 1
        self.failed += bool(failed)
        if self._bar is not None:
            self._bar.set_postfix_str(f"failed {self.failed}" if self.failed else "", refresh=False)
            self._bar.update(1)
            return
        eta = self.eta_s()
        log.info("%s %d/%d%s, %s elapsed, ETA %s%s", self.desc, self.done, self.total,
                 f" ({self.failed} failed)" if self.failed else "",
                 _hms(time.monotonic() - self.t0), "-" if eta is None else _hms(eta),
                 f": {note}" if note else "")

    def close(self) -> None:
        if self._bar is not None:
            self._bar.close()
            self._bar = None
