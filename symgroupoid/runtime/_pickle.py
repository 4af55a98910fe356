"""Pickling a compiled :class:`Simulator` as its generated C, flags and content hash.

A simulator sent to another process (a worker of a process pool or of a Dask cluster)
travels as a :class:`SimulatorRecipe`: plain data only — the kernel's C source, header and
cffi declarations, the compiler flags, the source key (a hash of all of them and the ABI) and
a digest of the C text, the Newton options, and what the runtime needs of the step besides
its kernel: its name, the names of the unknowns, knowns and parameters (with the assumptions
the parameters are declared with), and a snapshot of the state layout (named parts, with
each matrix part's group as its size and free entries).  No SymPy expression, no callable.

Unpickled, the recipe builds the kernel into the receiving process's own kernel cache, or
loads it from there (the cache is keyed by the hash of the C, the flags and the ABI), once per
process, and returns a :class:`Simulator` whose ``equations`` is a :class:`DetachedStep`.
It simulates, batches and names the parts of states exactly as the original; it checks
states (shape, finiteness, group membership of matrix parts) and parameters (names, values,
declared assumptions) as the original does, but not the constraints, which are symbolic:
check states on the side that has the step (sweeps do).  What needs the symbolic step
(``from_momentum``, LaTeX, …) raises :class:`DetachedStepError` there.

A NumPy-backend simulator evaluates the step's symbolic program and does not pickle
(:class:`NotPortableError`): compile with the C backend to send a simulator elsewhere.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass, field

import numpy as np
import sympy as sp

from .._errors import CacheError, SymgroupoidError
from ..codegen import KernelSource
from ..stepper import NO_TIME, TimeLayout
from ._layout import Part, StateLayout
from ._options import NewtonOptions


class NotPortableError(SymgroupoidError, TypeError):
    """The object cannot be sent to another process (a NumPy-backend simulator)."""


class DetachedStepError(SymgroupoidError, AttributeError):
    """A simulator restored from its kernel (unpickled) was asked for the symbolic step."""


def c_digest(kernel: KernelSource) -> str:
    """SHA-256 of the generated C (header, source, declarations): the content hash."""
    digest = hashlib.sha256()
    for part in (kernel.prefix, kernel.header_name, kernel.header, kernel.source, kernel.cdef):
        data = part.encode()
        digest.update(len(data).to_bytes(8, "little"))
        digest.update(data)
    return digest.hexdigest()


# --- plain stand-ins for the symbolic groupoid ------------------------------------------------

@dataclass(frozen=True)
class GroupSpec:
    """A matrix Lie group as the state checks need it: its size, whether affine (SE(n)), and
    the entries its arrow coordinates fill in the identity (``numeric_matrix``)."""

    name: str
    symbol_name: str
    n: int
    affine: bool
    _free: tuple

    @property
    def arrow_dim(self) -> int:
        return len(self._free)

    @property
    def free_entries(self) -> tuple:
        """The matrix positions the arrow coordinates hold (``MatrixLieGroup.free_entries``)."""
        return self._free

    def numeric_matrix(self, coords) -> np.ndarray:
        M = np.eye(self.n)
        for (i, j), c in zip(self._free, coords):
            M[i, j] = c
        return M

    @classmethod
    def of(cls, group) -> GroupSpec:
        free = tuple((int(i), int(j)) for i, j in group.free_entries)
        return cls(str(group.name), str(group.symbol_name), int(group.n), bool(group.affine),
                   free)


@dataclass(frozen=True)
class PlainGroupoid:
    """A groupoid as the state checks need it: name, arrow dimension and matrix parts."""

    name: str
    arrow_dim: int
    parts: tuple = ()
    offsets: tuple = ()

    def matrix_parts(self) -> list:
        return list(self.parts)

    def offset_parts(self) -> list:
        return list(self.offsets)


def plain_layout(layout: StateLayout) -> StateLayout:
    """A copy of ``layout`` whose groupoid and groups are plain data (picklable)."""
    groups: dict[int, GroupSpec] = {}

    def spec(group):
        if group is None:
            return None
        if isinstance(group, GroupSpec):
            return group
        return groups.setdefault(id(group), GroupSpec.of(group))

    G = layout.groupoid
    plain = G if isinstance(G, PlainGroupoid) else PlainGroupoid(
        str(G.name), int(G.arrow_dim), tuple((int(s), spec(g)) for s, g in G.matrix_parts()),
        tuple((int(s), spec(g)) for s, g in G.offset_parts()))
    out = StateLayout.__new__(StateLayout)
    out.__dict__.update(layout.__dict__)
    out.groupoid = plain
    out.equations = None  # symbolic: diagnostics need the step, which a recipe does not carry
    out.parts = {name: Part(p.name, p.offsets, p.index, p.fixed, spec(p.group))
                 for name, p in layout.parts.items()}
    out.names = list(layout.names)
    return out


# --- the step as the runtime needs it ---------------------------------------------------------

class DetachedStep:
    """The step of an unpickled simulator: names and sizes, no symbolic equations."""

    system = None  # no constraint check without the symbolic system

    def __init__(self, name: str, order: int, n_constraints: int, unknowns: list[str],
                 knowns: list[str], parameters: list[tuple[str, dict]],
                 domain_kinds: tuple = ()):
        self.name, self.order, self.n_constraints = name, order, n_constraints
        self.domain_kinds = list(domain_kinds)
        self.unknowns = [sp.Symbol(s) for s in unknowns]
        self.knowns = [sp.Symbol(s) for s in knowns]
        self.parameters = [sp.Symbol(s, **assumptions) for s, assumptions in parameters]

    def __getattr__(self, name: str):
        if name.startswith("__"):
            raise AttributeError(name)
        raise DetachedStepError(
            f"{self.name}: this simulator was restored from its compiled kernel (unpickled), "
            f"without the symbolic step, so {name!r} is not available here; use the "
            f"simulator where the step was derived")

    def __len__(self) -> int:
        return len(self.unknowns)

    def __repr__(self) -> str:
        return f"<DetachedStep {self.name!r}: {len(self.unknowns)} unknowns>"


def _declared_assumptions(symbol) -> dict:
    given = getattr(symbol, "_assumptions_orig", None)
    if given is None:
        given = getattr(symbol, "assumptions0", {})
    return {str(k): bool(v) for k, v in sorted(given.items()) if v is not None}


@dataclass
class SimulatorRecipe:
    """Everything a process needs to rebuild a compiled simulator (plain data)."""

    name: str
    order: int
    n_constraints: int
    unknowns: list
    knowns: list
    parameters: list  # (name, declared assumptions)
    kernel: KernelSource
    flags: tuple
    source_key: str
    digest: str
    options: NewtonOptions
    layout: StateLayout
    extra: dict = field(default_factory=dict)
    time: TimeLayout = NO_TIME  # the step's time indices (its branch check's messages)
    #: what each value of the kernel's ``domain`` needs (its domain check's messages)
    domain_kinds: tuple = ()


def recipe_of(sim) -> SimulatorRecipe:
    """The recipe of a compiled simulator (its kernel source is regenerated from the step
    when this process did not build it; the result is kept on the simulator)."""
    from .toolchain import kernel_source_of

    if sim.backend != "c":
        raise NotPortableError(
            f"{sim.name}: a NumPy-backend simulator cannot be pickled (its kernel is the "
            f"symbolic step program); compile the step with backend='c' to send it to "
            f"another process")
    recipe = getattr(sim, "_recipe", None)
    if recipe is not None:
        if recipe.options != sim.options:
            recipe = SimulatorRecipe(**{**recipe.__dict__, "options": sim.options})
        return recipe
    step = sim.equations
    source = kernel_source_of(sim.kernel, step)
    recipe = SimulatorRecipe(
        name=sim.name, order=int(getattr(step, "order", 1)),
        n_constraints=int(step.n_constraints),
        unknowns=[str(s) for s in step.unknowns], knowns=[str(s) for s in step.knowns],
        parameters=[(str(s), _declared_assumptions(s)) for s in step.parameters],
        kernel=source, flags=tuple(sim.kernel.flags), source_key=sim.kernel.source_key,
        digest=c_digest(source), options=sim.options, layout=plain_layout(sim.layout),
        time=sim.time, domain_kinds=tuple(step.domain_kinds))
    sim._recipe = recipe
    return recipe


def restore_simulator(recipe: SimulatorRecipe):
    """A simulator from its recipe: the kernel built into this process's cache, or loaded."""
    from ._compile import load_kernel_source
    from ._simulator import Simulator

    if c_digest(recipe.kernel) != recipe.digest:
        raise CacheError(f"{recipe.name}: the kernel source received does not match its "
                         f"content hash {recipe.digest[:16]}…; it was damaged in transit")
    kernel, entry = load_kernel_source(recipe.kernel, recipe.flags, recipe.name,
                                       len(recipe.unknowns), len(recipe.knowns))
    step = DetachedStep(recipe.name, recipe.order, recipe.n_constraints, recipe.unknowns,
                        recipe.knowns, recipe.parameters,
                        getattr(recipe, "domain_kinds", ()))
    sim = Simulator.__new__(Simulator)
    sim.equations = step
    sim.kernel = kernel
    sim.options = recipe.options
    sim.cache_entry = entry
    sim.layout = recipe.layout
    sim.time = recipe.time
    sim.parameter_names = [name for name, _ in recipe.parameters]
    sim._momentum = _NoMomentum(step)
    sim._recipe = recipe
    return sim


class _NoMomentum:
    """``from_momentum`` of a restored simulator: the Legendre transform is symbolic."""

    def __init__(self, step: DetachedStep):
        self.step = step

    def solve(self, *args, **kwargs):
        return self.step.legendre_transform  # raises DetachedStepError
