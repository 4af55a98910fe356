"""Two-point boundary-value problems: the whole discrete trajectory at once.

Discrete optimal control problems (seed 000 §6.1–6.2, seed 001 §3.3) fix the end
configurations (second order: also the first and last arrows) and ask for a critical point
of Σ [L + λ·φ].  The unknowns are, for every free junction j, a variation δ_j ∈ R^rank that
moves the arrows as

    g_j ↦ g_j · h(δ_j),   g_{j+1} ↦ h(δ_j)⁻¹ · g_{j+1},    h(δ) ⊂ α⁻¹(β(g_j)),

— the junction variation of the derivation — so every iterate stays composable with the
end points fixed, plus the multipliers of every term.  The equations are the junction
residuals and the constraints of every term; each depends only on a window of neighbouring
unknowns, so the Jacobian is block-banded.  Its blocks are X⃖ and X⃗ derivatives of the
window residual, derived symbolically once and compiled to C through the same cffi build
cache as the step kernels (evaluated for all windows in one call; NumPy, vectorised over the
windows, without a compiler); the banded system is solved in time linear in N (LAPACK's
banded solver through SciPy when installed, a block-tridiagonal elimination in NumPy
otherwise).

The derivatives are exact but never expanded into expression trees: the window action is
written as a straight-line program of elementary operations (one assignment per distinct
subexpression), and the residual and its slot derivatives are obtained by forward-mode
differentiation of that program along the section fields — the chain rule applied assignment
by assignment.  The program grows linearly with the number of derivatives instead of the
expression swell of differentiating the expanded residual twice.
"""

from __future__ import annotations

import functools
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
import sympy as sp

from .._errors import (
    NewtonDivergenceError,
    NotComposableError,
    ShapeError,
    SingularJacobianError,
)
from .._symbols import multiplier_symbols
from ..derivation._junction import slot
from ..derivation._step import shifted, window
from ._programs import compile_program

# --- symbolic window kernel --------------------------------------------------------------

class _Program:
    """A straight-line program: assignments ``t_j = e_j`` of elementary operations (a sum, a
    product, a power or a function of earlier symbols and the inputs), one per distinct
    subexpression, extended by forward-mode directional derivatives.

    Subexpressions that are not plain arithmetic or functions of expressions (``Piecewise``,
    …) stay whole; their derivatives are taken by SymPy and written as programs in turn.
    """

    def __init__(self):
        self.assignments: list[tuple[sp.Symbol, sp.Expr, tuple]] = []
        self._memo: dict = {}
        self._names = sp.numbered_symbols("t", real=True)

    def node(self, expr) -> sp.Expr:
        """An atom standing for ``expr``, adding the assignments it needs."""
        expr = sp.sympify(expr)
        if expr.is_Atom:
            return expr
        hit = self._memo.get(expr)
        if hit is not None:
            return hit
        if _elementary(expr):
            e = expr.func(*[self.node(a) for a in expr.args])
            if e.is_Atom:
                return e
            deps = tuple(a for a in e.args if a.is_Symbol)
        else:
            e, deps = expr, tuple(expr.free_symbols)
        hit = self._memo.get(e)
        if hit is None:
            hit = next(self._names)
            self.assignments.append((hit, e, deps))
            self._memo[e] = hit
        self._memo[expr] = hit
        return hit

    def tangent(self, targets: Sequence, seed: dict, upto: int | None = None) -> list:
        """d/dt of the atoms ``targets`` along the input tangent ``seed`` (symbol → value),
        through the first ``upto`` assignments; new assignments are appended."""
        tan = {x: self.node(v) for x, v in seed.items() if v != 0}
        for s, e, deps in self.assignments[:upto]:
            if not any(x in tan for x in deps):
                continue
            d = _chain_rule(e, deps, tan)
            if d != 0:
                tan[s] = self.node(d)
        return [tan.get(t, sp.S.Zero) for t in targets]

    def needed(self, outputs: Sequence) -> tuple[list[tuple[sp.Symbol, sp.Expr]], list]:
        """The assignments the outputs depend on, in order, with their targets renamed so
        that a name is reused once its value is dead (evaluated on arrays of windows, this
        keeps the live temporaries few instead of one per assignment); and the outputs in
        the new names."""
        outputs = [sp.sympify(o) for o in outputs]
        need: set = set()
        for o in outputs:
            need |= o.free_symbols
        keep = []
        for s, e, _ in reversed(self.assignments):
            if s in need:
                keep.append((s, e))
                need |= e.free_symbols
        keep.reverse()
        last: dict = {}
        for i, (_, e) in enumerate(keep):
            for x in e.free_symbols:
                last[x] = i
        for o in outputs:
            for x in o.free_symbols:
                last[x] = len(keep)
        names = sp.numbered_symbols("r", real=True)
        free: list = []
        rename: dict = {}
        out = []
        for i, (s, e) in enumerate(keep):
            renamed = e.xreplace(rename)
            free += [rename[x] for x in e.free_symbols if x in rename and last[x] == i]
            rename[s] = free.pop() if free else next(names)
            out.append((rename[s], renamed))
        return out, [o.xreplace(rename) for o in outputs]


def _elementary(expr) -> bool:
    return ((expr.is_Add or expr.is_Mul or expr.is_Pow or isinstance(expr, sp.Function))
            and all(isinstance(a, sp.Expr) for a in expr.args)
            and not isinstance(expr, sp.Piecewise))


def _chain_rule(e, deps, tan) -> sp.Expr:
    """Directional derivative of one assignment from the tangents of its dependencies."""
    if e.is_Add:
        return sp.Add(*[tan[a] for a in e.args if a in tan])
    if e.is_Mul:
        args = e.args
        return sp.Add(*[sp.Mul(tan[a], *args[:i], *args[i + 1:])
                        for i, a in enumerate(args) if a in tan])
    if e.is_Pow:
        b, n = e.args
        out = n * b ** (n - 1) * tan[b] if b in tan else sp.S.Zero
        return out + (sp.log(b) * e * tan[n] if n in tan else 0)
    return sp.Add(*[sp.diff(e, x) * tan[x] for x in deps if x in tan])


def _vectorised(args, outputs, program: _Program, label: str):
    """Evaluate the program's outputs for W windows: (W, n_args) → (W, n_outputs).

    Compiled to C through the kernel cache when a compiler is available (the same build path
    as the step kernels); NumPy (lambdify, vectorised over windows) otherwise."""
    assignments, outs = program.needed(outputs)
    compiled = compile_program(label, args, assignments, outs)
    if compiled is not None:
        def call_c(values: np.ndarray) -> np.ndarray:
            with np.errstate(all="ignore"):
                return compiled(values)

        return call_c
    f = sp.lambdify(args, outputs, "numpy", cse=program.needed)

    def call(values: np.ndarray) -> np.ndarray:
        with np.errstate(all="ignore"):  # non-finite values are detected by the caller
            out = f(*values.T)
        return np.array([np.broadcast_to(np.asarray(o, float), (len(values),))
                         for o in out]).T

    return call


def _seed(coords: Sequence, field: Sequence, sign: int = 1) -> dict:
    return {c: sign * v for c, v in zip(coords, field) if v != 0}


class WindowKernel:
    """Residuals of one junction and of one term, with their slot derivatives.

    For the junction residual r (rank rows) and each slot o of the window:
    ``left[o]`` = X⃖_b[r_i] on slot o and ``right[o]`` = X⃗_b[r_i] on slot o (rank × rank),
    and ``dlam[s]`` = ∂r/∂λ_s; likewise for the constraints of the term starting at 0.

    The window action S = Σ_s [L + λ_s·Φ](terms starting at s) (seed 001 eq. (17)) becomes a
    :class:`_Program`; the junction residual r_b = X⃖_b[S](g_j) − X⃗_b[S](g_{j+1}) is its
    derivative along the left field of section b on slot 0 and minus the right field on slot
    1 (the junction variation, docs/conventions.md §2), and each block a derivative of r along one
    section field on one slot.
    """

    def __init__(self, system):
        G, fs = system.groupoid, system._fs
        self.groupoid, self.rank, self.m = G, G.rank, len(fs.constraints)
        self.arity = len(fs.slots)
        self.offsets, self.starts = window(self.arity)
        self.parameters = list(system.parameters)
        r, m, arity = self.rank, self.m, self.arity
        A = {o: slot(G, f"v{o + 2}_") for o in self.offsets}
        lam = {s: multiplier_symbols(m, s) for s in self.starts}
        S = sum((shifted(fs, [A[s + i] for i in range(arity)], lam[s]) for s in self.starts),
                sp.S.Zero)
        constraints = shifted(fs, [A[i] for i in range(arity)], [1] * m, lagrangian=False,
                              separate=True)
        # plain identifiers for every input, so the generated code needs no renaming
        inputs = ([c for o in self.offsets for c in A[o]]
                  + [x for s in self.starts for x in lam[s]] + self.parameters)
        plain = {x: sp.Symbol(f"a{i}", real=True) for i, x in enumerate(inputs)}
        A = {o: tuple(plain[c] for c in A[o]) for o in self.offsets}
        lam = {s: [plain[x] for x in lam[s]] for s in self.starts}
        params = [plain[x] for x in self.parameters]
        fields = {o: (G.left_field(A[o]), G.right_field(A[o])) for o in self.offsets}

        P = _Program()
        action = P.node(S.xreplace(plain))
        res = [P.tangent([action], {**_seed(A[0], fields[0][0][b]),
                                    **_seed(A[1], fields[1][1][b], -1)})[0] for b in range(r)]
        base = len(P.assignments)
        blocks = list(res)
        for o in self.offsets:
            d = {(side, c): P.tangent(res, _seed(A[o], fields[o][side][c]), base)
                 for side in (0, 1) for c in range(r)}
            for b in range(r):
                blocks += [d[side, c][b] for side in (0, 1) for c in range(r)]
        for s in self.starts:
            d = [P.tangent(res, {x: 1}, base) for x in lam[s]]
            blocks += [d[a][b] for b in range(r) for a in range(m)]
        coords = [c for o in self.offsets for c in A[o]]
        lams = [x for s in self.starts for x in lam[s]]
        self._junction = _vectorised(coords + lams + params, blocks, P,
                                     f"{system.name}_junction")

        self._term = None
        if m:
            Q = _Program()
            values = [Q.node(c.xreplace(plain)) for c in constraints]
            base = len(Q.assignments)
            cblocks = list(values)
            for o in range(arity):
                d = {(side, c): Q.tangent(values, _seed(A[o], fields[o][side][c]), base)
                     for side in (0, 1) for c in range(r)}
                for e in range(m):
                    cblocks += [d[side, c][e] for side in (0, 1) for c in range(r)]
            ccoords = [x for o in range(arity) for x in A[o]]
            self._term = _vectorised(ccoords + params, cblocks, Q, f"{system.name}_term")

    def junction(self, windows: np.ndarray, lams: np.ndarray, params: np.ndarray):
        """All junction blocks for W windows: windows (W, slots, arrow_dim), lams (W, starts, m)."""
        W = len(windows)
        vals = np.hstack([windows.reshape(W, -1), lams.reshape(W, -1),
                          np.broadcast_to(params, (W, len(params)))])
        out = self._junction(vals)  # (W, total)
        r, k = self.rank, 0
        res = out[:, k:k + r]
        k += r
        left, right = {}, {}
        for o in self.offsets:
            blk = out[:, k:k + 2 * r * r].reshape(W, r, 2, r)
            left[o], right[o] = blk[:, :, 0, :], blk[:, :, 1, :]
            k += 2 * r * r
        dlam = {}
        for s in self.starts:
            dlam[s] = out[:, k:k + r * self.m].reshape(W, r, self.m)
            k += r * self.m
        return res, left, right, dlam

    def term(self, windows: np.ndarray, params: np.ndarray):
        """Constraint values and slot derivatives for T terms: windows (T, arity, arrow_dim)."""
        T, m, r = len(windows), self.m, self.rank
        vals = np.hstack([windows.reshape(T, -1), np.broadcast_to(params, (T, len(params)))])
        out = self._term(vals)
        res = out[:, :m]
        left, right, k = {}, {}, m
        for o in range(self.arity):
            blk = out[:, k:k + 2 * m * r].reshape(T, m, 2, r)
            left[o], right[o] = blk[:, :, 0, :], blk[:, :, 1, :]
            k += 2 * m * r
        return res, left, right


@functools.lru_cache(maxsize=8)
def window_kernel(system) -> WindowKernel:
    """The (cached) window kernel of a system."""
    return WindowKernel(system)


# --- numeric structure maps ------------------------------------------------------------------

@functools.lru_cache(maxsize=16)
def _maps(G) -> _Maps:
    return _Maps(G)


class _Maps:
    def __init__(self, G):
        a = G._generic_arrow
        b = tuple(sp.Dummy(f"b{i}") for i in range(G.arrow_dim))
        d = tuple(sp.Dummy(f"d{i}") for i in range(G.rank))
        self.G = G
        self._mul = sp.lambdify([a, b], list(G.multiply(a, b)), "numpy")
        self._inv = sp.lambdify([a], list(G.inverse(a)), "numpy")
        q = G.target(a)
        self._flow = sp.lambdify([a, d], list(G.section_flow(q, d)), "numpy")

    @staticmethod
    def _rows(values, n):
        return np.array([np.broadcast_to(np.asarray(v, float), (n,)) for v in values]).T

    def multiply(self, A, B):
        return self._rows(self._mul(A.T, B.T), len(A))

    def inverse(self, A):
        return self._rows(self._inv(A.T), len(A))

    def flow_at_target(self, A, D):
        """h(δ) ⊂ α⁻¹(β(A)) for each row."""
        return self._rows(self._flow(A.T, D.T), len(A))


# --- the solution --------------------------------------------------------------------------

@dataclass
class BoundaryValueSolution:
    """A solved two-point problem: arrows g_1 … g_N, multipliers per term, and diagnostics.

    ``arrows`` (N, arrow_dim); ``multipliers`` (terms, m) — the costates of optimal control;
    ``controls`` (N, rank) — chart coordinates of each arrow (Lie groups: τ⁻¹(g_k) = hξ_k);
    ``configurations`` — the N + 1 configurations; ``sol[name]`` — a named part of every
    arrow (``"x"``: the target point of each arrow; ``"g"``: each arrow's matrix; …).
    """

    system: object
    arrows: np.ndarray
    multipliers: np.ndarray
    configurations: list
    parameters: dict
    iterations: int
    residual_norm: float
    history: list = field(default_factory=list)
    seconds: float = 0.0

    @property
    def steps(self) -> int:
        return len(self.arrows)

    @functools.cached_property
    def controls(self) -> np.ndarray:
        G = self.system.groupoid
        return np.array([G.fibre_chart_inverse(G.fibre_of(a), G.source(a))
                         for a in self.arrows], float)

    def __getitem__(self, name: str) -> np.ndarray:
        G = self.system.groupoid
        table = G.symbols_by_name(0)
        if name not in table:
            raise KeyError(f"no part named {name!r}; available: {sorted(table)}")
        position = {s: i for i, s in enumerate(G.named_arrow(0)) if isinstance(s, sp.Symbol)}
        value = table[name]
        entries = value if isinstance(value, sp.MatrixBase) else sp.Matrix([value])
        out = np.empty((len(self.arrows),) + entries.shape)
        for idx in np.ndindex(*entries.shape):
            e = entries[idx]
            out[(slice(None),) + idx] = (self.arrows[:, position[e]] if e in position
                                         else float(e))
        return out if isinstance(value, sp.MatrixBase) else out[:, 0, 0]

    def __repr__(self) -> str:
        return (f"<BoundaryValueSolution {self.system.name!r}: {self.steps} arrows, "
                f"{self.iterations} Newton iterations, |F| = {self.residual_norm:.2e}>")


# --- linear algebra --------------------------------------------------------------------------

def _solve_banded(rows, cols, vals, n, rhs) -> np.ndarray:
    """Solve the sparse banded system (COO triplets) in time linear in its size."""
    kl = int(np.max(rows - cols, initial=0))
    ku = int(np.max(cols - rows, initial=0))
    try:
        from scipy.linalg import solve_banded
    except ImportError:  # pragma: no cover - exercised by forcing the fallback in tests
        return _block_tridiagonal(rows, cols, vals, n, rhs, max(kl, ku))
    ab = np.zeros((kl + ku + 1, n))
    np.add.at(ab, (ku + rows - cols, cols), vals)
    return solve_banded((kl, ku), ab, rhs)


def _block_tridiagonal(rows, cols, vals, n, rhs, band) -> np.ndarray:
    """Block elimination with blocks of size ``band`` (≥ the bandwidth), so the matrix is
    block tridiagonal; each diagonal block is LU-factorised with pivoting by NumPy."""
    b = max(band, 1)
    nb = -(-n // b)
    size = nb * b
    D = np.zeros((nb, b, b))
    L = np.zeros((nb, b, b))
    U = np.zeros((nb, b, b))
    bi, bj = rows // b, cols // b
    for arr, mask in ((D, bi == bj), (L, bi == bj + 1), (U, bi + 1 == bj)):
        np.add.at(arr, (bi[mask], rows[mask] % b, cols[mask] % b), vals[mask])
    pad = np.arange(n, size)
    D[pad // b, pad % b, pad % b] = 1.0
    y = np.zeros(size)
    y[:n] = rhs
    y = y.reshape(nb, b)
    for k in range(1, nb):
        F = np.linalg.solve(D[k - 1].T, L[k].T).T
        D[k] -= F @ U[k - 1]
        y[k] -= F @ y[k - 1]
    x = np.zeros_like(y)
    x[-1] = np.linalg.solve(D[-1], y[-1])
    for k in range(nb - 2, -1, -1):
        x[k] = np.linalg.solve(D[k], y[k] - U[k] @ x[k + 1])
    return x.ravel()[:n]


# --- the solver --------------------------------------------------------------------------------

@dataclass
class _Layout:
    """Positions of the unknowns (δ_j, λ_t) and equations (DEL_j, Φ_t) in the banded system."""

    junctions: np.ndarray
    terms: np.ndarray
    delta_index: dict
    lam_index: dict
    size: int


def _layout(n: int, arity: int, rank: int, m: int) -> _Layout:
    junctions = np.arange(arity - 1, n - arity)
    terms = np.arange(0, n - arity + 1)
    delta_index, lam_index, k = {}, {}, 0
    term_set = set(terms.tolist())
    for p in range(n + 1):  # interleave by position: λ_p then δ_p
        if m and p in term_set:
            lam_index[p] = k
            k += m
        if arity - 1 <= p < n - arity:
            delta_index[p] = k
            k += rank
    return _Layout(junctions, terms, delta_index, lam_index, k)


def _parameter_vector(system, params) -> tuple[np.ndarray, dict]:
    if params is None:
        params = {}
    if isinstance(params, Mapping):
        values, named = [], {}
        for s in system.parameters:
            if s in params:
                v = params[s]
            elif str(s) in params:
                v = params[str(s)]
            else:
                raise KeyError(f"{system.name}: missing parameter {s}")
            values.append(float(v))
            named[str(s)] = float(v)
        return np.array(values), named
    values = np.asarray(params, float)
    if values.shape != (len(system.parameters),):
        raise ShapeError(f"{system.name}: expected {len(system.parameters)} parameters "
                         f"({', '.join(map(str, system.parameters))}), got {values.shape}")
    return values, {str(s): float(v) for s, v in zip(system.parameters, values)}


def interpolate_arrows(G, total: Sequence, steps: int) -> np.ndarray:
    """N arrows whose product is ``total``: P_k = (q, chart⁻¹ interpolated k/N of the way
    from the identity to ``total`` in the fibre chart), g_k = P_{k−1}⁻¹ P_k."""
    total = np.asarray(total, float)
    q = tuple(G.source(total))
    x_id = np.asarray(G.fibre_chart_inverse(G.fibre_of(G.identity(q)), q), float)
    x_end = np.asarray(G.fibre_chart_inverse(G.fibre_of(tuple(total)), q), float)
    maps = _maps(G)
    P = [np.asarray(G.identity(q), float)]
    for k in range(1, steps + 1):
        f = G.numeric_fibre_chart(x_id + (x_end - x_id) * k / steps, q)
        P.append(np.array([float(v) for v in G.arrow_from(q, f)]))
    P = np.array(P)
    return maps.multiply(maps.inverse(P[:-1]), P[1:])


def solve_boundary_value(step_equations, start, end, steps: int, guess=None, params=None, *,
                         tol: float = 1e-10, tol_step: float = 1e-9,
                         max_iterations: int = 30) -> BoundaryValueSolution:
    """Solve a discrete two-point problem for the system behind ``step_equations``.

    First order: ``start`` and ``end`` are the end configurations (pair groupoid: points;
    Lie group: matrices; products: tuples).  Second order: ``start = (c₀, c₁)`` and
    ``end = (c_{N−1}, c_N)``, fixing the first and last arrows too.  ``guess``: N arrows
    (N, arrow_dim), optionally with multipliers as ``(arrows, multipliers)``; default: the
    interpolation of :func:`interpolate_arrows` and zero multipliers.

    Converged when |F|∞ < ``tol``, or after a Newton update below ``tol_step``·(1 + |λ|∞):
    Newton's quadratic convergence (the Jacobian is exact) leaves an error of the order of
    its square, so the iterate is then at the residual's rounding floor — which grows with
    N (for a residual scaled like 1/h², about N² ε), so a fixed absolute ``tol`` alone
    would fail for large N.  Raises :class:`NewtonDivergenceError` naming the worst step
    when Newton does not converge.
    """
    system = getattr(step_equations, "system", step_equations)
    G = system.groupoid
    a = len(system._fs.slots)
    if steps < 2 * a:
        raise ShapeError(f"{system.name}: a problem of order {a} needs at least {2 * a} "
                         f"steps, got {steps}")
    p, named = _parameter_vector(system, params)
    r, m = G.rank, len(system._fs.constraints)
    arrows, lam, first, last = _initial(system, a, m, start, end, steps, guess)
    kernel = window_kernel(system)
    lay = _layout(steps, a, r, m)
    maps = _maps(G)
    t0, history = time.perf_counter(), []
    F, rows, cols, vals, worst = _assemble(kernel, lay, arrows, lam, p)
    for it in range(max_iterations + 1):
        norm = float(np.max(np.abs(F))) if F.size else 0.0
        history.append(norm)
        if not np.all(np.isfinite(F)) or not np.all(np.isfinite(vals)):
            raise NewtonDivergenceError(
                f"{system.name}: non-finite residual or Jacobian at Newton iteration {it}, "
                f"step {worst}", step=worst, residual_norm=norm, iterate=arrows)
        if norm < tol:
            break
        if it == max_iterations:
            raise NewtonDivergenceError(
                f"{system.name}: boundary-value Newton did not converge in {max_iterations} "
                f"iterations; |F|∞ = {norm:.3e}, worst at step {worst}",
                step=worst, residual_norm=norm, iterate=arrows)
        try:
            dz = _solve_banded(rows, cols, vals, lay.size, -F)
        except np.linalg.LinAlgError as exc:
            raise SingularJacobianError(
                f"{system.name}: singular boundary-value Jacobian at Newton iteration {it} "
                f"(|F|∞ = {norm:.3e}, worst at step {worst}); the boundary data may violate "
                "the constraints or the Lagrangian is not regular there",
                step=worst, residual_norm=norm, iterate=arrows) from exc
        arrows, lam, (F, rows, cols, vals, worst) = _line_search(
            kernel, lay, maps, arrows, lam, dz, F, p)
        scale = 1.0 + (float(np.max(np.abs(lam))) if lam.size else 0.0)
        if float(np.max(np.abs(dz))) <= tol_step * scale:
            norm = float(np.max(np.abs(F))) if F.size else 0.0
            history.append(norm)
            it += 1
            break
    configurations = [start if a == 1 else start[0]]
    for g in arrows:
        configurations.append(G.configuration_after(configurations[-1], g))
    return BoundaryValueSolution(system, arrows, lam, configurations, named, it, norm, history,
                                 time.perf_counter() - t0)


def _initial(system, a, m, start, end, steps, guess):
    G = system.groupoid
    if a == 1:
        total = G.arrow_between(start, end)
        first = last = None
    else:
        try:
            (c0, c1), (cn1, cn) = start, end
        except (TypeError, ValueError) as exc:
            raise ShapeError(f"{system.name}: second-order boundary data are two "
                             "configurations at each end: start=(c0, c1), end=(cN-1, cN)") from exc
        first = np.asarray(G.arrow_between(c0, c1), float)
        last = np.asarray(G.arrow_between(cn1, cn), float)
        total = G.arrow_between(c0, cn)
    n_terms = steps - a + 1
    if guess is None:
        if a == 1:
            arrows = interpolate_arrows(G, total, steps)
        else:
            inner = interpolate_arrows(G, G.arrow_between(c1, cn1), steps - 2)
            arrows = np.vstack([first, inner, last])
        lam = np.zeros((n_terms, m))
    else:
        arrows, lam = (guess if isinstance(guess, tuple) else (guess, None))
        arrows = np.array(arrows, float)
        if arrows.shape != (steps, G.arrow_dim):
            raise ShapeError(f"{system.name}: guess must have shape ({steps}, {G.arrow_dim}) "
                             f"(one arrow per step), got {arrows.shape}")
        lam = np.zeros((n_terms, m)) if lam is None else np.array(lam, float)
        if lam.shape != (n_terms, m):
            raise ShapeError(f"{system.name}: multiplier guess must have shape "
                             f"({n_terms}, {m}), got {lam.shape}")
        _check_guess(system, arrows, total, first, last)
    return arrows, lam, first, last


def _check_guess(system, arrows, total, first, last):
    G = system.groupoid
    maps = _maps(G)
    for k in range(1, len(arrows)):
        if not np.allclose(G.target(arrows[k - 1]), G.source(arrows[k]), atol=1e-9):
            raise NotComposableError(f"{system.name}: guess arrows {k - 1} and {k} are not "
                                     "composable (β(g_{k-1}) ≠ α(g_k))")
    product = arrows[0:1]
    for k in range(1, len(arrows)):
        product = maps.multiply(product, arrows[k:k + 1])
    if not np.allclose(product[0], total, atol=1e-8):
        raise NotComposableError(f"{system.name}: the guess does not join the boundary "
                                 "configurations (its product differs from start⁻¹·end)")
    if first is not None and not (np.allclose(arrows[0], first) and
                                  np.allclose(arrows[-1], last)):
        raise ShapeError(f"{system.name}: a second-order guess must keep the fixed first and "
                         "last arrows")


def _line_search(kernel, lay, maps, arrows, lam, dz, F, p):
    """Backtracking on |F|₂: the full Newton step when it reduces the residual (always near
    a solution, so convergence stays quadratic), else halve it (at most 12 times)."""
    r, m = kernel.rank, kernel.m
    f0 = float(F @ F)
    step = 1.0
    for _ in range(12):
        new_arrows, new_lam = _update(maps, lay, arrows, lam, step * dz, r, m)
        assembled = _assemble(kernel, lay, new_arrows, new_lam, p)
        Fn = assembled[0]
        if np.all(np.isfinite(Fn)) and float(Fn @ Fn) <= (1 - 1e-4 * step) * f0:
            return new_arrows, new_lam, assembled
        step /= 2
    return new_arrows, new_lam, assembled


def _assemble(kernel, lay, arrows, lam, p):
    a, r, m = kernel.arity, kernel.rank, kernel.m
    rows, cols, vals = [], [], []
    F = np.zeros(lay.size)
    J = lay.junctions
    worst_val, worst = -1.0, 0
    if len(J):
        windows = np.stack([arrows[J + o] for o in kernel.offsets], axis=1)
        lams = (np.stack([lam[J + s] for s in kernel.starts], axis=1) if m
                else np.zeros((len(J), len(kernel.starts), 0)))
        res, left, right, dlam = kernel.junction(windows, lams, p)
        eq = np.array([lay.delta_index[j] for j in J])
        F[eq[:, None] + np.arange(r)] = res
        for o in kernel.offsets:  # arrow j+o moves with δ_{j+o} (left) and δ_{j+o−1} (right)
            _add(rows, cols, vals, lay.delta_index, eq, J + o, left[o], r)
            _add(rows, cols, vals, lay.delta_index, eq, J + o - 1, -right[o], r)
        for s in kernel.starts:
            _add(rows, cols, vals, lay.lam_index, eq, J + s, dlam[s], m)
        bad = np.max(np.abs(res), axis=1)
        if bad.max() > worst_val:
            worst_val, worst = bad.max(), int(J[np.argmax(bad)]) + 1
    if m:
        T = lay.terms
        windows = np.stack([arrows[T + o] for o in range(a)], axis=1)
        res, left, right = kernel.term(windows, p)
        eq = np.array([lay.lam_index[t] for t in T])
        F[eq[:, None] + np.arange(m)] = res
        for o in range(a):
            _add(rows, cols, vals, lay.delta_index, eq, T + o, left[o], r, m)
            _add(rows, cols, vals, lay.delta_index, eq, T + o - 1, -right[o], r, m)
        bad = np.max(np.abs(res), axis=1)
        if bad.max() > worst_val:
            worst_val, worst = bad.max(), int(T[np.argmax(bad)]) + 1
    return (F, np.concatenate(rows), np.concatenate(cols), np.concatenate(vals), worst)


def _add(rows, cols, vals, index, eq, targets, block, width, height=None):
    """Scatter ``block[w]`` (height × width) at equation row ``eq[w]`` and the unknowns of
    ``targets[w]`` in ``index`` (skipping targets that are not unknowns)."""
    height = block.shape[1] if height is None else height
    keep = np.array([t in index for t in targets], bool)
    if not keep.any():
        return
    start = np.array([index[t] for t in targets[keep]])
    ii = eq[keep][:, None, None] + np.arange(height)[None, :, None]
    jj = start[:, None, None] + np.arange(width)[None, None, :]
    ii, jj = np.broadcast_arrays(ii, jj)
    rows.append(ii.ravel())
    cols.append(jj.ravel())
    vals.append(block[keep].reshape(-1))


def _update(maps, lay, arrows, lam, dz, r, m):
    n = len(arrows)
    D = np.zeros((n + 1, r))
    for j, k in lay.delta_index.items():
        D[j] = dz[k:k + r]
    arrows = arrows.copy()
    moved = np.array(sorted(lay.delta_index))
    if len(moved):
        H = maps.flow_at_target(arrows[moved], D[moved])
        arrows[moved] = maps.multiply(arrows[moved], H)  # g_j · h(δ_j)
        arrows[moved + 1] = maps.multiply(maps.inverse(H), arrows[moved + 1])  # h⁻¹ · g_{j+1}
    lam = lam.copy()
    for t, k in lay.lam_index.items():
        lam[t] += dz[k:k + m]
    return arrows, lam
