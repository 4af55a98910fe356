"""From a step's :class:`~symgroupoid.ir.Program` to straight-line C: the kernel bodies.

Each kernel function (residual, residual + Jacobian, chart, prediction, state update) is a
*block*: the named nodes of the program that its outputs need, in node order, as
``const double`` locals, then the stores to the output arrays.  The residual and its exact
Jacobian come from one graph, so they share every common subexpression by construction
(no ``cse`` pass is needed), and the fibre chart τ(x) is computed once.

A block with more than :data:`PART_SIZE` statements is split into parts — static functions
run in order, each of bounded size — so that the C compiler's time stays near-linear in the
size of the kernel; values one part computes and a later part reads live in a work array.
"""

from __future__ import annotations

import hashlib
import re
from collections.abc import Sequence
from dataclasses import dataclass, field

from .._arguments import names_argument
from ..ir import C, functions_used, plan, write
from ._band import band_order
from ._checks import program_argument

_C_KEYWORDS = frozenset(
    "auto break case char const continue default do double else enum extern float for goto "
    "if inline int long register restrict return short signed sizeof static struct switch "
    "typedef union unsigned void volatile while _Bool _Complex _Imaginary".split())

#: the translation unit number of the kernel's cold unit (``<prefix>_cold.c``, the code that
#: runs rarely: the batched entry point, the status messages, the residual's scale)
COLD_UNIT = -1

#: statements per function (part) of a split kernel: small functions keep the C compiler's
#: time linear in the kernel's size, and run faster too (measured: the planar 32-link chain's
#: step at -O2 takes 3.16e5 instructions with parts of 500 statements, 3.68e5 with 2000)
PART_SIZE = 500


#: the longest prefix of C identifiers a kernel gets: its files are named after it
#: (``<prefix>_stepper.c``, ``<prefix>_blocks_1.c``), and a file name has at most 255 bytes
MAX_PREFIX = 64


def c_identifier(name: str) -> str:
    """A safe C identifier prefix from a system name.

    Lower-cased; every run of characters outside ``[A-Za-z0-9_]`` becomes ``_``; a leading
    digit, an empty result or a C keyword gets the prefix ``sg_``.  A result longer than
    :data:`MAX_PREFIX` keeps its first 55 characters and ends with 8 hexadecimal digits of
    the SHA-256 of the whole name (two long names that differ only after the 55th character
    get different prefixes).
    """
    ident = re.sub(r"[^A-Za-z0-9_]+", "_", name.strip()).strip("_").lower()
    if not ident or ident[0].isdigit() or ident in _C_KEYWORDS:
        ident = f"sg_{ident}".rstrip("_") if ident else "sg_system"
    if len(ident) > MAX_PREFIX:
        digest = hashlib.sha256(name.encode("utf-8", "surrogatepass")).hexdigest()[:8]
        ident = f"{ident[:MAX_PREFIX - 9].rstrip('_')}_{digest}"
    return ident


@dataclass
class Part:
    """Straight-line C for one function: local definitions then output stores."""

    locals: list[str] = field(default_factory=list)  # "const double t3 = …;" / "w[2] = …;"
    stores: list[str] = field(default_factory=list)  # "F[0] = …;"
    unit: int = 0  # the translation unit defining it (0: the kernel's source)

    @property
    def statements(self) -> int:
        return len(self.locals) + len(self.stores)


@dataclass
class Block:
    """A kernel function body: one part, or several run in order with a work array.

    ``borrowed``: how many leading parts are the part functions of another block (the
    residual's, which the residual-and-Jacobian block calls instead of compiling them
    again)."""

    parts: list[Part] = field(default_factory=list)
    work: int = 0  # doubles in the work array shared by the parts (0: not split)
    borrowed: int = 0
    home: int = 0  # the unit of a split block's function (which only calls its parts)

    @property
    def split(self) -> bool:
        return len(self.parts) > 1 or self.work > 0

    @property
    def locals(self) -> list[str]:
        return self.parts[0].locals if not self.split else []

    @property
    def stores(self) -> list[str]:
        return self.parts[0].stores if not self.split else []

    @property
    def statements(self) -> int:
        return sum(p.statements for p in self.parts)

    @property
    def unit(self) -> int:
        """The translation unit defining the function of a block: its part's for a block
        in one part; ``home`` for a split block's function, which only calls its parts (the
        kernel's source, unless the whole block was moved to the cold unit)."""
        return self.parts[0].unit if not self.split else self.home

    def move_to(self, unit: int) -> None:
        """Place the whole block (function and parts) in translation unit ``unit``."""
        for part in self.parts:
            part.unit = unit
        self.home = unit

    def units(self) -> set[int]:
        """The translation units defining some of this block's code."""
        return {p.unit for p in self.parts[self.borrowed:]}


def _input_names(program, input_names: dict | None) -> dict:
    """C names of the program's input nodes: ``array[i]``."""
    rename = input_names or {}
    return {n: f"{rename.get(array, array)}[{i}]"
            for n, (array, i) in program.input_positions().items()}


def _chunks(nodes: Sequence[int], part_size: int) -> list[list[int]]:
    return [list(nodes[i:i + part_size]) for i in range(0, len(nodes), part_size)] or [[]]


def _targets(program, outputs: Sequence[tuple[str, str]]) -> list[tuple[str, int]]:
    """(C lvalue, node) of every entry of the named outputs, e.g. ``("F[0]", 17)``."""
    return [(f"{array}[{i}]", n) for array, name in outputs
            for i, n in enumerate(program.outputs[name])]


def _parts(g, p, chunks: list[list[int]], stores: Sequence[tuple[str, int, int, int]],
           names: dict) -> tuple[list[Part], int]:
    """The parts computing ``chunks`` (runs of the named nodes of plan ``p``) and the output
    ``stores`` (lvalue, node, first part, last part): each store in the part computing its
    node, kept within its range (a leaf's store: the last part of its range).  A value read
    by another part than the one computing it lives in the work array; returns the parts and
    the size of that array.  ``names`` (the inputs' C names) receives the named nodes'."""
    part_of = {n: k for k, chunk in enumerate(chunks) for n in chunk}
    placed = [(t, n, min(max(part_of.get(n, hi), lo), hi)) for t, n, lo, hi in stores]
    shared: dict = {}
    for k, chunk in enumerate(chunks):
        for n in chunk:
            for r in sorted(p.refs[n]):
                if part_of[r] != k and r not in shared:
                    shared[r] = len(shared)
    for _, n, k in placed:
        if n in part_of and part_of[n] != k and n not in shared:
            shared[n] = len(shared)
    local = iter(range(len(p.named)))
    for n in p.named:
        names[n] = f"w[{shared[n]}]" if n in shared else f"t{next(local)}"
    stores_at: dict = {}
    for t, n, k in placed:
        stores_at.setdefault(k, []).append((t, n))
    parts, writer = [], None
    for k, chunk in enumerate(chunks):
        statements, writer = write(g, p, chunk, names, C, writer)
        part = Part()
        for (name, text), n in zip(statements, chunk):
            decl = "" if n in shared else "const double "
            part.locals.append(f"{decl}{name} = {text};")
        part.stores = [f"{t} = {writer.atom(n)[0]};" for t, n in stores_at.get(k, [])]
        parts.append(part)
    return parts, len(shared)


def build_block(program, outputs: Sequence[tuple[str, str]], part_size: int | None = None,
                input_names: dict | None = None) -> Block:
    """The C of ``program``'s named outputs stored into C arrays.

    ``outputs``: (C array name, program output name) pairs, e.g. ``("F", "F")``;
    ``input_names``: C array names of the program's input arrays (default: their own names).
    """
    return _targets_block(program, _targets(program, outputs), part_size, input_names)


def _targets_block(program, targets: list[tuple[str, int]], part_size: int | None = None,
                   input_names: dict | None = None, given: dict | None = None) -> Block:
    """:func:`build_block` of the stores ``targets`` ((C lvalue, node) pairs); ``given``:
    operation nodes computed elsewhere, read by their C names (:func:`hoisted_values`)."""
    g = program.graph
    given = given or {}
    p = plan(g, [n for _, n in targets], given=given)
    chunks = _chunks(p.named, PART_SIZE if part_size is None else part_size)
    last = len(chunks) - 1
    parts, work = _parts(g, p, chunks, [(t, n, 0, last) for t, n in targets],
                         {**_input_names(program, input_names), **given})
    return Block(parts=parts, work=work if len(chunks) > 1 else 0)


def hoisted_values(program, names: Sequence[str] = ("F", "J"), over: str = "u") -> list[int]:
    """The values a Newton step computes once: the operation nodes of the outputs ``names``
    that depend on no entry of the input array ``over`` (the unknowns) and that a node
    depending on it reads, or that are outputs themselves (ascending node ids).

    Newton evaluates F (and once J) at several iterates of the same step, whose known arrow
    and parameters do not change: the terms of the known arrow alone -- X⃖L(g_k) and
    f⁺(g_k) in the DEL residual (docs/conventions.md §4, §20), the known factors of
    products with the new arrow -- are computed once per step by ``<prefix>_hoist`` and
    read by the residual.  The same operations on the same values: the same bits."""
    names = names_argument(names, "names", owner="hoisted_values")
    program_argument(program, "hoisted_values", outputs=names, inputs=[over])
    g = program.graph
    nodes = program.nodes(list(names))
    unknowns = [g.inputs[s] for s in program.inputs[over] if s in g.inputs]
    moving = g.dependents(unknowns, nodes)
    outputs = {n for name in names for n in program.outputs[name]}
    frontier: set = set()
    for n in nodes:
        if n in moving:
            frontier.update(a for a in g.args[n] if a not in moving and g.args[a])
        elif n in outputs and g.args[n]:
            frontier.add(n)
    return sorted(frontier)


def band_targets(program, band) -> list[tuple[str, int]]:
    """(C lvalue, node) of the Jacobian in the band form of ``band`` (a
    :class:`~symgroupoid.stepper.BandOrder`): entry (i, j) of the reordered Jacobian
    B = J[order[i]][order[j]], −kl ≤ j − i ≤ ku, at ``J[i·(kl + ku + 1) + j − i + kl]``
    (the stepper's ``SG_JACOBIAN_AT``); the entries outside the band are structurally zero
    and not stored."""
    n, order, width = len(band.order), band.order, band.kl + band.ku + 1
    nodes = program.outputs["J"]
    return [(f"J[{i * width + j - i + band.kl}]", nodes[order[i] * n + order[j]])
            for i in range(n) for j in range(max(0, i - band.kl), min(n, i + band.ku + 1))]


def residual_blocks(program, part_size: int | None = None,
                    band=None, given: dict | None = None) -> tuple[Block, Block]:
    """The residual block and the residual-and-Jacobian block of a step's program (the
    Jacobian in the band form of ``band``, when given: :func:`band_targets`).

    When F and J together need more than one part, one plan computes both: first the parts
    of the nodes F needs, which store F, then the Jacobian's, which read the residual's
    values from the work array.  The residual function is the first parts alone, and the
    residual-and-Jacobian function calls them before its own (``Block.borrowed``): the
    residual's code is compiled once, not twice (the same values: the same operations).
    Smaller kernels get a block each, in one function without a work array.
    ``given``: nodes computed elsewhere, read by their C names (:func:`hoisted_values`).
    """
    part_size = PART_SIZE if part_size is None else part_size
    g = program.graph
    given = given or {}
    f_targets = _targets(program, [("F", "F")])
    j_targets = (_targets(program, [("J", "J")]) if band is None
                 else band_targets(program, band))
    p = plan(g, [n for _, n in f_targets + j_targets], given=given)
    if len(p.named) + len(f_targets) + len(j_targets) <= part_size:
        return (_targets_block(program, f_targets, part_size, given=given),
                _targets_block(program, f_targets + j_targets, given=given))
    in_f = dict.fromkeys(g.reachable([n for _, n in f_targets], stop=given))
    f_chunks = _chunks([n for n in p.named if n in in_f], part_size)
    j_chunks = _chunks([n for n in p.named if n not in in_f], part_size)
    k, last = len(f_chunks), len(f_chunks) + len(j_chunks) - 1
    stores = [(t, n, 0, k - 1) for t, n in f_targets] + [(t, n, k, last) for t, n in j_targets]
    parts, work = _parts(g, p, f_chunks + j_chunks, stores,
                         {**_input_names(program, None), **given})
    work = max(work, 1)
    return Block(parts=parts[:k], work=work), Block(parts=parts, work=work, borrowed=k)


@dataclass
class KernelBlocks:
    """The bodies of the generated kernel functions, plus sizes and helper functions."""

    reconstruct: Block
    hoist: Block  # the values of the known arrow that F and J read (hoisted_values)
    n_hoisted: int
    residual: Block
    residual_jacobian: Block
    residual_scale: Block
    predict: Block
    next_knowns: Block
    n_fibre: int
    #: the values of the window's terms defined on part of the real line only (docs/
    #: conventions.md §11): a step's solution is accepted where they are all finite
    domain: Block
    n_domain: int
    helpers: list[str] = field(default_factory=list)  # C helper functions (smooth maps)
    #: ∂F/∂(u_k, u_{k+1}) of a step with inputs (docs/conventions.md §20); None without
    input_jacobian: Block | None = None
    input_jacobian_helpers: list[str] = field(default_factory=list)  # the helpers it calls


#: the Newton stepper's loops are unrolled completely up to this many unknowns (the
#: ``SG_UNROLL`` macro of symgroupoid/stepper/stepper.c)
UNROLLED_UNKNOWNS = 8


def stepper_statements(n_unknowns: int) -> int:
    """The C compiler's time on a kernel's hot fixed code (Newton stepper, LU, simulate; not
    the batched entry point, see ``symgroupoid/stepper/batch.c``) for ``n_unknowns`` unknowns, in
    statements of the straight-line blocks that take it as long to compile.

    Measured at -O3 (gcc 12, CPU seconds): the straight-line blocks take 0.3 to 0.5 ms a
    statement (planar 8- and 16-link chains, 3D chains of 2 to 8 bodies), the Jacobian's
    more than the others' (the planar 16-link chain's: 0.8 ms); the stepper unrolled
    completely (n ≤ :data:`UNROLLED_UNKNOWNS`) takes 0.144, 0.172, 0.201, 0.266, 0.38 s at
    n = 2, 3, 4, 6, 8 (320 + 10 n² statements at 0.4 ms: within 5 %), rolled 0.29, 0.33,
    0.35, 0.25, 0.24 s at n = 9, 12, 16, 18, 24 (500 statements: as much of the large
    kernels' Jacobians).
    """
    if n_unknowns <= UNROLLED_UNKNOWNS:
        return 320 + 10 * n_unknowns * n_unknowns
    return 500


#: a kernel of more than 6 and at most :data:`UNROLLED_UNKNOWNS` unknowns whose blocks hold
#: fewer statements keeps them in the stepper's translation unit.  Measured on the
#: plate-ball (8 unknowns, 379 statements): 0.27 µs a step with its functions beside the
#: stepper, 0.34 µs with them in a unit of their own -- the same machine code for every
#: function, placed differently around the 14 kB of the unrolled LU factorisation -- while
#: the planar chains of 2, 4 and 8 links and the 3D chains of 1, 2 and 3 bodies (2 to 9
#: unknowns) step as fast either way (within 2 %).
UNIT_MIN_STATEMENTS = 600
#: the smallest number of unknowns whose small blocks stay beside the stepper (above)
CLOSE_UNKNOWNS = 7
#: the part size of a kernel spread over translation units (:func:`unit_part_size`)
UNIT_PART_SIZE = 200


def unit_part_size(n_unknowns: int, units: int) -> int:
    """The part size of the blocks of a kernel of ``n_unknowns`` unknowns in at most
    ``units`` translation units: :data:`UNIT_PART_SIZE` when it is spread over several,
    except one of :data:`CLOSE_UNKNOWNS` to :data:`UNROLLED_UNKNOWNS` unknowns (which may
    stay in one unit, :func:`assign_units`), else :data:`PART_SIZE`.

    Smaller parts take the C compiler less time (its register allocation grows faster than
    a function's length), and the residual-and-Jacobian function of a kernel of more than
    one part calls the residual's parts instead of computing the residual again
    (:func:`residual_blocks`).  Measured (CPU ms of all units at the default flags, parts
    of 500 -> 200 statements, two runs each; µs per step): 3D chain of 2 bodies 380 -> 309
    and 384 -> 322, 0.68 -> 0.61 and 0.65; of 4 bodies 480 -> 463 and 490 -> 461, 2.3 ->
    2.1 and 2.0; of 8 bodies 958 -> 794 and 986 -> 778, 7.6 -> 7.3 and 7.1 -> 7.2; planar
    chain of 6 links 302 -> 280 and 305 -> 292, 1.7 -> 1.5 and 1.8 -> 1.5; of 16 links
    691 -> 589 and 709 -> 572, 8.0 -> 7.9 and 7.8 -> 7.7.
    """
    if units > 1 and not CLOSE_UNKNOWNS <= n_unknowns <= UNROLLED_UNKNOWNS:
        return UNIT_PART_SIZE
    return PART_SIZE


def assign_units(blocks: Sequence[Block], units: int, n_unknowns: int,
                 block_weight: float = 1.0) -> int:
    """Distribute the code of ``blocks`` over at most ``units`` translation units so that
    each takes the C compiler about as long (deterministic); the number of units used.

    Unit 0, the kernel's source, holds the hot fixed code (:func:`stepper_statements`
    of ``n_unknowns``), which for small kernels takes the compiler longer than all the
    blocks: they then go to unit 1 and both compile at the same time (planar 2-link chain:
    0.27 s in one unit; 0.14 s for the stepper beside 0.06 s for the blocks).  A statement
    in a unit other than 0 (a block unit) costs ``block_weight`` times one in unit 0 (block
    units may be compiled at a cheaper level, ``runtime.toolchain.unit_flags``).  Blocks of
    fewer than :data:`UNIT_MIN_STATEMENTS` statements of a kernel of
    :data:`CLOSE_UNKNOWNS` to :data:`UNROLLED_UNKNOWNS` unknowns stay in unit 0 (see there).
    The items moved are whole functions of one part and the parts of split functions
    (empty ones stay).  Items are placed largest first on the unit where they would finish
    first (ties: the lower unit, then the earlier item), and the units are then numbered
    in order of their first item (unit 0 first).
    """
    items = list({id(part): part for block in blocks for part in block.parts}.values())
    for part in items:
        part.unit = 0
    total = sum(part.statements for part in items)
    close = CLOSE_UNKNOWNS <= n_unknowns <= UNROLLED_UNKNOWNS and total < UNIT_MIN_STATEMENTS
    if units <= 1 or close:
        return 1
    weights = [1.0] + [block_weight] * (units - 1)
    loads = [float(stepper_statements(n_unknowns))] + [0.0] * (units - 1)
    order = sorted((i for i in range(len(items)) if items[i].statements),
                   key=lambda i: (-items[i].statements, i))
    for i in order:
        size = items[i].statements
        unit = min(range(units), key=lambda u: (loads[u] + weights[u] * size, u))
        items[i].unit = unit
        loads[unit] += weights[unit] * size
    first: dict[int, int] = {0: -1}
    for i, part in enumerate(items):
        first.setdefault(part.unit, i)
    number = {u: k for k, u in enumerate(sorted(first, key=first.get))}
    for part in items:
        part.unit = number[part.unit]
    return len(number)


def program_functions(program, outputs: Sequence[str]) -> list:
    """The function specs the named outputs need, in first-use order."""
    return functions_used(program.graph, [n for name in outputs for n in program.outputs[name]])


def program_helpers(program, outputs: Sequence[str]) -> list[str]:
    """The C helper functions (smooth special functions) the named outputs need."""
    helpers: dict = {}
    for spec in program_functions(program, outputs):
        helpers.update(spec.c_helpers())
    return list(helpers.values())


def kernel_blocks(step, part_size: int | None = None) -> KernelBlocks:
    """All function bodies of the kernel of ``step`` (deterministic for equal input), in
    parts of at most ``part_size`` statements (default :data:`PART_SIZE`)."""
    program = step.program
    hoisted = hoisted_values(program)
    given = {n: f"h[{i}]" for i, n in enumerate(hoisted)}
    residual, residual_jacobian = residual_blocks(program, part_size, band_order(step), given)
    helpers = program_helpers(program, list(program.outputs))
    input_jacobian, input_helpers = None, []
    if getattr(step, "inputs", ()):
        inputs = input_jacobian_program(step)
        input_jacobian = build_block(inputs, [("J_inputs", "J_inputs")], part_size)
        input_helpers = program_helpers(inputs, ["J_inputs"])
        helpers = list(dict.fromkeys(helpers + input_helpers))
    return KernelBlocks(
        reconstruct=build_block(program, [("fibre", "fibre")], part_size),
        hoist=_targets_block(program, [(name, n) for n, name in given.items()], part_size),
        n_hoisted=len(hoisted),
        residual=residual,
        residual_jacobian=residual_jacobian,
        residual_scale=build_block(program, [("S", "F_scale")], part_size),
        predict=build_block(program, [("u", "predict")], part_size),
        next_knowns=build_block(program, [("known_next", "next_knowns")], part_size),
        n_fibre=len(program.outputs["fibre"]),
        domain=build_block(program, [("D", "domain")], part_size),
        n_domain=len(program.outputs.get("domain", ())),
        helpers=helpers, input_jacobian=input_jacobian, input_jacobian_helpers=input_helpers,
    )


def input_jacobian_program(step):
    """The program of ∂F/∂(u_k, u_{k+1}) of a step with inputs, the one
    :meth:`StepEquations.input_jacobian` evaluates (the same graph, the same operations: the
    C and NumPy forms give the same bits, docs/conventions.md §17)."""
    from ..equations import input_jacobian_program as program_of

    return program_of(step)


__all__ = ["Block", "KernelBlocks", "PART_SIZE", "Part", "assign_units", "band_targets",
           "build_block", "c_identifier", "hoisted_values", "kernel_blocks",
           "program_functions", "program_helpers", "residual_blocks", "stepper_statements",
           "unit_part_size"]
