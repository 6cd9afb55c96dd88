"""Memory budget: how much a command may allocate, and the one error when a request would
not fit.

Every command estimates the bytes its large arrays need *before* allocating them and
calls :func:`check_memory`.  The budget is ``simulation.max_memory_gb`` when the scene
sets it, else :data:`AUTO_FRACTION` of the memory the machine has available now
(``MemAvailable`` of ``/proc/meminfo``, capped by the control group's limit when one is
set); either is capped by the room left under the address-space limit (``ulimit -v``)
when one is set.  The error names what would be allocated, the parameter that drives its size, and
the value of that parameter that would fit (:func:`fit_value`).
"""

from __future__ import annotations

from typing import Any
from collections.abc import Iterable
import math
import os
from pathlib import Path

from .units import GIB_TO_BYTES, MIB_TO_BYTES, TIB_TO_BYTES
from .errors import MemoryBudgetError

__all__ = ["available_memory", "default_budget", "memory_budget", "check_memory",
           "fit_value", "format_bytes", "format_number", "AUTO_FRACTION", "Driver",
           "PIXEL_RANGE_MM", "MAX_FIELD_MM", "MAX_ABS_MM", "MOSTLY_EMPTY_FRACTION",
           "mostly_empty_warning", "address_space_limit", "address_space_used",
           "address_space_room", "check_address_space", "mitsuba_address_space", "usable_cpus",
           "ADDRESS_SPACE_HEADROOM", "MITSUBA_ADDRESS_SPACE", "MITSUBA_ADDRESS_SPACE_PER_THREAD",
           "TILED_SAMPLES"]

#: share of the available memory a command may use when the scene sets no budget
AUTO_FRACTION = 0.8
#: address space kept free under ``ulimit -v`` (beyond the budget's own 20 %) for what
#: libraries map as they go on (thread stacks, small buffers)
ADDRESS_SPACE_HEADROOM = 32 * MIB_TO_BYTES
#: address space a Mitsuba render (Mitsuba 3.9, ``llvm_ad_rgb``) reserves beyond what
#: the process held before Mitsuba was imported, and per Dr.Jit thread.  Measured with
#: ``render`` on the shipped sts_sinusoidal_grid scene, 2 threads: 642 MB held before,
#: peaks 446 MB (diffuse), 454 MB (interferometer) and 658 MB (both) above it; under
#: ``prlimit --as`` of 1100 MiB the diffuse render ends with a segmentation fault;
#: Dr.Jit's threads add about 12 MiB each (2 to 32 threads)
MITSUBA_ADDRESS_SPACE = 640 * MIB_TO_BYTES
MITSUBA_ADDRESS_SPACE_PER_THREAD = 16 * MIB_TO_BYTES
#: maps of more samples than this are simulated tile by tile whatever the memory budget
#: (when the process can): the in-memory run would hold several GiB and write a
#: heightmap.exr of more than 400 MB, the tiled one holds the tiles in flight and writes
#: a Zarr store with its pyramid
TILED_SAMPLES = 1 << 25  # not a unit conversion

# -- plausibility bounds of measured height maps (the readers and ``analyze`` refuse or
#    warn beyond them; see docs/limits.md)
#: sampling distance of a measured map, mm (0.1 nm .. 100 mm): outside this the file's
#: lateral unit was not understood
PIXEL_RANGE_MM = (1e-7, 100.0)
#: largest side of a measured field, mm
MAX_FIELD_MM = 2e4
#: largest height or origin coordinate, mm (the scene's positions keep within the same
#: bound: beyond it a double no longer resolves nanometres)
MAX_ABS_MM = 1e4
#: a map with more than this share of points not measured gets a warning
MOSTLY_EMPTY_FRACTION = 0.5


def mostly_empty_warning(unmeasured_fraction: float) -> str:
    """The warning for a map more than :data:`MOSTLY_EMPTY_FRACTION` of which is not
    measured."""
    return (f"{unmeasured_fraction:.0%} of the map is not measured (more than "
            f"{MOSTLY_EMPTY_FRACTION:.0%}): its parameters describe the measured "
            f"{1.0 - unmeasured_fraction:.0%} only; check the instrument's settings or crop "
            f"the map to the measured area")
_FALLBACK = 4 * GIB_TO_BYTES


def _meminfo_available() -> int | None:
    try:
        text = Path("/proc/meminfo").read_text()
    except OSError:
        return None
    for line in text.splitlines():
        if line.startswith("MemAvailable:"):
            parts = line.split()
            if len(parts) >= 2 and parts[1].isdigit():
                return int(parts[1]) * 1024
    return None


def _cgroup_room() -> int | None:
    """Bytes left under the control group's memory limit (cgroup v2 or v1), if any."""
    for limit_f, usage_f in (("/sys/fs/cgroup/memory.max", "/sys/fs/cgroup/memory.current"),
                             ("/sys/fs/cgroup/memory/memory.limit_in_bytes",
                              "/sys/fs/cgroup/memory/memory.usage_in_bytes")):
        try:
            limit = Path(limit_f).read_text().strip()
            usage = Path(usage_f).read_text().strip()
        except OSError:
            continue
        if not limit.isdigit() or not usage.isdigit():
            continue
        lim = int(limit)
        if lim >= 2 ** 60:  # "no limit" in cgroup v1
            continue
        return max(lim - int(usage), 0)
    return None


def address_space_limit() -> int | None:
    """The process's address-space limit (``ulimit -v``, RLIMIT_AS soft limit), bytes, or
    None when there is none."""
    try:
        import resource

        soft, _ = resource.getrlimit(resource.RLIMIT_AS)
    except (ImportError, ValueError, OSError, AttributeError):
        return None
    if soft == resource.RLIM_INFINITY or soft < 0:
        return None
    return int(soft)


def address_space_used() -> int | None:
    """Bytes of address space the process holds now (``VmSize``), or None if unknown."""
    try:
        text = Path("/proc/self/status").read_text()
    except OSError:
        return None
    for line in text.splitlines():
        if line.startswith("VmSize:"):
            parts = line.split()
            if len(parts) >= 2 and parts[1].isdigit():
                return int(parts[1]) * 1024
    return None


def address_space_room() -> int | None:
    """Bytes that new allocations may still reserve under the address-space limit: the
    limit less what the process holds now and :data:`ADDRESS_SPACE_HEADROOM`; None when
    there is no limit."""
    limit = address_space_limit()
    if limit is None:
        return None
    used = address_space_used() or 0
    return max(limit - used - ADDRESS_SPACE_HEADROOM, 0)


def available_memory() -> int:
    """Bytes the machine can give a new allocation now (``MemAvailable``, or the room
    under the control group's limit or under the address-space limit, ``ulimit -v``, if
    smaller); a fixed 4 GiB when none is known."""
    cands = [v for v in (_meminfo_available(), _cgroup_room()) if v is not None]
    if not cands:
        try:
            cands = [os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")]
        except (ValueError, OSError, AttributeError):
            cands = [_FALLBACK]
    room = address_space_room()
    if room is not None:
        cands.append(room)
    return int(min(cands))


def default_budget() -> int:
    """:data:`AUTO_FRACTION` of :func:`available_memory`, bytes."""
    return int(AUTO_FRACTION * available_memory())


def _limit_text() -> str:
    limit = address_space_limit()
    used = address_space_used()
    used_text = f", {format_bytes(used)} of it in use" if used is not None else ""
    return f"the address-space limit (ulimit -v) of {format_bytes(limit)}{used_text}"


def memory_budget(max_memory_gb: float | None = None) -> tuple[int, str]:
    """(bytes, where the figure comes from) for a scene's ``simulation.max_memory_gb``
    (None: the automatic budget).  The address-space limit (``ulimit -v``) caps either:
    an allocation beyond it fails however much memory the machine has."""
    room = address_space_room()
    if max_memory_gb is not None:
        asked = int(float(max_memory_gb) * GIB_TO_BYTES)
        if room is not None and room < asked:
            return room, (f"simulation.max_memory_gb = {max_memory_gb:g}, capped by "
                          f"{_limit_text()}")
        return asked, f"simulation.max_memory_gb = {max_memory_gb:g}"
    b = default_budget()
    if room is not None and room <= available_memory():
        return b, (f"{AUTO_FRACTION:.0%} of the room under {_limit_text()}; raise it "
                   f"(ulimit -v unlimited) or set simulation.max_memory_gb lower")
    return b, (f"{AUTO_FRACTION:.0%} of the memory available now, {format_bytes(b / AUTO_FRACTION)}; "
               f"set simulation.max_memory_gb to choose")


def usable_cpus() -> int:
    """The CPUs this process may run on: its CPU affinity where the system reports one
    (``taskset``, a batch scheduler's CPU set), else the machine's CPU count.  Threads
    beyond it only share the same cores and add memory."""
    try:
        return max(len(os.sched_getaffinity(0)), 1)
    except (AttributeError, OSError):
        return os.cpu_count() or 1


def mitsuba_address_space(threads: int | None = None) -> int:
    """Address space a Mitsuba render (LLVM variant) reserves beyond what the process held
    before Mitsuba was imported: :data:`MITSUBA_ADDRESS_SPACE` plus
    :data:`MITSUBA_ADDRESS_SPACE_PER_THREAD` for each of Dr.Jit's threads (one per CPU
    unless ``threads``)."""
    if threads is None:
        threads = os.cpu_count() or 1
    return MITSUBA_ADDRESS_SPACE + MITSUBA_ADDRESS_SPACE_PER_THREAD * max(int(threads), 1)


def check_address_space(nbytes: float, *, what: str) -> None:
    """Refuse, with one line naming the limit, work that would reserve ``nbytes`` more
    address space than the address-space limit (``ulimit -v``) leaves: for libraries that
    crash rather than fail cleanly when a reservation is refused (Mitsuba's LLVM JIT ends
    with a segmentation fault).  Nothing happens without a limit."""
    limit = address_space_limit()
    if limit is None:
        return
    used = address_space_used() or 0
    room = limit - used
    if float(nbytes) > room:
        raise MemoryBudgetError(
            f"{what} reserves about {format_bytes(nbytes)} of address space, more than the "
            f"{format_bytes(max(room, 0))} left under the address-space limit (ulimit -v, "
            f"RLIMIT_AS) of {format_bytes(limit)} ({format_bytes(used)} in use); raise the "
            f"limit to at least {format_bytes(used + float(nbytes))} or remove it "
            f"(ulimit -v unlimited)")


def format_number(v: Any) -> str:
    """A number in at most 3 significant digits (``1.2e+14``, ``3600``, ``0.0025``)."""
    try:
        f = float(v)
    except (TypeError, ValueError, OverflowError):
        return repr(v)
    if math.isnan(f):
        return "nan"
    if math.isinf(f):
        return "inf" if f > 0 else "-inf"
    if f == int(f) and abs(f) < 1e6:
        return str(int(f))
    return f"{f:.3g}"


def format_bytes(n: Any) -> str:
    """Bytes as MiB, GiB or TiB with 3 significant digits (huge figures in powers of ten,
    never hundreds of digits)."""
    try:
        f = float(n)
    except OverflowError:
        f = math.inf
    if not math.isfinite(f):
        return "an unbounded amount of memory"
    if f < GIB_TO_BYTES:
        return f"{f / MIB_TO_BYTES:.3g} MiB"
    if f < TIB_TO_BYTES:
        return f"{f / GIB_TO_BYTES:.3g} GiB"
    return f"{f / TIB_TO_BYTES:.3g} TiB"


def fit_value(value: float, nbytes: float, budget: float, exponent: float) -> float:
    """The value of a parameter that brings ``nbytes`` down to ``budget`` when the memory
    grows as ``value ** exponent`` (1: linear, -1: inverse, 2: an area, -2: a pixel)."""
    try:
        ratio = float(budget) / float(nbytes)
    except (OverflowError, ZeroDivisionError):
        ratio = 0.0
    if ratio <= 0 or not math.isfinite(ratio):
        return 0.0 if exponent > 0 else math.inf
    return float(value) * ratio ** (1.0 / exponent)


class Driver:
    """A parameter that drives the size of an allocation.

    Parameters
    ----------
    key : str
        Scene key (dotted) or command-line option.
    value : float
        Its value now.
    exponent : float
        Memory grows as ``value ** exponent``.
    unit : str
        Unit printed after the values.
    limit : (lo, hi), optional
        The schema's range; advice outside it is not given.
    """

    def __init__(self, key: str, value: Any, exponent: float, unit: str = "", *,
                 limit: tuple[float | None, float | None] | None = None):
        self.key, self.value, self.exponent, self.unit = key, value, exponent, unit
        self.limit = limit

    def advice(self, nbytes: float, budget: float) -> str | None:
        try:
            v = float(self.value)
        except (TypeError, ValueError, OverflowError):
            return None
        if v == 0 or not math.isfinite(v):
            return None
        target = fit_value(v, nbytes, budget, self.exponent)
        if not math.isfinite(target) or target == 0:
            return None
        if self.limit is not None:
            lo, hi = self.limit
            if (lo is not None and target < lo) or (hi is not None and target > hi):
                return None
        rel = "<=" if self.exponent > 0 else ">="
        unit = f" {self.unit}" if self.unit else ""
        return f"{self.key} {rel} {format_number(target)}{unit} (now {format_number(v)}{unit})"


def check_memory(nbytes: float, *, what: str, budget: tuple[int, str] | int | None = None,
                 drivers: Iterable[Any] = (), hint: str | None = None) -> int:
    """Raise :class:`MemoryBudgetError` when ``nbytes`` exceeds the budget.

    Parameters
    ----------
    nbytes : int or float
        Estimated bytes at the peak (may be a float, or inf for a request that cannot be
        counted).
    what : str
        What would be allocated ("the tool path (2.1e9 points)").
    budget : (bytes, source) or bytes, optional
        From :func:`memory_budget`; default: the automatic budget.
    drivers : sequence of Driver
        The parameters that drive the size, most direct first: the message says how far
        each one would have to change.
    hint : str, optional
        Further advice appended to the message.

    Returns
    -------
    int
        ``nbytes`` (as an int when it fits).
    """
    if budget is None:
        budget = memory_budget(None)
    if isinstance(budget, tuple):
        limit, source = budget
    else:
        limit, source = int(budget), "the memory budget"
    try:
        n = float(nbytes)
    except OverflowError:
        n = math.inf
    if math.isnan(n):
        n = math.inf
    if n <= limit:
        return int(n)
    tips = [t for t in (d.advice(n, limit) for d in drivers) if t]
    msg = (f"{what} would need about {format_bytes(n)}, more than the memory budget of "
           f"{format_bytes(limit)} ({source})")
    if tips:
        msg += "; to fit, set " + " or ".join(tips)
    if hint:
        msg += f"; {hint}"
    raise MemoryBudgetError(msg)
