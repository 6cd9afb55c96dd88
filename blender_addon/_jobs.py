"""Long work in a worker process: progress, cancel, nothing half-made.

A :class:`Job` runs one task of ``_tasks.py`` in a child process (``_worker.py``): the
Python that runs Blender's scripts for plain tasks, Blender itself in background mode for
the Cycles render (in ``bpy``-as-a-module there is no Blender binary; the child is that
Python again).  A reader thread collects the child's progress lines; the modal operator
polls :attr:`Job.state` on a timer.  :meth:`Job.cancel` stops the child (SIGTERM, then
kill) and removes the hidden ``.<folder>.partial-*`` folders it was writing, so a cancelled
run leaves neither files nor Blender data behind.
"""

import atexit
import json
import os
import shutil
import subprocess
import sys
import tempfile
import threading
import time
from collections import deque
from pathlib import Path

HERE = Path(__file__).resolve().parent
WORKER = HERE / "_worker.py"
TASKS = HERE / "_tasks.py"
PREFIX = "@render_inspect@ "
#: Tasks whose worker must be Blender (they use bpy).
NEEDS_BLENDER = {"render"}

#: The job now running (one at a time), or None.
current = None


def worker_command(task: str, spec: Path) -> list[str]:
    """The child's command line: Blender in background mode for bpy tasks when this is
    the Blender application, else this Python (``sys.executable``)."""
    binary = ""
    if task in NEEDS_BLENDER:
        import bpy

        binary = bpy.app.binary_path
    if binary:
        return [binary, "--background", "--factory-startup", "-noaudio", "--python-exit-code",
                "1", "--python", str(WORKER), "--", str(spec)]
    return [sys.executable, str(WORKER), str(spec)]


def worker_numba_cache(folder: str) -> str:
    """The workers' own numba cache inside ``folder`` (Blender's).  Blender imports the
    extension's render_inspect as ``bl_ext.<repository>.render_inspect._bundled.render_inspect``,
    a worker as ``render_inspect``; numba names a cache file after the source file alone,
    but a cached kernel that calls another kernel refers to it by its module's full name, so
    a kernel cached by one process fails to load in the other (``No module named
    'bl_ext'``).  Separate folders keep each process to kernels it can load."""
    return os.path.join(folder, "render_inspect_worker")


def remove_partials(out, since: float) -> list[str]:
    """Remove the hidden ``.<name>.partial-*`` folders next to ``out`` made after
    ``since`` (time.time()) by an output folder being written; return their paths."""
    out = Path(out)
    removed = []
    if not out.parent.is_dir():
        return removed
    for d in out.parent.glob(f".{out.name}.partial-*"):
        try:
            if d.is_dir() and d.stat().st_mtime >= since - 2.0:
                shutil.rmtree(d, ignore_errors=True)
                removed.append(str(d))
        except OSError:
            pass
    return removed


class Job:
    """One task in a worker process.

    Parameters
    ----------
    task : str
        A key of ``_tasks.TASKS``.
    params : dict
        JSON-able parameters of the task.
    out_dirs : sequence of path
        Output folders the task writes (cleaned of partial folders on cancel/failure).
    """

    def __init__(self, task: str, params: dict, *, out_dirs=()):
        self.task = task
        self.params = params
        self.out_dirs = [str(d) for d in out_dirs]
        self.started = time.time()
        self.progress = 0.0
        self.message = "starting"
        self.result = None
        self.error = None
        self.cancelled = False
        self.tail = deque(maxlen=40)
        self.steps = deque(maxlen=200)  # every progress message, in order
        self._lock = threading.Lock()
        self._dir = Path(tempfile.mkdtemp(prefix="render_inspect_job_"))
        spec = self._dir / "spec.json"
        from . import _lib

        where = _lib.folder()  # the worker imports this render_inspect (the extension's copy)
        spec.write_text(json.dumps({"task": task, "params": params, "tasks_file": str(TASKS),
                                    "render_inspect_path": str(where.parent) if where else ""}))
        env = dict(os.environ)
        env["RENDER_INSPECT_SYS_PATH"] = json.dumps([p for p in sys.path if p])
        env["PYTHONUNBUFFERED"] = "1"
        if env.get("NUMBA_CACHE_DIR"):
            env["NUMBA_CACHE_DIR"] = worker_numba_cache(env["NUMBA_CACHE_DIR"])
        kwargs = {}
        if os.name == "posix":
            kwargs["start_new_session"] = True  # Ctrl-C in Blender's terminal is not the child's
        else:
            kwargs["creationflags"] = subprocess.CREATE_NEW_PROCESS_GROUP
        self.proc = subprocess.Popen(worker_command(task, spec), stdout=subprocess.PIPE,
                                     stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL,
                                     text=True, encoding="utf-8", errors="replace", env=env,
                                     **kwargs)
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()

    def _read(self):
        for line in self.proc.stdout:
            if not line.startswith(PREFIX):
                self.tail.append(line.rstrip())
                continue
            try:
                msg = json.loads(line[len(PREFIX):])
            except ValueError:
                continue
            with self._lock:
                if "progress" in msg:
                    self.progress = min(max(float(msg["progress"]), 0.0), 1.0)
                    self.message = msg.get("message", self.message)
                    self.steps.append(self.message)
                if "result" in msg:
                    self.result = msg["result"]
                if "error" in msg:
                    self.error = msg["error"]

    @property
    def state(self) -> str:
        """``running``, ``finished``, ``failed`` or ``cancelled``."""
        if self.cancelled:
            return "cancelled"
        if self.proc.poll() is None or self._reader.is_alive():
            return "running"
        with self._lock:
            if self.result is not None and self.error is None:
                return "finished"
            if self.error is None:
                last = next((t for t in reversed(self.tail) if t.strip()), "no output")
                self.error = (f"the {self.task} worker stopped (exit code {self.proc.returncode}) "
                              f"without a result: {last}")
        return "failed"

    def wait(self, timeout: float | None = None) -> str:
        """Block until the job is no longer running (or ``timeout`` s); return the state."""
        t_end = None if timeout is None else time.monotonic() + timeout
        while self.state == "running":
            if t_end is not None and time.monotonic() > t_end:
                break
            time.sleep(0.05)
        state = self.state
        if state != "running":
            self.clean()
        return state

    def cancel(self, grace: float = 5.0) -> None:
        """Stop the worker (SIGTERM: it removes what it was writing; after ``grace``
        seconds, kill) and remove any partial output folder."""
        self.cancelled = True
        if self.proc.poll() is None:
            self.proc.terminate()
            try:
                self.proc.wait(grace)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
        self._reader.join(5.0)
        self.clean()

    def clean(self) -> list[str]:
        """Remove partial output folders and the job's own temporary folder."""
        removed = []
        for d in self.out_dirs:
            removed += remove_partials(d, self.started)
        shutil.rmtree(self._dir, ignore_errors=True)
        return removed


def start(task: str, params: dict, *, out_dirs=()) -> Job:
    """Start ``task`` in a worker and make it the current job."""
    global current
    if current is not None and current.state == "running":
        raise RuntimeError("render_inspect is already running a job")
    current = Job(task, params, out_dirs=out_dirs)
    return current


def finish_current() -> None:
    global current
    current = None


def cancel_current() -> None:
    """Cancel the running job, if any (used when the add-on is disabled)."""
    global current
    if current is not None and current.state == "running":
        current.cancel()
    current = None


# Blender quitting while a job runs: stop the worker too (it runs in its own session)
atexit.register(cancel_current)


def run_here(task: str, params: dict, progress=None) -> dict:
    """Run ``task`` in this process (background mode, scripts): the same code as the
    worker's, synchronously."""
    from . import _tasks

    return _tasks.run(task, params, progress or (lambda f, m: None))
