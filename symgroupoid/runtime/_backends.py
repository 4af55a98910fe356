"""Two interchangeable kernels behind a :class:`~symgroupoid.runtime.Simulator`.

:class:`CKernel` calls the compiled C (through cffi); :class:`NumpyKernel` evaluates the
lambdified SymPy forms and runs the *same* Newton iteration in Python (same convergence
tests, same LU with partial pivoting and singularity threshold), so both backends give the
same trajectories up to rounding.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import sympy as sp

from ..codegen._emit import DEFAULT_OPTIONS

OK, SINGULAR_JACOBIAN, NOT_CONVERGED, NON_FINITE, INVALID_ARGUMENT = range(5)

STATUS_MESSAGES = {
    OK: "converged",
    SINGULAR_JACOBIAN: "singular Jacobian: the discrete Lagrangian is not regular at this step",
    NOT_CONVERGED: "Newton's method reached the iteration cap without converging",
    NON_FINITE: "non-finite value (NaN or infinity) during the step",
    INVALID_ARGUMENT: "invalid argument",
}


@dataclass(frozen=True)
class NewtonOptions:
    """Newton options of a step.

    Converged when |F|_∞ ≤ ``tol_residual`` or the last Newton step was at most
    ``tol_step``·(1 + |u|_∞); at most ``max_iterations`` updates.  With ``extrapolate`` the
    guess of step k ≥ 2 is 2u_{k-1} − u_{k-2} (falling back to ``step.prediction`` if Newton
    fails from it); otherwise every step starts from ``step.prediction``.
    """

    tol_residual: float = DEFAULT_OPTIONS["tol_residual"]
    tol_step: float = DEFAULT_OPTIONS["tol_step"]
    max_iterations: int = DEFAULT_OPTIONS["max_iterations"]
    extrapolate: bool = True

    def __post_init__(self):
        for name in ("tol_residual", "tol_step"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value >= 0):
                raise ValueError(f"{name} must be a finite number >= 0, got {value!r}")
        if int(self.max_iterations) != self.max_iterations or self.max_iterations < 0:
            raise ValueError(f"max_iterations must be an integer >= 0, got "
                             f"{self.max_iterations!r}")


@dataclass
class RawRun:
    """What a kernel's simulate returns (states up to the failing step)."""

    states: np.ndarray  # (n_steps + 1, n_known); rows after a failure are not valid
    iterations: np.ndarray  # (n_steps,) int
    residual_norms: np.ndarray  # (n_steps,)
    status: int
    failed_step: int  # -1 on success
    last_iterate: np.ndarray  # (n_unknown,)


class CKernel:
    """The compiled kernel of a step (a cffi extension module)."""

    name = "c"

    def __init__(self, module, prefix: str, n_unknowns: int, n_knowns: int):
        self.module, self.ffi, self.lib = module, module.ffi, module.lib
        self.prefix, self.n_u, self.n_k = prefix, n_unknowns, n_knowns
        self._f = {n: getattr(self.lib, f"{prefix}_{n}") for n in (
            "residual", "residual_jacobian", "predict", "next_knowns", "solve_step",
            "simulate", "reconstruct")}

    def _options(self, options: NewtonOptions):
        opts = self.ffi.new(f"{self.prefix}_options *")
        opts.tol_residual = options.tol_residual
        opts.tol_step = options.tol_step
        opts.max_iterations = int(options.max_iterations)
        opts.extrapolate = int(bool(options.extrapolate))
        return opts

    def _ptr(self, array: np.ndarray, ctype: str = "double[]"):
        return self.ffi.from_buffer(ctype, array)

    def residual(self, u, known, p) -> np.ndarray:
        F = np.empty(self.n_u)
        self._f["residual"](self._ptr(u), self._ptr(known), self._ptr(p), self._ptr(F))
        return F

    def residual_jacobian(self, u, known, p) -> tuple[np.ndarray, np.ndarray]:
        F, J = np.empty(self.n_u), np.empty((self.n_u, self.n_u))
        self._f["residual_jacobian"](self._ptr(u), self._ptr(known), self._ptr(p),
                                     self._ptr(F), self._ptr(J))
        return F, J

    def predict(self, known, p) -> np.ndarray:
        u = np.empty(self.n_u)
        self._f["predict"](self._ptr(known), self._ptr(p), self._ptr(u))
        return u

    def next_knowns(self, u, known, p) -> np.ndarray:
        out = np.empty(self.n_k)
        self._f["next_knowns"](self._ptr(u), self._ptr(known), self._ptr(p), self._ptr(out))
        return out

    def solve_step(self, known, p, u0, options: NewtonOptions):
        u = np.array(u0, dtype=float)
        it, rn = self.ffi.new("int *"), self.ffi.new("double *")
        status = self._f["solve_step"](self._ptr(known), self._ptr(p), self._options(options),
                                       self._ptr(u), it, rn)
        return int(status), u, int(it[0]), float(rn[0])

    def simulate(self, known0, p, n_steps: int, options: NewtonOptions) -> RawRun:
        states = np.empty((n_steps + 1, self.n_k))
        iterations = np.zeros(n_steps, dtype=np.intc)
        norms = np.zeros(n_steps)
        last = np.zeros(self.n_u)
        failed = self.ffi.new("long *")
        status = self._f["simulate"](
            self._ptr(known0), self._ptr(p), n_steps, self._options(options), self._ptr(states),
            self._ptr(iterations, "int[]"), self._ptr(norms), failed, self._ptr(last))
        return RawRun(states, iterations.astype(np.int64), norms, int(status), int(failed[0]),
                      last)


def norm_inf(v: np.ndarray) -> float:
    """max |v_i|, or a non-finite value if any entry is NaN or infinite (as the C kernel)."""
    a = np.abs(np.asarray(v, dtype=float))
    if a.size == 0:
        return 0.0
    bad = ~np.isfinite(a)
    if bad.any():
        return float(a[np.argmax(bad)])
    return float(a.max())


def lu_solve(A: np.ndarray, b: np.ndarray, scale: float) -> np.ndarray | None:
    """LU with partial pivoting exactly as the C kernel (reciprocal pivots, zero multipliers
    skipped); None when a pivot is not above n·ε·scale."""
    A, b = np.array(A, dtype=float), np.array(b, dtype=float)
    n = len(b)
    tiny = n * np.finfo(float).eps * scale
    inv = np.empty(n)
    for k in range(n):
        piv = k + int(np.argmax(np.abs(A[k:, k])))
        if not abs(A[piv, k]) > tiny:
            return None
        if piv != k:
            A[[k, piv]] = A[[piv, k]]
            b[[k, piv]] = b[[piv, k]]
        inv[k] = 1.0 / A[k, k]
        for i in range(k + 1, n):
            lik = A[i, k] * inv[k]
            if lik != 0.0:
                A[i, k + 1:] -= lik * A[k, k + 1:]
                b[i] -= lik * b[k]
    for i in range(n - 1, -1, -1):
        s = b[i]
        for j in range(i + 1, n):
            s -= A[i, j] * b[j]
        b[i] = s * inv[i]
    return b


class NumpyKernel:
    """The same kernel evaluated with NumPy (lambdified SymPy; Newton in Python)."""

    name = "numpy"

    def __init__(self, step):
        self.step = step
        self.n_u, self.n_k = len(step.unknowns), len(step.knowns)
        args = [list(step.unknowns), list(step.knowns), list(step.parameters)]
        self._F = sp.lambdify(args, sp.Matrix(step.residuals_in_unknowns()), "numpy",
                              cse=True)
        self._J = sp.lambdify(args, step.jacobian(substitute=True), "numpy", cse=True)
        self._next = sp.lambdify(args, sp.Matrix(step.next_knowns), "numpy", cse=True)
        self._pred = sp.lambdify(args[1:], sp.Matrix(step.prediction), "numpy", cse=True)

    def residual(self, u, known, p) -> np.ndarray:
        return np.asarray(self._F(u, known, p), dtype=float).reshape(self.n_u)

    def residual_jacobian(self, u, known, p):
        J = np.asarray(self._J(u, known, p), dtype=float).reshape(self.n_u, self.n_u)
        return self.residual(u, known, p), J

    def predict(self, known, p) -> np.ndarray:
        return np.asarray(self._pred(known, p), dtype=float).reshape(self.n_u)

    def next_knowns(self, u, known, p) -> np.ndarray:
        return np.asarray(self._next(u, known, p), dtype=float).reshape(self.n_k)

    def solve_step(self, known, p, u0, options: NewtonOptions):
        """Newton's method exactly as ``<prefix>_solve_step`` in the C kernel."""
        u = np.array(u0, dtype=float)
        step_norm = 0.0
        it = 0
        with np.errstate(all="ignore"):
            while True:
                if it == 0:
                    F, J = self.residual_jacobian(u, known, p)
                else:
                    F = self.residual(u, known, p)
                rnorm = norm_inf(F)
                if not np.isfinite(rnorm):
                    return NON_FINITE, u, it, rnorm
                if rnorm <= options.tol_residual or (
                        it > 0 and step_norm <= options.tol_step * (1.0 + norm_inf(u))):
                    return OK, u, it, rnorm
                if it >= options.max_iterations:
                    return NOT_CONVERGED, u, it, rnorm
                if it > 0:
                    F, J = self.residual_jacobian(u, known, p)
                jscale = norm_inf(J)
                if not np.isfinite(jscale):
                    return NON_FINITE, u, it, rnorm
                du = lu_solve(J, F, jscale)
                if du is None:
                    return SINGULAR_JACOBIAN, u, it, rnorm
                step_norm = norm_inf(du)
                if not np.isfinite(step_norm):
                    return NON_FINITE, u, it, rnorm
                u = u - du
                it += 1

    def simulate(self, known0, p, n_steps: int, options: NewtonOptions) -> RawRun:
        """As ``<prefix>_simulate``: predict twice, then (with ``options.extrapolate``)
        extrapolate, retrying from the prediction when Newton fails from there."""
        states = np.empty((n_steps + 1, self.n_k))
        states[0] = known0
        iterations = np.zeros(n_steps, dtype=np.int64)
        norms = np.zeros(n_steps)
        u1 = u2 = None
        for k in range(n_steps):
            current = states[k]
            with np.errstate(all="ignore"):
                extrapolated = k >= 2 and options.extrapolate
                u0 = 2.0 * u1 - u2 if extrapolated else self.predict(current, p)
            status, u, iterations[k], norms[k] = self.solve_step(current, p, u0, options)
            if status != OK and extrapolated:  # retry from the prediction
                with np.errstate(all="ignore"):
                    u0 = self.predict(current, p)
                status, u, more, norms[k] = self.solve_step(current, p, u0, options)
                iterations[k] += more
            if status == OK:
                with np.errstate(all="ignore"):
                    states[k + 1] = self.next_knowns(u, current, p)
                if not np.isfinite(norm_inf(states[k + 1])):
                    status = NON_FINITE
            if status != OK:
                return RawRun(states, iterations, norms, status, k, u)
            u1, u2 = u, u1
        return RawRun(states, iterations, norms, OK, -1, np.zeros(self.n_u))
