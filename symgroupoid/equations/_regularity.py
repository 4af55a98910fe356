"""Derivation-time diagnosis of step equations that cannot determine a step.

A step F(u; k, p) = 0 determines its unknowns u (chart coordinates of the newest arrow, then
the multipliers λ_{k+1}) near a solution exactly when the step Jacobian ∂F/∂u is invertible.
For a first-order constrained system (seed 000 §3.3; docs/conventions.md §4) it has the blocks

    ∂F/∂u = [ A  B ]    A = ∂(DEL)/∂x,   B = ∂(DEL)/∂λ_{k+1} = −X⃗[φ](g_{k+1}),
            [ C  0 ]    C = ∂φ(g_{k+1})/∂x,

and regularity of L (seed 000 Thm 2.16: F⁻L, F⁺L local diffeomorphisms) is its invertibility.
:func:`diagnose` finds, before any step is taken,

- residuals that are identically zero (a null Lagrangian: constant, zero, or a difference
  f(β(g)) − f(α(g)); a constraint that is identically zero), structurally or numerically;
- residuals that involve no unknown, and unknowns that enter no residual (a multiplier whose
  constraint depends only on the target of the arrow, so that X⃗[φ] = 0);
- a Jacobian singular at every one of several random admissible points, classified as
  dependent constraints (rows of C), undetermined multipliers (columns of B), or else a
  Lagrangian that is not regular, naming the rows and columns of the null spaces.

The residuals are analytic in the unknowns, the knowns and the parameters, so a determinant
that vanishes at several random points of an open set vanishes identically; a regular point
anywhere clears the system.  Points where the residuals are not finite are not evidence and
are replaced by others.  The points come from a fixed seed, so the diagnosis is deterministic.
"""


from __future__ import annotations

from collections.abc import Sequence

from .._errors import CoordinateNameError, DegenerateSystemError
from ..groupoids import RESERVED_NAMES
from ._findings import Finding, Layout, default_layout
from ._kinetic import check_kinetic
from ._sampling import POINTS, numeric_findings
from ._structure import structural_findings


def diagnose(step, layout: Layout | None = None, *, points: int = POINTS,
             seed: int = 0) -> None:
    """Raise :class:`DegenerateSystemError` if ``step`` cannot determine its unknowns.

    Structural checks first (exact zeros, symbols that do not occur); then ``points`` random
    admissible points (see :func:`random_point`) through ``step.evaluate``.
    """
    layout = layout or default_layout(step)
    findings = structural_findings(step, layout)
    if not findings:
        findings = numeric_findings(step, layout, points, seed)
    if findings:
        raise DegenerateSystemError(_message(step, findings), findings=tuple(findings))


def _message(step, findings: Sequence[Finding]) -> str:
    texts = [f.text[:1].upper() + f.text[1:] for f in findings]
    body = " ".join(f"({i + 1}) {t}" for i, t in enumerate(texts)) if len(texts) > 1 else texts[0]
    return (f"{step.name}: the step equations cannot determine the step, so no simulation "
            f"could solve them. {body}")


# --- entry point for the systems --------------------------------------------------------------

def check_coordinatelisted(step) -> None:
    """A coordinate named like the multipliers' key would make ``step.symbol`` ambiguous."""
    names = set(step.groupoid.symbols_by_name(0))
    clash = sorted(names & set(RESERVED_NAMES))
    if clash:
        raise CoordinateNameError(
            f"{step.name}: the coordinate name {clash[0]!r} of {step.groupoid.name} is "
            f"reserved for the multipliers ({', '.join(map(repr, RESERVED_NAMES))} all name "
            "λ in step.symbol); rename the coordinate")


def check_step(step, *, distribution: int | None = None, lie_poisson: bool = False,
               time_steps: Sequence = (), stages: int = 0) -> None:
    """The derivation-time checks of a system's step: coordinate names, then
    :func:`diagnose` with the rows named for the kind of step, then :func:`check_kinetic`
    with the candidate step parameters ``time_steps``.

    ``distribution``: dim D_c of a nonholonomic step (its first rows are the DEL along the
    basis of D_c, the rest the constraints ψ defining M_c, docs/conventions.md §10);
    ``lie_poisson``: the reconstruction step of the Lie–Poisson form (seed 000 §6.1);
    ``stages``: the number of stage rows (∂L/∂ζ of both arrows) after the junction rows
    (docs/conventions.md §22).
    """
    check_coordinatelisted(step)
    if distribution is not None:
        n = len(step)
        layout = default_layout(
            step, [f"the DEL along the D_c basis element {a + 1}" for a in range(distribution)],
            constraint_letter="ψ", constraint_rows=range(distribution, n))
    elif lie_poisson:
        rank = len(step) - step.n_constraints
        layout = default_layout(
            step, [f"μ + λ·Φ = m_{{k+1}} along E_{a + 1}" for a in range(rank)])
    elif stages:
        rank = len(step) - step.n_constraints - stages
        half = stages // 2
        layout = default_layout(
            step, [f"the DEL along X_{a + 1}" for a in range(rank)]
            + [f"∂L/∂ζ_{a % half + 1} of g_{{k{'' if a < half else '+1'}}}"
               for a in range(stages)])
    else:
        layout = default_layout(step)
    diagnose(step, layout)
    check_kinetic(step, layout, time_steps)


