"""Why a step cannot determine its unknowns: the findings and their messages.

A :class:`Finding` names a cause (one of the constants below), the equations and unknowns it
involves, and a message that says what to do; :func:`compose` makes them from the rows that
vanish, the rows without unknowns and the unknowns without rows (seed 000 §3.3, Thm 2.16;
docs/conventions.md §4, §15).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

#: causes reported in :attr:`DegenerateSystemError.findings`
IDENTICALLY_ZERO = "identically zero"
NO_UNKNOWN = "involves no unknown"
UNUSED_UNKNOWN = "unknown enters no equation"
UNDETERMINED_MULTIPLIER = "undetermined multiplier"
DEPENDENT_CONSTRAINTS = "dependent constraints"
NOT_REGULAR = "not regular"

HOLONOMIC_HINT = (
    "a constraint on configurations belongs on the configuration space: give it as "
    "DiscreteSystem(..., holonomic=lambda q: [...]) for constraints ψ(q) on the base point q "
    "(docs/conventions.md §15), whose multiplier is determined with the next arrow")


@dataclass(frozen=True)
class Finding:
    """One reason why the step cannot be solved."""

    cause: str
    equations: tuple[str, ...]
    unknowns: tuple[str, ...]
    text: str


@dataclass
class Layout:
    """How to name the rows and columns of a step: equation labels, which rows are
    constraints (with their names) and which unknowns are their multipliers."""

    labels: list[str]
    unknowns: list[str]
    constraint_rows: list[int] = field(default_factory=list)
    constraint_names: list[str] = field(default_factory=list)
    multiplier_columns: list[int] = field(default_factory=list)
    order: int = 1

    def constraint_of_row(self, i: int) -> str | None:
        if i in self.constraint_rows:
            return self.constraint_names[self.constraint_rows.index(i)]
        return None


def default_layout(step, section_labels: Sequence[str] | None = None,
                   constraint_letter: str | None = None,
                   constraint_rows: Sequence[int] | None = None) -> Layout:
    """Rows: one per basis section (``section_labels``, default "the DEL along X_i"), then
    the constraints (the last ``step.n_constraints`` rows unless ``constraint_rows`` is given)
    named φ_a (Φ_a for second order, or ``constraint_letter``) and the holonomic ones ψ_a;
    multipliers: the last ``step.n_constraints`` unknowns."""
    n, m = len(step), step.n_constraints
    rows = list(constraint_rows) if constraint_rows is not None else list(range(n - m, n))
    letter = constraint_letter or ("Φ" if step.order == 2 else "φ")
    held = getattr(step, "n_holonomic", 0)
    names = ([f"{letter}_{a + 1}" for a in range(len(rows) - held)]
             + [f"ψ_{a + 1}" for a in range(held)])
    free = [i for i in range(n) if i not in rows]
    if section_labels is None:
        section_labels = [f"the DEL along X_{s + 1}" for s in range(len(free))]
    labels = [""] * n
    for i, text in zip(free, section_labels):
        labels[i] = f"equation {i + 1} ({text})"
    for i, name in zip(rows, names):
        labels[i] = f"equation {i + 1} ({name} = 0)"
    u = len(step.unknowns)
    return Layout(labels=labels, unknowns=[str(s) for s in step.unknowns],
                  constraint_rows=rows, constraint_names=names,
                  multiplier_columns=list(range(u - m, u)), order=step.order)


# --- composing findings ----------------------------------------------------------------------

def listed(items: Sequence[str]) -> str:
    items = list(items)
    return items[0] if len(items) == 1 else ", ".join(items[:-1]) + " and " + items[-1]


def _verb(items: Sequence, one: str, many: str) -> str:
    return one if len(items) == 1 else many


def _short(expr) -> str:
    text = str(expr)
    return text if len(text) <= 80 else text[:77] + "..."


def compose(layout: Layout, zero: Sequence[int], idle: Sequence[int],
            unused: Sequence[int], shown: dict | None = None) -> list[Finding]:
    """Findings from rows that vanish, rows without unknowns and unknowns without rows."""
    out: list[Finding] = []
    crow = set(layout.constraint_rows)
    zero_eq = [i for i in zero if i not in crow]
    zero_c = [i for i in zero if i in crow]
    n_eq = len(layout.labels) - len(crow)
    if zero_eq:
        out.append(_zero_equations(layout, zero_eq, all_of_them=len(zero_eq) == n_eq))
    if zero_c:
        out.append(_zero_constraints(layout, zero_c))
    idle_eq = [i for i in idle if i not in crow]
    idle_c = [i for i in idle if i in crow]
    if idle_eq:
        out.append(_idle_equations(layout, idle_eq, shown or {}))
    if idle_c:
        out.append(_idle_constraints(layout, idle_c))
    if len(zero) == len(layout.labels):
        return out  # nothing is left for an unknown to enter
    explained = {layout.multiplier_columns[layout.constraint_rows.index(i)]
                 for i in zero_c if layout.multiplier_columns}
    mcols = set(layout.multiplier_columns)
    chart = [j for j in unused if j not in mcols]
    lam = [j for j in unused if j in mcols and j not in explained]
    if chart:
        out.append(_unused_chart(layout, chart))
    if lam:
        out.append(undetermined(layout, lam))
    return out


def _zero_equations(layout: Layout, rows: Sequence[int], all_of_them: bool) -> Finding:
    eqs = tuple(layout.labels[i] for i in rows)
    if all_of_them:
        text = (f"The Euler–Lagrange equations vanish identically: {listed(eqs)} "
                f"{_verb(eqs, 'reads', 'read')} 0 = 0. The discrete Lagrangian is a null "
                "Lagrangian — a constant, zero (e.g. a rigid body with zero inertia), or a "
                "difference f(β(g)) − f(α(g)) such as a·(q₁ − q₀)/h or (q₁² − q₀²)/(2h) — "
                "and determines no motion.")
    else:
        text = (f"{listed(eqs)} {_verb(eqs, 'reads', 'read')} 0 = 0: the discrete Lagrangian "
                "and the constraints do not change along these sections, so nothing "
                "determines the motion in these directions.")
    return Finding(IDENTICALLY_ZERO, eqs, (), text)


def _zero_constraints(layout: Layout, rows: Sequence[int]) -> Finding:
    names = [layout.constraint_of_row(i) for i in rows]
    lam = tuple(layout.unknowns[layout.multiplier_columns[layout.constraint_rows.index(i)]]
                for i in rows if layout.multiplier_columns)
    one = len(names) == 1
    text = (f"The constraint{'' if one else 's'} {listed(names)} "
            f"{_verb(names, 'is', 'are')} identically zero: "
            + ("it constrains nothing" if one else "they constrain nothing")
            + (f" and {'leaves its multiplier' if one else 'leave their multipliers'} "
               f"{listed(lam)} undetermined" if lam else "")
            + f"; remove {'it' if one else 'them'}.")
    return Finding(IDENTICALLY_ZERO, tuple(layout.labels[i] for i in rows), lam, text)


def _idle_equations(layout: Layout, rows: Sequence[int], shown: dict) -> Finding:
    eqs = tuple(layout.labels[i] for i in rows)
    exprs = "; ".join(f"{_short(shown[i])} = 0" for i in rows if i in shown)
    text = (f"{listed(eqs)} {_verb(eqs, 'involves', 'involve')} none of the unknowns"
            + (f" ({exprs})" if exprs else "")
            + ": a condition on the known state, not an equation for the step. The discrete "
            "Lagrangian does not depend on the unknown arrow in these directions (e.g. it "
            "depends on the source α(g) or the target β(g) of the arrow only).")
    return Finding(NO_UNKNOWN, eqs, (), text)


def _idle_constraints(layout: Layout, rows: Sequence[int]) -> Finding:
    names = [layout.constraint_of_row(i) for i in rows]
    newest = "g_{k+2}" if layout.order == 2 else "g_{k+1}"
    why = ("(the unknown arrow moves its target β in no direction that changes ψ)"
           if all(n.startswith("ψ") for n in names) else
           "(e.g. it depends only on the source α(g) of the arrow)")
    text = (f"The constraint{'s' if len(names) > 1 else ''} {listed(names)} "
            f"{_verb(names, 'does', 'do')} not depend on the unknown arrow {newest} "
            f"{why}: it restricts the known state, not the step, and its multiplier is not "
            "determined.")
    return Finding(NO_UNKNOWN, tuple(layout.labels[i] for i in rows), (), text)


def _unused_chart(layout: Layout, cols: Sequence[int]) -> Finding:
    names = tuple(layout.unknowns[j] for j in cols)
    text = (f"The unknown{'s' if len(names) > 1 else ''} {listed(names)} "
            f"{_verb(names, 'enters', 'enter')} no equation: the discrete Lagrangian and the "
            "constraints do not vary with "
            f"{'it' if len(names) == 1 else 'them'}, so nothing determines "
            f"{'it' if len(names) == 1 else 'them'}.")
    return Finding(UNUSED_UNKNOWN, (), names, text)


def undetermined(layout: Layout, cols: Sequence[int], dependent: bool = False) -> Finding:
    names = tuple(layout.unknowns[j] for j in cols)
    phis = [layout.constraint_names[layout.multiplier_columns.index(j)] for j in cols]
    plural = len(names) > 1
    if dependent:
        head = (f"The multipliers {listed(names)} of {listed(phis)} are not determined by "
                "the equations: a combination of these constraints is unchanged")
    else:
        head = (f"The multiplier{'s' if plural else ''} {listed(names)} of {listed(phis)} "
                f"{_verb(names, 'enters', 'enter')} no equation, so nothing determines "
                f"{'them' if plural else 'it'}: {_verb(names, 'its', 'each')} constraint is "
                "unchanged")
    if all(p.startswith("ψ") for p in phis):
        text = (f"{head} as the junction node moves (dψ(ρ(X)) = 0 for every basis section X, "
                "ρ the anchor): the sections do not move the base point in a direction that "
                "changes ψ, so ψ does not constrain the motion; remove it, or check that it "
                "depends on coordinates of the base point the sections move.")
    else:
        text = (f"{head} under the variation at the junction (X⃗[φ] = 0 at the arrow it "
                "constrains), which happens when a constraint depends only on the target β(g) "
                f"of the arrow, as φ = |q₁|² − ℓ² does; {HOLONOMIC_HINT}.")
    return Finding(UNDETERMINED_MULTIPLIER, (), names, text)


