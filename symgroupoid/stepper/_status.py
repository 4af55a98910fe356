"""The statuses of every run the library makes: one enum, with its messages.

A Newton step (the C library beside this module and its NumPy twin), a run of steps, a
batch, a boundary-value solve and a sweep all report how they ended by one of these codes
(``batch.status``, ``SweepResult.status``, the C functions' return values).  The codes of
:attr:`Status.kernel` statuses are those the C library returns (its ``SG_OK`` …
``SG_BRANCH_JUMP`` in ``stepper.h`` and the texts of ``SG_NAME(status_message)`` in
``batch.c``, which a test checks against this enum: :func:`c_defines`,
:func:`c_status_message`); the others are given by the runtime to runs that a step did not
end (a boundary-value path at the cut locus of its chart, a run stopped from outside).
"""

from __future__ import annotations

import enum


class Status(enum.IntEnum):
    """How a run ended: 0 completed, else the reason it stopped (``Status(code).message``).

    Kernel statuses (returned by the C library and its NumPy twin; docs/conventions.md §11
    tells the failures apart): ``OK``, ``SINGULAR_JACOBIAN``, ``NOT_CONVERGED`` (the iteration
    cap), ``NON_FINITE``, ``INVALID_ARGUMENT``, ``STALLED`` (an update at the rounding noise
    of the solve, the residual above every floor), ``BRANCH_JUMP`` (a solution outside the
    trust region of its guess), ``OUTSIDE_DOMAIN`` (a solution where the discrete Lagrangian
    is not defined, docs/conventions.md §11).  Given by the runtime: ``CUT_LOCUS`` (a
    boundary-value path met the cut locus of its chart), and for runs stopped from outside,
    ``INTERRUPTED`` (Ctrl-C), ``TIMED_OUT`` (a sweep's ``timeout``) and ``WORKER_DIED`` (a
    sweep's worker process died).  A boundary-value run reports ``SINGULAR_JACOBIAN``,
    ``CUT_LOCUS``, ``OUTSIDE_DOMAIN`` or ``NOT_CONVERGED`` (any other way its iteration
    ended without a solution: :meth:`of_boundary_value_error`).
    """

    message: str

    def __new__(cls, code: int, message: str) -> Status:
        member = int.__new__(cls, code)
        member._value_ = code
        member.message = message
        return member

    OK = 0, "converged"
    SINGULAR_JACOBIAN = 1, (
        "singular Jacobian: a pivot vanished relative to its equation at Newton's iterate, so "
        "the step equations do not determine the next state there (the discrete Lagrangian "
        "is not regular there, or the step is too large for a root near the guess: a "
        "rotation per step near a half-turn, a step beyond the equations' reach)")
    NOT_CONVERGED = 2, (
        "Newton's method reached its iteration cap (the max_iterations option: that many "
        "updates) without converging")
    NON_FINITE = 3, (
        "non-finite value (overflow to infinity, or NaN) in the residual, the Jacobian, the "
        "Newton step or the next state")
    INVALID_ARGUMENT = 4, (
        "invalid argument (null buffer, negative step count, capacity below n_steps + 1, bad "
        "option or warm start, or non-finite input)")
    STALLED = 5, (
        "Newton's method stalled: its update is at the rounding noise of the solve while the "
        "residual stays above its rounding floor")
    BRANCH_JUMP = 6, (
        "branch jump: the step's solution lies far outside the region the last steps predict, "
        "or on a time groupoid its time step reverses or changes by more than a factor 2 "
        "(the nearby root of the step equations has disappeared: reduce the step; or the "
        "motion itself runs away faster than its last steps, as a solution that blows up "
        "does)")
    OUTSIDE_DOMAIN = 8, (
        "outside the domain: Newton solved the step equations, but the discrete Lagrangian "
        "is not defined at the solution (a logarithm, square root, acos, ... of it is not "
        "finite there)")
    CUT_LOCUS = 7, (
        "the boundary-value path met the cut locus of its chart (a half-turn, where the chart "
        "and the equations are not defined)")
    INTERRUPTED = 10, "interrupted (Ctrl-C)"
    TIMED_OUT = 11, "its task exceeded the sweep's timeout"
    WORKER_DIED = 12, "its worker process died while running it"

    @classmethod
    def _missing_(cls, value) -> Status:
        """A :class:`~symgroupoid.StatusCodeError` naming the codes there are."""
        from .._errors import StatusCodeError

        codes = ", ".join(f"{int(s)} {s.name}" for s in cls)
        raise StatusCodeError(f"{value!r} is not the code of a run's status; the codes are "
                              f"{codes}")

    @property
    def kernel(self) -> bool:
        """Whether the C library (and its NumPy twin) returns this status."""
        return self <= Status.BRANCH_JUMP or self is Status.OUTSIDE_DOMAIN

    @property
    def stopped(self) -> bool:
        """Whether this is the status of a run stopped from outside (not a failure of
        its own)."""
        return self >= Status.INTERRUPTED

    @classmethod
    def of_boundary_value_error(cls, error: BaseException) -> Status:
        """The status of a boundary-value run that raised ``error``: ``SINGULAR_JACOBIAN``,
        ``CUT_LOCUS`` or ``OUTSIDE_DOMAIN`` for those errors, else ``NOT_CONVERGED`` (the
        iteration cap, a stalled update, no decrease of the merit function, a non-finite
        residual)."""
        from .._errors import CutLocusError, LagrangianDomainError, SingularJacobianError

        if isinstance(error, LagrangianDomainError):
            return cls.OUTSIDE_DOMAIN
        if isinstance(error, SingularJacobianError):
            return cls.SINGULAR_JACOBIAN
        if isinstance(error, CutLocusError):
            return cls.CUT_LOCUS
        return cls.NOT_CONVERGED


#: the texts of the kernel statuses, by code (the C ``<prefix>_status_message``'s)
STATUS_MESSAGES: dict[int, str] = {int(s): s.message for s in Status if s.kernel}


def _c_string(text: str) -> str:
    return '"' + text.replace("\\", "\\\\").replace('"', '\\"') + '"'


def c_defines() -> str:
    """The ``#define SG_<NAME> <code>`` lines of the kernel statuses (``stepper.h``)."""
    return "".join(f"#define SG_{s.name} {int(s)}\n" for s in Status if s.kernel)


def c_status_message() -> str:
    """The C function ``SG_NAME(status_message)`` of the kernel statuses (``batch.c``)."""
    cases = "".join(f"    case SG_{s.name}:\n        return {_c_string(s.message)};\n"
                    for s in Status if s.kernel)
    return ("const char *SG_NAME(status_message)(int status)\n{\n    switch (status) {\n"
            f"{cases}    default:\n        return \"unknown status\";\n    }}\n}}\n")


__all__ = ["STATUS_MESSAGES", "Status", "c_defines", "c_status_message"]
