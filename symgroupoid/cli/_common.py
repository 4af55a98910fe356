"""What the commands share: deriving a file's system and getting its stepper, with times."""

from __future__ import annotations

import re
import sys
import time
from dataclasses import dataclass

from ..runtime.toolchain import STATS
from ._system_file import SystemFile, load_system

BACKENDS = ("auto", "c", "numpy")


def say(text: str = "") -> None:
    """A line of the command's result (stdout)."""
    print(text, flush=True)


def warn(text: str) -> None:
    """A line of commentary (stderr), kept out of results a script reads."""
    print(text, file=sys.stderr, flush=True)


def file_stem(name: str) -> str:
    """A file-name-safe form of a system name."""
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", name).strip("._") or "system"


@dataclass
class Derived:
    """A system file's system and its step equations, with the derivation time."""

    source: SystemFile
    step: object
    seconds: float

    @property
    def system(self):
        return self.source.system


def derive(target: str) -> Derived:
    """Import ``FILE.py[:NAME]`` and derive its step equations."""
    source = load_system(target)
    t0 = time.perf_counter()
    step = source.system.euler_lagrange()
    return Derived(source, step, time.perf_counter() - t0)


@dataclass
class Stepper:
    """A simulator and how it was obtained: seconds, and whether a compiler ran."""

    sim: object
    seconds: float
    built: bool

    def describe(self) -> str:
        if self.sim.backend != "c":
            return f"NumPy backend, ready in {self.seconds:.2f} s"
        how = "compiled" if self.built else "loaded from the cache"
        return f"C kernel {how} in {self.seconds:.2f} s"


def stepper(derived: Derived, backend: str) -> Stepper:
    """The simulator of the derived step (C kernel from the cache, building it on a miss)."""
    builds = STATS["builds"]
    t0 = time.perf_counter()
    sim = derived.step.compile(backend=backend)
    return Stepper(sim, time.perf_counter() - t0, STATS["builds"] > builds)
