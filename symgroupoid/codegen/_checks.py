"""The code generator's checks of its arguments: what every public entry point of
:mod:`symgroupoid.codegen` receives is a step's equations or a program (named inputs and
outputs over the expression graph, the only thing that passes from the symbolic side to an
evaluator), and the names it asks of a program are the program's; anything else is refused
with a named :class:`~symgroupoid.SymgroupoidError` before any work."""

from __future__ import annotations

from collections.abc import Sequence

from .._arguments import instance_argument, shown_value
from .._errors import DomainError
from ..ir import Program


def step_argument(step, owner: str):
    """``step`` if it is a :class:`~symgroupoid.StepEquations`, else an
    :class:`~symgroupoid.InputTypeError` naming ``step`` and ``owner``."""
    from ..equations import StepEquations

    return instance_argument(step, StepEquations, "step", "the StepEquations of a system "
                             "(from system.euler_lagrange())", owner=owner)


def program_argument(program, owner: str, *, outputs: Sequence = (),
                     inputs: Sequence = ()) -> Program:
    """``program`` if it is a :class:`~symgroupoid.ir.Program` with the outputs and input
    arrays named, else an :class:`~symgroupoid.InputTypeError` (not a program) or a
    :class:`~symgroupoid.DomainError` naming the missing name and the ones it has."""
    instance_argument(program, Program, "program", "a symgroupoid.ir.Program", owner=owner)
    for kind, names, held in (("output", outputs, program.outputs),
                              ("input array", inputs, program.inputs)):
        for name in names:
            if not isinstance(name, str) or name not in held:
                raise DomainError(f"{owner}: the program has no {kind} {shown_value(name)} "
                                  f"(it has {', '.join(map(repr, held))})")
    return program


__all__ = ["program_argument", "step_argument"]
