"""Legendre transforms, Noether quantities and Lie–Poisson equations as objects."""

from __future__ import annotations

import functools
import math
from collections.abc import Mapping, Sequence

import numpy as np
import sympy as sp

from .._arguments import finite_vector, flag_argument, instance_argument
from .._errors import (
    DomainError,
    InputTypeError,
    ParameterError,
    ShapeError,
    UnsupportedFeatureError,
)
from .._lambdify import NUMPY_MODULES
from .._sizes import nodes_at_most
from .._symbols import stage_symbols
from ..derivation import LegendreForms, LiePoissonForms, NoetherForms
from ..ir import Graph, Program, from_sympy, term_magnitude
from ._programs import solve_stages
from ._step import StepEquations

#: the most terms (expanded, :func:`~._printing.expanded_terms`) of a quantity printed on
#: one line: a chain's momentum has tens, a free body's on SO(3) by the midpoint rule
#: thousands (about 5 MB of LaTeX)
INLINE_TERMS = 400
#: the bound on F_X's expanded terms, counted on the expression graph of a quantity built
#: there (``Program.expanded_terms``), above which ``latex()`` refuses before building its
#: SymPy form: the graph's count and the SymPy form's differ (1,240 against 60 for a plane
#: by GaussLegendre(2); 1.4e7 against 1.4e7 for the heavy top by the midpoint rule; 3.5e11
#: against 3.5e12 for the heavy top by GaussLegendre(2), whose SymPy form took 5 minutes
#: to be refused), so only a count far past INLINE_TERMS refuses at once
GRAPH_INLINE_TERMS = 10**5

#: characters of an expression shown in a repr before it is cut
REPR_WIDTH = 60


def _parameter_value(symbol: sp.Symbol, value, entry: str) -> float:
    """A trajectory's value of ``symbol`` as a float: a number (:class:`ParameterError`
    otherwise), finite and of the sign the symbol is declared with (:class:`DomainError`)."""
    try:
        number = float(value)
    except (TypeError, ValueError, OverflowError):
        raise ParameterError(f"NoetherQuantity.{entry}: the trajectory's value of {symbol} "
                             f"is not a number: {value!r}") from None
    if not math.isfinite(number):
        raise DomainError(f"NoetherQuantity.{entry}: the trajectory's value of {symbol} is "
                          f"{number}; parameters must be finite")
    if (symbol.is_positive and number <= 0) or (symbol.is_nonnegative and number < 0):
        sign = "positive" if symbol.is_positive else "nonnegative"
        raise DomainError(f"NoetherQuantity.{entry}: {symbol} is declared {sign}, the "
                          f"trajectory's value is {number}")
    return number


def _finite_values(out: np.ndarray, entry: str, what, where: str) -> None:
    """A :class:`DomainError` at the first non-finite entry of ``out``: ``what`` (a text,
    or a callable giving it, called only then) overflows at that ``where`` (state or step)
    of finite states."""
    if not np.isfinite(out).all():
        k = int(np.flatnonzero(~np.isfinite(out))[0])
        what = what() if callable(what) else what
        raise DomainError(f"NoetherQuantity.{entry}: {what} is not finite at {where} {k} "
                          f"({out[k]}): it overflows there (check the section's "
                          f"coefficients and the parameters)")


def _short(expr) -> str:
    """An expression's text, cut to REPR_WIDTH characters: its leading terms, each printed
    only when small (printing the whole of a Legendre transform of the heavy top, 3.5 MB,
    took 22 s)."""
    text = ""
    for term in sp.Add.make_args(expr):
        piece = str(term) if nodes_at_most(term, REPR_WIDTH) else "…"
        text = piece if not text else f"{text} + {piece}"
        if len(text) > REPR_WIDTH or piece == "…":
            break
    return text if len(text) <= REPR_WIDTH else text[:REPR_WIDTH - 1] + "…"



def _forms_argument(forms, kind: type, method: str, owner: str) -> None:
    """An :class:`~symgroupoid.InputTypeError` unless ``forms`` are the derived forms these
    objects are built from (a system's ``method`` builds them)."""
    instance_argument(forms, kind, "forms", f"the {kind.__name__} of a system (use the "
                      f"system's {method})", owner=owner)

class LegendreTransforms:
    """F⁻L(g_k, λ_k) and F⁺L(g_k, λ_k) in the basis of sections (seed 000 §3.3).

    ``minus[a] = X⃗_a[L + λ·φ](g)``, ``plus[a] = X⃖_a[L + λ·φ](g)``; the discrete
    Euler–Lagrange equations say F⁺L(g_k, λ_k) = F⁻L(g_{k+1}, λ_{k+1}).
    """

    def __init__(self, forms: LegendreForms, parameters: Sequence):
        _forms_argument(forms, LegendreForms, "legendre()", "LegendreTransforms")
        self.minus: list[sp.Expr] = forms.minus
        self.plus: list[sp.Expr] = forms.plus
        self.arrow: tuple = forms.arrow
        self.multipliers: list = forms.multipliers
        self.parameters = list(parameters)

    @functools.cached_property
    def _numeric(self):
        args = [list(self.arrow), list(self.multipliers), list(self.parameters)]
        return (sp.lambdify(args, sp.Matrix(self.minus), NUMPY_MODULES),
                sp.lambdify(args, sp.Matrix(self.plus), NUMPY_MODULES))

    def evaluate(self, arrow: Sequence, multipliers: Sequence = (), params: Sequence = ()):
        """Numeric (F⁻L, F⁺L) at an arrow (flat coordinates) and multipliers."""
        fm, fp = self._numeric
        args = (np.asarray(arrow, float), np.asarray(multipliers, float),
                np.asarray(params, float))
        return np.asarray(fm(*args), float).ravel(), np.asarray(fp(*args), float).ravel()

    def latex(self, width=None, document: bool = False) -> str:
        """(𝔽⁻L)_a, then (𝔽⁺L)_a, as an ``align`` environment: terms collected by multipliers,
        variables and parameters (checked to be the transforms), rows broken to ``width``
        pt (default 450); or, with ``document``, a standalone document (as a step's)."""
        from ._latex import rows_latex
        from ._momentum_rows import legendre_rows

        return rows_latex(legendre_rows(self, width), flag_argument(document, "document"),
                          "the discrete Legendre transforms")

    def __repr__(self) -> str:
        return (f"<LegendreTransforms F⁻L, F⁺L: {len(self.minus)} components each (section "
                f"basis), on arrows of {len(self.arrow)} coordinates, "
                f"{len(self.multipliers)} multipliers>")


def _inputs(trajectory) -> int:
    """Inputs per arrow of a trajectory's system (its states end with u_k, u_{k+1})."""
    return int(getattr(getattr(trajectory, "_layout", None), "n_inputs", 0))


def _finite_states(states: np.ndarray, entry: str) -> None:
    """A :class:`DomainError` naming the first state with a non-finite arrow coordinate,
    multiplier or input (the entries a Noether quantity or its impulse reads), before any
    evaluation or stage solve."""
    bad = ~np.isfinite(states).all(axis=1)
    if bad.any():
        k = int(np.flatnonzero(bad)[0])
        raise DomainError(f"NoetherQuantity.{entry}: state {k} of the trajectory has "
                          f"non-finite entries ({states[k].tolist()}); use a trajectory of "
                          f"finite states")


#: the fractions of its value the time step is tried at where the stages of a random arrow
#: cannot be solved at the value drawn (:meth:`NoetherQuantity.check_on_graph`)
STAGE_RETRIES = (0.1, 0.01)


class NoetherQuantity:
    """The conserved quantity F_X of a section X (seed 000 Thm 4.9).

    ``is_symmetry`` records the check that ⟨F⁻L, X(α)⟩ + f(α) = ⟨F⁺L, X(β)⟩ + f(β) holds
    identically on G (with the multipliers free); ``defect`` is their difference and
    ``verification`` says how it was decided (symbolically, or numerically at random arrows
    of G for defects too large to simplify; see
    :func:`symgroupoid.derivation._momenta.vanishing_check`) — with holonomic constraints,
    on N = G|_M (docs/conventions.md §15).  ``is_symmetry`` is False both where the check
    refuted the symmetry and where it could not decide (no random arrow gave finite values,
    or none had solvable stages): ``verification`` then starts with "undecided", and the
    quantity's repr says so.
    """

    def __init__(self, forms: NoetherForms, is_symmetry: bool, parameters: Sequence):
        _forms_argument(forms, NoetherForms, "noether()", "NoetherQuantity")
        self._forms = forms
        #: of a system with internal stages: F_X, the defect and the stage rows as nodes of
        #: the program's graph, ``graph_forms(g, symbols, memo) -> (F, defect, rows)``, and
        #: ``symbolic_forms()``,
        #: the :class:`NoetherForms` with their SymPy expressions, built on first use of
        #: :attr:`expr` or :attr:`defect` (the symbolic Legendre transforms of a Galerkin
        #: step take minutes; evaluation never needs them)
        self.graph_forms = None
        self.symbolic_forms = None
        self.arrow: tuple = forms.arrow
        self.multipliers: list = forms.multipliers
        self.is_symmetry: bool = is_symmetry
        self.verification: str = "symbolic"
        self.parameters = list(parameters)
        #: the name of the system it is the quantity of (a run of another system is
        #: refused), and that system's inputs per arrow; set by ``DiscreteSystem.noether``
        self.system_name: str | None = None
        self.n_inputs: int = 0
        #: that system (its ``fingerprint`` tells its runs from those of another system of
        #: the same name)
        self.system = None
        #: arrows of the window the quantity is written on: 1, or 3 for a second-order
        #: system (its state's (g_{k−1}, g_k, g_{k+1}), whose terms carry u_{k−1}, u_k)
        self.window: int = getattr(forms, "window", 1)

    @property
    def expr(self) -> sp.Expr:
        """F_X as a SymPy expression in the arrow's coordinates (and the stages ζ)."""
        return self._symbolic().quantity

    @property
    def defect(self) -> sp.Expr:
        """⟨F⁻L, X(α)⟩ + f(α) − F_X as a SymPy expression (zero for a symmetry)."""
        return self._symbolic().defect

    def _shown(self) -> str:
        """F_X's leading terms, or, while its SymPy form is not built (a quantity evaluated
        on the graph), what it is."""
        if self._forms.quantity is None:
            return "⟨F⁺L(g, ζ*), X(β(g))⟩ + f(β(g)) (on the expression graph)"
        return _short(self.expr)

    def _symbolic(self) -> NoetherForms:
        if self._forms.quantity is None and self.symbolic_forms is not None:
            self._forms = self.symbolic_forms()
        return self._forms

    @property
    def _known_inputs(self) -> int:
        """Input sets a state holds for its known terms (1, or 2 for second order), before
        the slot of the input to come."""
        return 2 if self.window == 3 else 1

    def evaluate(self, arrow: Sequence, multipliers: Sequence = (), params: Sequence = ()
                 ) -> float:
        """F_X at one arrow and its multipliers, with the parameters' values in the order
        of :attr:`parameters`; with internal stages, at the arrow's stages ζ* (∂L/∂ζ = 0,
        without forces: a forced run's values are :meth:`along`'s).  Evaluated by the
        quantity's program, as :meth:`along` is (the SymPy form is not built).  Arrays of
        other lengths are a :class:`ShapeError`; non-finite entries, and a value that is
        not finite there, a :class:`DomainError`."""
        values = [finite_vector(given, want, name, owner="NoetherQuantity.evaluate")
                  for name, given, want in (("arrow", arrow, len(self.arrow)),
                                            ("multipliers", multipliers,
                                             len(self.multipliers)),
                                            ("params", params, len(self.parameters)))]
        known = np.r_[values[0], values[1]][:, None]
        with np.errstate(all="ignore"):
            (F,) = self._at_stages(["F"], known, values[2])
        out = np.ravel(np.asarray(F, dtype=float))[:1]
        _finite_values(out, "evaluate", lambda: f"the quantity F_X = {self._shown()}", "arrow")
        return float(out[0])

    def latex(self, width=None, document: bool = False) -> str:
        """F_X, its terms collected by multipliers, variables and parameters (checked to be
        F_X), on one line; with ``width`` (pt) or ``document``, as the row F_X = … of an
        ``align`` broken to that width (default 450), or a standalone document, as a step's
        (a quantity of 1,500 characters ran 2,000 pt past the page on one line); an
        :class:`~symgroupoid.UnsupportedFeatureError`, at once, when
        expanded it could have more than :data:`INLINE_TERMS` terms (a free body on SO(3)
        by the midpoint rule: 2,736, about 5 MB of LaTeX).  With internal stages
        (docs/conventions.md §22) the arrow's stages print as the step prints those of its
        known arrow, (ζ_k)_1, (ζ_k)_2, …: F_X is taken at the stages solved for the arrow
        (the forced stages of a forced system)."""
        from ._latex import rows_latex
        from ._momentum_rows import inline_latex, quantity_rows
        from ._printing import expanded_terms
        from ._rows import check_width

        if self._forms.quantity is None and self.graph_forms is not None:
            terms = self._program.expanded_terms(["F"])
            if terms > GRAPH_INLINE_TERMS:  # hopeless: not worth its SymPy form (minutes)
                raise UnsupportedFeatureError(
                    f"the Noether quantity F_X could have about {terms} terms expanded "
                    f"(counted on the expression graph it is evaluated on), far more than "
                    f"the {INLINE_TERMS} one line can hold (printed, it would run to "
                    f"megabytes that no page holds): LaTeX is not produced for it.  Its "
                    f"values along a trajectory (along(), plot_conservation) are unaffected")
        terms = expanded_terms([self.expr])
        if terms > INLINE_TERMS:
            raise UnsupportedFeatureError(
                f"the Noether quantity F_X could have {terms} terms expanded, more than the "
                f"{INLINE_TERMS} one line can hold (printed, it would run to megabytes that "
                f"no page holds): LaTeX is not produced for it.  Its values along a "
                f"trajectory (along(), plot_conservation) are unaffected")
        document = flag_argument(document, "document")
        if width is not None or document:
            check_width(width)  # (refused before any printing)
        expr = self.expr
        if self.stages:
            expr = expr.xreplace(dict(zip(self.stages, stage_symbols(len(self.stages), 0))))
        if width is None and not document:
            return inline_latex(expr, self.multipliers, self.parameters)
        return rows_latex(quantity_rows(expr, self.multipliers, self.parameters, width),
                          document, "a Noether quantity F_X")

    #: a system with internal stages (docs/conventions.md §22): the generic stages ζ the
    #: quantity and the defect are written in (with their stage rows ∂L/∂ζ, from
    #: :attr:`graph_forms`, whose root ζ* they are evaluated at: the envelope theorem,
    #: F^±L_d(g) = F^±L(g, ζ*))
    stages: tuple = ()
    #: a forced system with internal stages: f_ζ of the arrow in the generic stages and its
    #: inputs ``stage_inputs`` (the state's u_k), which the stage rows gain, so that F_X is
    #: evaluated at the forced stages, ∂L/∂ζ + f_ζ = 0 (docs/conventions.md §22); the
    #: symbols (ζ_k, ζ_{k+1}) of the stages the impulse form is written in
    forces = None  # the system's ForceFunctions (in its slot coordinates)
    stage_inputs: tuple = ()
    impulse_stages: tuple = ()
    #: a system with internal stages and holonomic constraints ψ (docs/conventions.md §22,
    #: "The Noether quantity on N = G|_M"): the arrows of N = G|_M near a random arrow at
    #: which the symmetry is checked (a :class:`~symgroupoid.equations.RestrictedArrows`),
    #: and the end multipliers of ψ, whose coefficients in the defect, −dψ_a(α(g))(ρ(X)),
    #: vanish on M iff X is tangent to M
    restriction = None
    tangency: tuple = ()

    @property
    def stage_forces(self) -> bool:
        """Whether F_X is evaluated at forced stages (a forced system with stages)."""
        return bool(self.stages) and self.forces is not None

    @functools.cached_property
    def _program(self) -> Program:
        g = Graph()
        names = [*self.arrow, *self.multipliers]
        symbols = {s: g.input(s) for s in (*names, *self.stages, *self.stage_inputs,
                                           *self.parameters) if isinstance(s, sp.Symbol)}
        memo: dict = {}
        if self.graph_forms is not None:
            node, defect, rows = self.graph_forms(g, symbols, memo)
        else:
            node = from_sympy(g, self.expr, symbols, "the Noether quantity", memo)
        inputs = {"known": names, "p": list(self.parameters)}
        varying = [symbols[s] for s in (*names, *self.stages) if s in symbols]
        outputs = {"F": [node], "F_scale": term_magnitude(g, [node], varying)}
        if self.graph_forms is not None:
            from ..derivation import step_jacobian

            # the defect is affine in the end multipliers of holonomic constraints: their
            # coefficients −dψ(α(g))(ρ(X)) vanish iff X is tangent to M (§22)
            (tangency,) = (step_jacobian(g, [defect], [symbols[lam] for lam in self.tangency])
                           if self.tangency else [[]])
            outputs.update({"defect": [defect], "tangency": list(tangency)})
        if self.stages:
            inputs["zeta"] = list(self.stages)
            zeta = [symbols[z] for z in self.stages]
            J = step_jacobian(g, rows, zeta)
            outputs.update({"rows": rows, "J": [c for row in J for c in row]})
            if self.stage_forces:
                inputs["u"] = list(self.stage_inputs)
                f_zeta = _force_nodes(g, self.forces, self.forces.stage_forces,
                                      [symbols[c] for c in self.arrow], zeta,
                                      [symbols[v] for v in self.stage_inputs], symbols)
                forced = [g.add(r, f) for r, f in zip(rows, f_zeta)]
                J = step_jacobian(g, forced, zeta)
                outputs.update({"forced_rows": forced,
                                "forced_J": [c for row in J for c in row]})
        return Program(g, inputs, outputs)

    def _stages_at(self, known: np.ndarray, p: np.ndarray,
                   u: np.ndarray | None = None) -> np.ndarray:
        """The stages of the arrows ``known`` (n, R): ζ* (∂L/∂ζ = 0), or, with the inputs
        ``u`` (m, R) of a forced system, the forced stages (∂L/∂ζ + f_ζ = 0: the stages the
        step solved, docs/conventions.md §22)."""
        if u is not None and self.stage_forces:
            rows = self._program.numpy_function(["forced_rows", "forced_J"],
                                                ["known", "zeta", "u", "p"])

            def at(known, zeta, p):
                return rows(known, zeta, u, p)

            return solve_stages(at, known, p, len(self.stages), "the Noether quantity")
        rows = self._program.numpy_function(["rows", "J"], ["known", "zeta", "p"])
        return solve_stages(rows, known, p, len(self.stages), "the Noether quantity")

    def _at_stages(self, outputs: list, known: np.ndarray, p: np.ndarray,
                   u: np.ndarray | None = None) -> list:
        """``outputs`` of the program at arrows ``known`` (n, R), at their stages for a
        system with internal stages (the forced stages with the inputs ``u``, see
        :meth:`_stages_at`)."""
        names = ["known", "zeta", "p"] if self.stages else ["known", "p"]
        f = self._program.numpy_function(outputs, names)
        if not self.stages:
            return f(known, p)
        return f(known, self._stages_at(known, p, u), p)

    def check_on_graph(self, groupoid, step=None) -> tuple[bool, str]:
        """Whether the defect vanishes (at ζ*, for a system with internal stages) at random
        arrows of ``groupoid`` (with random multipliers and parameters in [0.5, 1.5]), for
        a quantity built on the expression graph; and how that was decided.  Where the
        stages of an arrow cannot be solved (a step of h ~ 1 across a singular potential:
        ∂L/∂ζ = 0 has no root near ζ = 0), the arrow is tried again with the time step
        ``step`` (a parameter symbol) at a tenth and a hundredth of its value, where the
        stage equations are close to their linear part.  With holonomic
        constraints the arrows are moved onto N = G|_M first (:attr:`restriction`), the
        stages ζ* include the interior multipliers, and X must be tangent to M there
        (:attr:`tangency`; docs/conventions.md §22, "The Noether quantity on N = G|_M")."""
        from ..groupoids import Groupoid

        instance_argument(groupoid, Groupoid, "groupoid", "a Groupoid",
                          owner="check_on_graph")
        rng = np.random.default_rng(20260)
        usable = 0
        where = "random arrows" if self.restriction is None else "random arrows of N = G|_M"
        how = f"numeric at the stages ζ* of {where}"
        for _ in range(8):
            arrow = np.asarray(groupoid.random_arrow(rng), float)
            lam = rng.uniform(0.5, 1.5, len(self.multipliers))
            p = rng.uniform(0.5, 1.5, len(self.parameters))
            if self.restriction is not None:
                arrow = self.restriction(arrow, p)
                if arrow is None:  # no point of M near this arrow's ends
                    continue
            known = np.r_[np.asarray(arrow, float), lam][:, None]
            values = self._at_smaller_steps(known, p, step)
            if values is None:
                continue
            F, defect, tangency = values
            F, defect = float(np.ravel(F)[0]), float(np.ravel(defect)[0])
            tangency = np.ravel(np.asarray(tangency, float))
            if not (np.isfinite(F) and np.isfinite(defect) and np.isfinite(tangency).all()):
                continue
            usable += 1
            scale = 1e-9 * max(abs(F), 1.0)
            if (np.abs(tangency) > scale).any():
                return False, (f"not tangent to M = {{ψ = 0}}: dψ(X) ≠ 0 at the source of "
                               f"{where}")
            if abs(defect) > scale:
                return False, how if self.stages else "nonzero at a random arrow"
        if usable < 3:
            return False, (f"undecided: the stages could not be solved at {where}"
                           if self.stages else "undecided: no random arrow gave a finite value")
        return True, how if self.stages else (f"numerical: zero to 1e-09 relative at {usable} "
                                              f"{where} of {groupoid.name}")

    def _at_smaller_steps(self, known: np.ndarray, p: np.ndarray, step) -> tuple | None:
        """F, the defect and the tangency at the arrow ``known`` (at its stages ζ*), with
        the parameters ``p``, else with the time step ``step`` at 0.1 and 0.01 of its value
        (:data:`STAGE_RETRIES`) where the stages could not be solved; None when none of
        them could."""
        from .._errors import DiagnosticsError

        names = [str(s) for s in self.parameters]
        at = names.index(str(step)) if self.stages and step is not None \
            and str(step) in names else None
        for factor in (1.0, *(STAGE_RETRIES if at is not None else ())):
            q = p.copy()
            if at is not None:
                q[at] *= factor
            try:
                with np.errstate(all="ignore"):
                    F, defect, *tangency = self._at_stages(["F", "defect", "tangency"],
                                                           known, q)
            except DiagnosticsError:
                continue
            return F, defect, tangency
        return None

    def _check_run(self, trajectory, entry: str) -> None:
        """``trajectory`` is a :class:`~symgroupoid.Trajectory` (states and parameters by
        name: an :class:`InputTypeError` otherwise) of this quantity's system: the run of a
        system of another name, of another system of the same name (another fingerprint:
        two unnamed continuous systems discretised alike share a name), or with inputs where
        the system has none or the reverse, is a :class:`ShapeError` (its states may have
        the same width, and its numbers would be those of other equations: another scheme,
        the unforced stages)."""
        if not hasattr(trajectory, "states") or not isinstance(
                getattr(trajectory, "parameters", None), Mapping):
            raise InputTypeError(f"NoetherQuantity.{entry}: trajectory must be a Trajectory "
                                 f"(sim.simulate(...)), got {type(trajectory).__name__}")
        name = getattr(trajectory, "system_name", None)
        if self.system_name is not None and name is not None and name != self.system_name:
            raise ShapeError(f"NoetherQuantity.{entry}: the trajectory is a run of {name!r}, "
                             f"the quantity is of {self.system_name!r}; use a trajectory of "
                             f"this system's step")
        m = _inputs(trajectory)
        if self.system_name is not None and m != self.n_inputs:
            have = f"{m} input(s) per arrow" if m else "no inputs"
            want = f"{self.n_inputs}" if self.n_inputs else "none"
            raise ShapeError(f"NoetherQuantity.{entry}: the trajectory's system has {have}, "
                             f"this quantity's system {want}: it is a run of another "
                             f"system; use a trajectory of this system's step")
        run_of = getattr(trajectory, "is_run_of", None)
        if self.system is not None and run_of is not None and run_of(self.system) is False:
            raise ShapeError(f"NoetherQuantity.{entry}: the trajectory is a run of another "
                             f"system named {name!r} (another Lagrangian, scheme, constraints"
                             f" or forces); use a trajectory of this system's step")

    def _trajectory_parameters(self, trajectory, entry: str) -> np.ndarray:
        """The values of this quantity's parameters in ``trajectory.parameters``, which must
        name exactly the parameters of its system: a parameter missing, or one the system
        does not have (the run of another system, whose states may have the same width),
        is a :class:`ParameterError`."""
        values = getattr(trajectory, "parameters", {})
        names = [str(s) for s in self.parameters]
        missing = [n for n in names if n not in values]
        if missing:
            raise ParameterError(f"NoetherQuantity.{entry}: the trajectory gives no value "
                                 f"for {', '.join(missing)}")
        foreign = [str(n) for n in values if str(n) not in names]
        if foreign:
            raise ParameterError(f"NoetherQuantity.{entry}: the trajectory has parameters "
                                 f"{', '.join(foreign)} that the quantity's system (parameters"
                                 f" {', '.join(names) or 'none'}) does not have: it is a run "
                                 f"of another system; use a trajectory of this system's step")
        return np.array([_parameter_value(s, values[str(s)], entry) for s in self.parameters])

    def along(self, trajectory) -> np.ndarray:
        """F_X at every kept state of ``trajectory``, shape (R,): one vectorised evaluation.

        The states (g_k, λ_k) of a first-order step are the arrow coordinates and
        multipliers this quantity is written in, in that order; parameters are read by name
        from ``trajectory.parameters``.  Along a solution of a system with this symmetry
        F_X is constant up to the rounding of the steps (seed 000 Thm 4.9).  A state with
        non-finite entries (:class:`DomainError`) and the run of another system (another
        name, inputs where the system has none or the reverse: :class:`ShapeError`;
        parameters that this quantity's system does not have: :class:`ParameterError`) are
        refused before any evaluation, as in :meth:`impulse`.
        """
        (out,) = self._along(trajectory, ["F"], "along")
        _finite_values(out, "along", lambda: f"the quantity F_X = {self._shown()}", "state")
        return out

    def term_magnitude(self, trajectory) -> np.ndarray:
        """S_k, the size of the terms F_X is computed from at every kept state of
        ``trajectory``, shape (R,) (:func:`symgroupoid.ir.term_magnitude`, the state's
        entries varying): ε·S_k is the rounding of F_X there.  A momentum (q_{k+1} − q_k)/h
        at large q is a small difference of large terms, and rounds at their size, not at
        |F_X|; the rounding floor of :func:`~symgroupoid.conservation_summary` is
        ε·(|F_X|·√N + S).
        The same checks as :meth:`along`."""
        (out,) = self._along(trajectory, ["F_scale"], "term_magnitude")
        _finite_values(out, "term_magnitude", "the size of the terms of F_X", "state")
        return out

    def along_with_magnitude(self, trajectory) -> tuple[np.ndarray, np.ndarray]:
        """(:meth:`along`, :meth:`term_magnitude`) from one evaluation (of a system with
        internal stages: the stages of every state solved once)."""
        values, sizes = self._along(trajectory, ["F", "F_scale"], "along")
        _finite_values(values, "along", lambda: f"the quantity F_X = {self._shown()}", "state")
        _finite_values(sizes, "along", "the size of the terms of F_X", "state")
        return values, sizes

    def _along(self, trajectory, outputs: list[str], entry: str) -> list[np.ndarray]:
        """The program's ``outputs`` at every kept state of ``trajectory`` (see
        :meth:`along`), each of shape (R,)."""
        self._check_run(trajectory, entry)
        states = np.asarray(trajectory.states, float)
        n = len(self.arrow) + len(self.multipliers)
        m = _inputs(trajectory)  # a forced state ends with its terms' inputs and the slot
        u = None
        if states.ndim == 2 and states.shape[1] == n + (self._known_inputs + 1) * m:
            u = np.ascontiguousarray(states[:, n:n + m].T)  # the inputs of each arrow
            states = states[:, :n]
        if self.stage_forces and (u is None or len(u) != len(self.stage_inputs)):
            raise ShapeError(f"NoetherQuantity.{entry}: the quantity of a forced system with "
                             f"internal stages is evaluated at the forced stages of each "
                             f"arrow, with its {len(self.stage_inputs)} inputs; the "
                             f"trajectory's states have shape {states.shape}; use a "
                             f"trajectory of this system's step")
        if states.ndim != 2 or states.shape[1] != n:
            raise ShapeError(f"NoetherQuantity.{entry}: the quantity is written in {n} state "
                             f"entries (arrow and multipliers), the trajectory's states have "
                             f"shape {states.shape}; use a trajectory of this system's step")
        _finite_states(states if u is None else np.c_[states, u.T], entry)
        p = self._trajectory_parameters(trajectory, entry)
        with np.errstate(all="ignore"):
            values = self._at_stages(outputs, np.ascontiguousarray(states.T), p, u)
        return [np.broadcast_to(np.asarray(v[0], float), (len(states),)).copy() for v in values]

    def impulse(self, trajectory) -> np.ndarray:
        """The forces' impulse along the section over each step of a forced system's
        ``trajectory`` (kept every step), shape (R − 1,): I_k = Σ_b X^b(β(g_k))·(f⁺_b(g_k)
        + f⁻_b(g_{k+1})) with the inputs of both arrows (docs/conventions.md §20); second
        order I_k = Σ_b X^b(β(g_k))·(f²_b(g_{k−1}, g_k) + f¹_b(g_k, g_{k+1}) +
        f⁰_b(g_{k+1}, g_{k+2})), each pair with its inputs, from state k (g_{k−1}, g_k,
        g_{k+1}) to state k + 1.  For a symmetry X of L, ``np.diff(nq.along(traj))`` equals
        it to rounding (the forced Noether theorem); internal forces that cancel along X
        give zeros.  With internal stages both arrows' forces are taken at their forced
        stages and I_k gains −D(g_{k+1}, ζ_{k+1}), the symmetry defect at the new arrow's
        stages, which is the stage forces' work along the stages' motion under X
        (docs/conventions.md §22, "The forced Noether balance")."""
        if self.impulse_refused:
            raise UnsupportedFeatureError(f"NoetherQuantity.impulse: {self.impulse_refused}")
        if self.impulse_form is None:
            raise InputTypeError("NoetherQuantity.impulse: the system has no forces; its "
                                 "Noether quantity is conserved (use along())")
        self._check_run(trajectory, "impulse")
        if getattr(trajectory, "every", 1) != 1:
            raise ShapeError("NoetherQuantity.impulse: the impulse of each step needs every "
                             "state; simulate with every=1")
        states = np.asarray(trajectory.states, float)
        dim, m, held = len(self.arrow), _inputs(trajectory), self._known_inputs
        n = dim + len(self.multipliers)
        if states.ndim != 2 or states.shape[1] != n + (held + 1) * m:
            raise ShapeError(f"NoetherQuantity.impulse: the states have shape "
                             f"{states.shape}; use a trajectory of this system's step")
        _finite_states(states[:, :n + held * m], "impulse")
        p = self._trajectory_parameters(trajectory, "impulse")
        if self.stages:
            return self._impulse_with_stages(states, n, m, p)
        new = len(self.impulse_form[2])  # coordinates of the next state's newest arrow
        # state k gives its window and its terms' inputs; state k + 1 its newest arrow and
        # the input of its newest term (first order: its arrow g_{k+1} and u_{k+1})
        a = states[:-1, np.r_[0:dim, n:n + held * m]]
        b = states[1:, np.r_[dim - new:dim, n + (held - 1) * m:n + held * m]]
        f = self._impulse_program.numpy_function(["I"], ["a", "b", "p"])
        with np.errstate(all="ignore"):
            out = np.broadcast_to(np.asarray(f(np.ascontiguousarray(a.T),
                                               np.ascontiguousarray(b.T), p)[0][0], float),
                                  (len(a),))
        _finite_values(out, "impulse", "the forces' impulse", "step")
        return out.copy()

    def _impulse_with_stages(self, states: np.ndarray, n: int, m: int,
                             p: np.ndarray) -> np.ndarray:
        """I_k = Σ_b X^b(β(g_k))·(f⁺_b(g_k, ζ_k) + f⁻_b(g_{k+1}, ζ_{k+1})) − D(g_{k+1},
        ζ_{k+1}) at the forced stages ζ_k of every state (each with its arrow's inputs), D
        the symmetry defect ⟨F⁻L, X(α)⟩ − ⟨F⁺L, X(β)⟩, which vanishes at ζ* but not at
        forced stages: it is the stage forces' work f_ζ·Y along the stages' motion Y
        under the symmetry (docs/conventions.md §22, "The forced Noether balance")."""
        dim = len(self.arrow)
        known = np.ascontiguousarray(states[:, :n].T)
        u = np.ascontiguousarray(states[:, n:n + m].T)
        zeta = self._stages_at(known, p, u)
        f = self._program.numpy_function(["defect"], ["known", "zeta", "p"])
        g = self._impulse_program.numpy_function(["I"], ["a", "b", "za", "zb", "p"])
        with np.errstate(all="ignore"):
            (defect,) = f(known[:, 1:], zeta[:, 1:], p)
            a = np.r_[known[:dim, :-1], u[:, :-1]]
            b = np.r_[known[:dim, 1:], u[:, 1:]]
            (junction,) = g(a, b, zeta[:, :-1], zeta[:, 1:], p)
            out = np.broadcast_to(np.asarray(junction[0], float) - np.asarray(defect[0], float),
                                  (len(states) - 1,))
        _finite_values(out, "impulse", "the forces' impulse", "step")
        return out.copy()

    impulse_form = None  # (I, a, b, inputs at a, inputs at b), set for a forced system
    impulse_refused = ""  # why a forced system has no impulse form

    @functools.cached_property
    def _impulse_program(self) -> Program:
        expr, a, b, ua, ub = self.impulse_form
        g = Graph()
        names = {"a": [*a, *ua], "b": [*b, *ub], "p": list(self.parameters)}
        if self.impulse_stages:
            names.update(za=list(self.impulse_stages[0]), zb=list(self.impulse_stages[1]))
        symbols = {s: g.input(s) for group in names.values() for s in group}
        if not self.impulse_stages:
            return Program(g, names, {"I": [from_sympy(g, expr, symbols,
                                                       "the forces' impulse")]})
        # with stages: Σ_b X^b(β(a))·(f⁺_b(a, ζ_a; u_a) + f⁻_b(b, ζ_b; u_b)) on the graph
        za, zb = self.impulse_stages
        plus = _force_nodes(g, self.forces, self.forces.plus, [symbols[c] for c in a],
                            [symbols[z] for z in za], [symbols[v] for v in ua], symbols)
        minus = _force_nodes(g, self.forces, self.forces.minus, [symbols[c] for c in b],
                             [symbols[z] for z in zb], [symbols[v] for v in ub], symbols)
        X = [from_sympy(g, x, symbols, "the section") for x in expr]
        terms = [g.mul(x, g.add(fp, fm)) for x, fp, fm in zip(X, plus, minus)]
        return Program(g, names, {"I": [g.add(*terms) if terms else g.const(0)]})

    def __repr__(self) -> str:
        verdict = ("symmetry verified" if self.is_symmetry else
                   f"NOT verified to be a symmetry: {self.verification}"
                   if self.verification.startswith("undecided") else
                   "NOT verified to be a symmetry")
        return f"<NoetherQuantity F_X = {self._shown()} ({verdict})>"


def _force_nodes(g: Graph, forces, exprs, arrow: list, zeta: list, u: list,
                 symbols: dict) -> list[int]:
    """The force expressions ``exprs`` (in the forces' slot coordinates, generic stages and
    inputs) at the arrow, stages and inputs whose nodes are given: mapped on the graph,
    never substituted in SymPy (the forces of a Galerkin step on a group are large)."""
    mapping = dict(symbols)
    mapping.update(zip(forces.slot, arrow))
    mapping.update(zip(forces.stages, zeta))
    mapping.update(zip(forces.inputs, u))
    memo: dict = {}
    return [from_sympy(g, e, mapping, "the forces", memo) for e in exprs]


class LiePoissonEquations:
    """μ_{k+1} + λ_{k+1}·Φ_{k+1} = Ad*_{g_k}(μ_k + λ_k·Φ_k) (seed 000 §6.1).

    ``residuals``: that equation (in g_k, g_{k+1}) plus φ(g_{k+1}) = 0 — the Euler–Lagrange
    step rewritten in momentum form.  ``update``: m_{k+1} = Ad*_{g_k} m_k.  ``reconstruction``:
    the :class:`StepEquations` solving μ(g_{k+1}) + λ_{k+1}·Φ(g_{k+1}) = m_{k+1},
    φ(g_{k+1}) = 0 for (g_{k+1}, λ_{k+1}); its ``next_knowns`` are m_{k+2} = Ad*_{g_{k+1}}
    m_{k+1}, so stepping it is the Lie–Poisson integrator.
    """

    def __init__(self, forms: LiePoissonForms):
        _forms_argument(forms, LiePoissonForms, "lie_poisson()", "LiePoissonEquations")
        self.momentum: list = forms.momentum
        self.update: list = forms.update
        self.residuals: list = forms.residuals
        self.momentum_symbols: list = forms.momentum_symbols
        self.reconstruction = StepEquations(forms.reconstruction)

    def latex(self, width=None, document: bool = False) -> str:
        """μ_{k+1} = Ad*_{g_k} μ_k, then 0 = 𝔽⁻L_{k+1} − Ad*_{g_k} 𝔽⁻L_k and the constraints
        (seed 000 §6.1), Ad* printed by name; rows broken to ``width`` pt (default 450); or,
        with ``document``, a standalone document (as a step's: wide lines set smaller, those
        that would not fit reported with a ``WideLinesWarning``)."""
        from ._latex import rows_latex
        from ._momentum_rows import lie_poisson_rows

        return rows_latex(lie_poisson_rows(self, width), flag_argument(document, "document"),
                          f"{self.reconstruction.name}: the Lie–Poisson equations")

    def __repr__(self) -> str:
        return (f"<LiePoissonEquations {self.reconstruction.name!r}: "
                f"{len(self.momentum_symbols)} momenta, {len(self.residuals)} equations; "
                f"reconstruction {len(self.reconstruction)} equations in "
                f"{len(self.reconstruction.unknowns)} unknowns>")
