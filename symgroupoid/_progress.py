"""Progress of long work: derivations, kernel builds, simulations, boundary-value solves.

Work that ends within :data:`DELAY` seconds reports nothing.  Longer work reports according
to the ``progress`` switch of the entry point that started it:

- ``progress=True``: a bar on stderr — tqdm's for counted work when tqdm is installed
  (``pip install 'symgroupoid[progress]'``), else a one-line text bar.  On a terminal the
  bar is redrawn in place and erased when the work ends (the caller reports the result);
  elsewhere (a pipe, a log file) a line is written once the work has run for DELAY
  seconds, then every :data:`LOG_INTERVAL` seconds, and a last line when it ends;
- ``progress=False``: nothing;
- ``progress=None`` (the default): the choice of the enclosing work (a kernel build inside
  a boundary-value solve follows the solve), else the process default (:func:`set_default`),
  which is INFO messages on the ``"symgroupoid"`` logger — silent unless the application
  configures logging (``logging.basicConfig(level=logging.INFO)``).

The command line turns bars on for everything it runs.  Reports are made by a background
thread between the caller's updates, and a running simulation updates its task only between
chunks of steps, so the step loop itself is untouched.
"""

from __future__ import annotations

import contextvars
import functools
import logging
import shutil
import sys
import threading
import time
from collections.abc import Callable

from ._arguments import flag_argument

logger = logging.getLogger("symgroupoid")

#: seconds a piece of work runs before anything is reported
DELAY = 2.0
#: seconds between redraws of a bar on a terminal
REFRESH = 0.2
#: seconds between report lines when not drawing on a terminal (log messages, pipes)
LOG_INTERVAL = 10.0
#: characters of the built-in bar
BAR_WIDTH = 24

_MODES = {True: "bar", False: "off", None: "log"}
_default: bool | None = None
_active: contextvars.ContextVar[tuple[Task, ...]] = contextvars.ContextVar(
    "symgroupoid_progress", default=())


def set_default(progress: bool | None) -> bool | None:
    """Set the process default used by ``progress=None`` outside any reported work
    (True: bars, False: nothing, None: log messages); returns the previous default."""
    global _default
    previous, _default = _default, progress
    return previous


def _mode(progress: bool | None) -> str:
    if progress is None:
        stack = _active.get()
        if stack:
            return stack[-1].mode
        progress = _default
    return _MODES[bool(progress) if progress is not None else None]


def _tqdm_class():
    try:
        from tqdm import tqdm
    except ImportError:
        return None
    return tqdm


def _is_terminal(stream) -> bool:
    try:
        return bool(stream.isatty())
    except (AttributeError, ValueError):
        return False


class Task:
    """One piece of reported work: ``with Task("deriving", progress=...) as t: ...``.

    ``total`` (with ``unit``) makes it counted: :meth:`update` sets how much is done.
    :meth:`note` attaches a short status (e.g. the residual of the last iteration).
    """

    def __init__(self, description: str, *, total: int | None = None, unit: str = "",
                 progress: bool | None = None):
        self.description = description
        self.total = total
        self.unit = unit
        if progress is not None:  # True or False (or 1, 0): a string such as "no" is refused
            progress = flag_argument(progress, "progress", owner=description)
        self.mode = _mode(progress)
        self.done = 0
        self.status_note = ""
        self.started = 0.0
        self.shown = False
        self._next_line = 0.0
        self._tqdm = None
        self._token: contextvars.Token | None = None
        self._closed = False

    # --- lifetime ---------------------------------------------------------------------------
    def start(self) -> Task:
        self.started = time.monotonic()
        if self.mode == "log" and not logger.isEnabledFor(logging.INFO):
            self.mode = "off"
        self._token = _active.set(_active.get() + (self,))
        if self.mode == "bar" and self.total is not None:
            tqdm = _tqdm_class()
            if tqdm is not None:
                self._tqdm = tqdm(total=self.total, desc=self.description, unit=self.unit or "it",
                                  delay=DELAY, file=sys.stderr, leave=False, unit_scale=True,
                                  dynamic_ncols=True)
                return self
        if self.mode != "off":
            _Ticker.register(self)
        return self

    def close(self, failed: bool = False) -> None:
        """End the task; work that was reported gets a last line with its duration."""
        if self._closed:
            return
        self._closed = True
        if self._token is not None:
            try:
                _active.reset(self._token)
            except ValueError:  # closed in another context: drop it from that one's stack
                _active.set(tuple(t for t in _active.get() if t is not self))
        if self._tqdm is not None:
            self._tqdm.close()
            return
        if self.mode != "off":
            _Ticker.unregister(self, failed)

    def __enter__(self) -> Task:
        return self.start()

    def __exit__(self, kind, value, traceback) -> None:
        self.close(failed=kind is not None)

    # --- updates ----------------------------------------------------------------------------
    def update(self, done: int) -> None:
        """Set the amount of counted work done so far."""
        if self._tqdm is not None:
            self._tqdm.update(max(0, done - self.done))
        self.done = done

    def note(self, text: str) -> None:
        """A short status shown after the bar (replacing the previous one)."""
        self.status_note = text
        if self._tqdm is not None:
            self._tqdm.set_postfix_str(text, refresh=False)

    # --- rendering --------------------------------------------------------------------------
    def elapsed(self, now: float | None = None) -> float:
        return (time.monotonic() if now is None else now) - self.started

    def line(self, now: float | None = None) -> str:
        """One line of status: description, bar or count, elapsed time, note."""
        elapsed = self.elapsed(now)
        parts = [self.description]
        if self.total:
            fraction = min(1.0, max(0.0, self.done / self.total))
            filled = int(round(fraction * BAR_WIDTH))
            parts.append(f"[{'#' * filled}{'.' * (BAR_WIDTH - filled)}] {fraction:4.0%} "
                         f"{self.done}/{self.total} {self.unit}".rstrip())
            if 0 < self.done < self.total:
                parts.append(f"{elapsed:.0f} s, about {elapsed * (self.total / self.done - 1):.0f}"
                             f" s left")
            else:
                parts.append(f"{elapsed:.0f} s")
        else:
            if self.done:
                parts.append(f"{self.done} {self.unit}".rstrip())
            parts.append(f"{elapsed:.0f} s")
        if self.status_note:
            parts.append(self.status_note)
        return " — ".join([parts[0], ", ".join(parts[1:])])

    def final_line(self, failed: bool) -> str:
        elapsed = self.elapsed()
        if failed:
            return f"{self.description}: stopped after {elapsed:.1f} s"
        count = f" ({self.done} {self.unit})".replace(" )", ")") if self.total is not None else ""
        note = f"; {self.status_note}" if self.status_note else ""
        return f"{self.description}: done{count} in {elapsed:.1f} s{note}"


class _Ticker:
    """The thread that reports registered tasks once they run longer than DELAY."""

    lock = threading.RLock()
    tasks: list[Task] = []
    thread: threading.Thread | None = None
    drawn = False  # a bar line is on the terminal without its newline
    last_text = ""

    @classmethod
    def register(cls, task: Task) -> None:
        with cls.lock:
            cls.tasks.append(task)
            if cls.thread is None or not cls.thread.is_alive():
                cls.thread = threading.Thread(target=cls._run, name="symgroupoid-progress",
                                              daemon=True)
                cls.thread.start()

    @classmethod
    def unregister(cls, task: Task, failed: bool) -> None:
        with cls.lock:
            if task in cls.tasks:
                cls.tasks.remove(task)
            if task.shown or task.elapsed() >= DELAY:
                cls._emit_final(task, failed)

    @classmethod
    def _run(cls) -> None:
        while True:
            time.sleep(REFRESH)
            with cls.lock:
                if not cls.tasks:
                    cls.thread = None
                    return
                cls._tick(time.monotonic())

    @classmethod
    def _tick(cls, now: float) -> None:
        bars = [t for t in cls.tasks if t.mode == "bar" and t.elapsed(now) >= DELAY]
        if bars:
            cls._draw(bars[-1], now)  # the innermost work draws
        for task in cls.tasks:
            if task.mode == "log" and task.elapsed(now) >= DELAY and now >= task._next_line:
                logger.info("%s", task.line(now))
                task.shown, task._next_line = True, now + LOG_INTERVAL

    @classmethod
    def _draw(cls, task: Task, now: float) -> None:
        stream = sys.stderr
        try:
            if _is_terminal(stream):
                width = shutil.get_terminal_size((80, 24)).columns - 1
                text = task.line(now)
                text = text if len(text) <= width else text[:max(0, width - 1)] + "…"
                if text != cls.last_text or not cls.drawn:
                    stream.write("\r" + text + "\x1b[K")
                cls.drawn, cls.last_text = True, text
            elif now >= task._next_line:
                stream.write(task.line(now) + "\n")
                task._next_line = now + LOG_INTERVAL
            stream.flush()
        except (OSError, ValueError):  # stderr closed or gone: stop drawing
            return
        task.shown = True

    @classmethod
    def _emit_final(cls, task: Task, failed: bool) -> None:
        text = task.final_line(failed)
        if task.mode == "log":
            logger.info("%s", text)
            return
        stream = sys.stderr
        try:
            if _is_terminal(stream):
                if cls.drawn:  # erase the bar: the work is over
                    stream.write("\r\x1b[K")
            else:
                stream.write(text + "\n")
            stream.flush()
        except (OSError, ValueError):
            pass
        cls.drawn = False


def current() -> Task | None:
    """The innermost reported work of this thread, if any."""
    stack = _active.get()
    return stack[-1] if stack else None


def note(text: str) -> None:
    """Attach a status to the innermost reported work (no-op outside any)."""
    task = current()
    if task is not None:
        task.note(text)


def reported(describe: Callable[..., str]) -> Callable:
    """Decorator: run the function as reported work described by ``describe(*args,
    **kwargs)``, adding the keyword argument ``progress`` (True, False or None, see the
    module docstring)."""

    def decorate(function: Callable) -> Callable:
        @functools.wraps(function)
        def wrapper(*args, progress: bool | None = None, **kwargs):
            try:
                description = describe(*args, **kwargs)
            except Exception:  # a malformed call: the function itself reports it
                description = function.__name__
            with Task(description, progress=progress):
                return function(*args, **kwargs)

        return wrapper

    return decorate
