"""The pair groupoid G × G ⇉ G of SO(n) or SE(n) in left-trivialised (increment) coordinates.

The map (q₀, q₁) ↦ (q₀, q₀⁻¹q₁) identifies the pair groupoid of a Lie group G with the action
groupoid G ⋉ G (seed 001 §2.1.1: G acting on itself by right multiplication).  An arrow is
stored as the configuration q₀ and the *offset* D = F − I of the increment F = q₀⁻¹q₁:

    α(q, D) = q,   β(q, D) = q(I + D),   (q, D)(q(I + D), D') = (q, D + D' + DD'),
    ε(q) = (q, 0),   (q, D)⁻¹ = (q(I + D), F⁻¹ − I)   (Dᵀ on SO(n)),

and a step solves for the retraction coordinates x of the newest increment,
D = τ(x) − I (docs/conventions.md §18).

Why the offset: the equations of a Lie group variational integrator depend on the increment
(tr(F J_d)/h, R(F − I)ℓ/h), which is I + O(h).  Stored as q_{k+1} = q_k·τ(x) (the
:class:`PairGroupoid` of the group), every step re-forms F_k = q_kᵀq_{k+1} from rounded
entries of size 1, an error of ~1e-16 relative to the entries of F − I ~ h, which the 1/h of
the Lagrangian turns into a random kick of ~1e-14 to the Noether momenta per step.  Stored
as D, the increment a step solved for is the increment the next step reads, bit for bit.
The configuration q_{k+1} = q_k(I + D_k) a step stores is renormalised
(:meth:`renormalised_arrow`), so that it stays on the group over any number of steps.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import sympy as sp

from .._arguments import instance_argument, name_argument
from .._errors import InputTypeError
from .._symbols import StepSymbol, latex_name, printable_name, subscripted
from ._base import Arrow, Groupoid
from ._matrix_groups import MatrixLieGroup


class TrivialisedArrow(Arrow):
    """An arrow (q, F − I): ``.source`` = q, ``.increment`` = F = q⁻¹·target, ``.target`` =
    q·F (matrices).  Write a Lagrangian through ``.increment`` (F − I then cancels exactly
    to the stored offset) rather than through ``.source.T * .target``."""

    @property
    def source(self) -> sp.Matrix:
        G = self.groupoid
        return G.group.matrix(self.coords[: G.base_dim])

    @property
    def increment(self) -> sp.Matrix:
        G = self.groupoid
        return sp.eye(G.group.n) + G.offset_matrix(self.coords[G.base_dim:])

    @property
    def target(self) -> sp.Matrix:
        return self.source * self.increment


class TrivialisedPairGroupoid(Groupoid):
    """G × G ⇉ G in coordinates (q₀, q₀⁻¹q₁ − I) for G = SO(2), SO(3), SE(2) or SE(3)
    (``SO3("R")``, ``SE3("g")``); see the module docstring.

    ``increment``: the name of the increment F = q₀⁻¹q₁ in states and LaTeX (default "F"
    followed by what follows a leading "R" in the group's name: ``SO3("R2")`` → "F2").
    The state of a step holds q_{k−1} (named as the group) and F_{k−1} (named
    ``increment``); states give F as a matrix, stored as F − I.
    """

    def __init__(self, group: MatrixLieGroup, increment: str | None = None):
        owner = "TrivialisedPairGroupoid"
        instance_argument(group, MatrixLieGroup, "group",
                          "a matrix Lie group (SO3('R'), SE3('g'), …)", owner=owner)
        linear = group.n - 1 if group.affine else group.n
        if not group.rotation_block or group.rotation_block < linear:
            raise InputTypeError(f"{owner}: {group.name} has no rotation block over its whole "
                                 f"linear part; increment coordinates are implemented for "
                                 f"SO(2), SO(3), SE(2) and SE(3) (use PairGroupoid for "
                                 f"{group.name})")
        if increment is None:
            name = group.symbol_name
            increment = "F" + (name[1:] if name.startswith("R") else name)
        self.increment_name = printable_name(
            name_argument(increment, "the increment's name", owner=owner),
            "the increment's name", owner)
        if self.increment_name == group.symbol_name:
            raise InputTypeError(f"{owner}: the increment needs a name other than the "
                                 f"group's ({group.symbol_name!r})")
        self.group = group
        self.increment_latex = latex_name(self.increment_name)
        self.name = f"pair groupoid of {group.name}, in increments {self.increment_name}"

    # --- sizes ------------------------------------------------------------------------------
    @property
    def arrow_dim(self) -> int:
        return 2 * self.group.arrow_dim

    @property
    def base_dim(self) -> int:
        return self.group.arrow_dim

    @property
    def rank(self) -> int:
        return self.group.rank

    # --- matrices of coordinates ------------------------------------------------------------
    def offset_matrix(self, d: Sequence) -> sp.Matrix:
        """The n×n matrix D = F − I of offset coordinates: the group's free entries (all
        of them on SO(n); SE(n)'s last row is zero)."""
        n = self.group.n
        D = sp.zeros(n, n)
        for (i, j), v in zip(self.group._free, d):
            D[i, j] = v
        return D

    def _offset(self, D: sp.Matrix) -> tuple:
        return tuple(D[i, j] for i, j in self.group._free)

    def _numeric_offset(self, d: Sequence) -> np.ndarray:
        """:meth:`offset_matrix` of numeric offsets (NumPy)."""
        D = np.zeros((self.group.n, self.group.n))
        for (i, j), v in zip(self.group._free, d):
            D[i, j] = float(v)
        return D

    def _split(self, a: Sequence) -> tuple[tuple, tuple]:
        n = self.base_dim
        return tuple(a[:n]), tuple(a[n:])

    # --- structure maps -----------------------------------------------------------------------
    def source(self, a):
        return self._split(a)[0]

    def target(self, a):
        """q(I + D) = q + qD."""
        q, d = self._split(a)
        G = self.group
        Q = G.matrix(q)
        return G.entries(Q + Q * self.offset_matrix(d))

    def renormalised_arrow(self, a):
        """The arrow with its configuration q renormalised (:meth:`renormalised_matrix`:
        the identity on the group): a step stores q_{k+1} = q_k(I + D_k) so."""
        q, d = self._split(a)
        G = self.group
        return G.entries(G.renormalised_matrix(G.matrix(q))) + d

    def multiply(self, a, b):
        q, d = self._split(a)
        D, E = self.offset_matrix(d), self.offset_matrix(self._split(b)[1])
        return q + self._offset(D + E + D * E)

    def identity(self, q):
        return tuple(q) + (sp.S.Zero,) * self.base_dim

    def inverse(self, a):
        """(q(I + D), F⁻¹ − I): on a rotation group F⁻¹ − I = Dᵀ exactly; on SE(n), with
        F = [[I + D_R, p], [0, 1]], F⁻¹ − I = [[D_Rᵀ, −(I + D_R)ᵀp], [0, 0]]."""
        D = self.offset_matrix(self._split(a)[1])
        m = self.group.rotation_block
        out = sp.zeros(*D.shape)
        out[:m, :m] = D[:m, :m].T
        if self.group.affine:
            out[:m, m] = -(sp.eye(m) + D[:m, :m]).T * D[:m, m]
        return tuple(self.target(a)) + self._offset(out)

    def section_curves(self, q, t):
        return [tuple(q) + self.fibre_chart([t if b == a else 0 for b in range(self.rank)])
                for a in range(self.rank)]

    def arrow_from(self, q, f):
        return tuple(q) + tuple(f)

    def field_nodes(self, g, side, coords, parameters=None):
        """Closed form of the fields at (q, D), on the expression graph ``g``: with
        h_b(t) = (·, τ(tE_b) − I), m(a, h_b(t)) = (q, D + T + DT), T = τ(tE_b) − I, so
        X⃖_b = (0, (I + D)E_b); m(h_b(t)⁻¹, a) = (qτ(tE_b), τ(tE_b)⁻¹(I + D) − I), so
        X⃗_b = (−qE_b, E_b(I + D)) (τ(tE) = I + tE + O(t²) for the Cayley map and exp)."""
        G, n = self.group, self.group.n
        coords = list(coords)
        eye = sp.eye(n)
        q = [[g.const(eye[i, j]) for j in range(n)] for i in range(n)]
        W = [[g.const(eye[i, j]) for j in range(n)] for i in range(n)]
        for k, (i, j) in enumerate(G._free):
            q[i][j] = coords[k]
            d = coords[self.base_dim + k]
            W[i][j] = g.add(d, g.one) if i == j else d

        def product(A, B, negate: bool = False) -> list[int]:
            out = []
            for i, j in G._free:
                terms = [g.mul(a, b) for a, b in ((A(i, k), B(k, j)) for k in range(n))
                         if a is not None and b is not None]
                total = g.add(*terms) if terms else g.zero
                out.append(g.neg(total) if negate else total)
            return out

        zeros = [g.zero] * self.base_dim
        fields = []
        for E in G.basis_matrices():
            def basis(i, k, E=E):
                return g.const(E[i, k]) if E[i, k] != 0 else None

            if side == "left":
                fields.append(zeros + product(lambda i, k: W[i][k], basis))
            else:
                fields.append(product(lambda i, k: q[i][k], basis, negate=True)
                              + product(basis, lambda i, k: W[i][k]))
        return fields

    def fibre_of(self, a):
        return self._split(a)[1]

    # --- the chart of an α-fibre: D = τ(x) − I -------------------------------------------------
    def fibre_chart(self, x, source=None):
        """τ(x) − I.  Cayley: the rotation block c(ω̂ + ω̂²/2) with c = 4/(4 + |ω|²), as
        written (ω̂³ = −|ω|²ω̂ in so(2) and so(3)): a product of the common factor c and a
        polynomial, not a sum of rational terms over a common denominator, so that no entry
        cancels (a factored closed form biases the step's rounding: docs/conventions.md
        §18); on SE(n) the translation column (I − ω̂/2)⁻¹v, written out the same way."""
        G = self.group
        x = G._checked(x, "x", G.rank)
        if G.retraction != "cayley":
            return self._offset(G.exp(list(x)) - sp.eye(G.n))
        m, xi = G.rotation_block, G.hat(x)
        omega = xi[:m, :m]
        c = 4 / (4 - (omega * omega).trace() / 2)  # |ω|² = −tr(ω̂²)/2
        D = sp.zeros(G.n, G.n)
        D[:m, :m] = c * (omega + omega * omega / 2)
        if G.affine:  # (I − ω̂/2)⁻¹v = v + (c/2)(ω̂v + ω̂(ω̂v)/2)
            v = xi[:m, m]
            turned = omega * v
            D[:m, m] = v + c / 2 * (turned + omega * turned / 2)
        return self._offset(D)

    def chart_of_fibre(self, f, source=None):
        """τ⁻¹(I + D) symbolically.  Cayley: ω = 2 vee(D_R − D_Rᵀ)/(4 + tr D_R) on SO(2) and
        SO(3) alike (1 + tr cay(ω) = 4c on SO(3), 2 + tr cay(ω) = 4c on SO(2)), and on SE(n)
        v = (I − ω̂/2)p; the exponential: the group's logarithm."""
        G = self.group
        D = self.offset_matrix(f)
        if G.retraction != "cayley":
            return tuple(G.retraction_inverse(sp.eye(G.n) + D))
        m = G.rotation_block
        rotation = D[:m, :m]
        skew = rotation - rotation.T
        entries = (skew[2, 1], skew[0, 2], skew[1, 0]) if m == 3 else (skew[1, 0],)
        omega = [2 * v / (4 + rotation.trace()) for v in entries]
        if not G.affine:
            return tuple(omega)
        v = (sp.eye(m) - G.rot.hat(omega) / 2) * D[:m, m]
        return tuple(omega) + tuple(v)

    def fibre_chart_inverse(self, f, source=None):
        """τ⁻¹(I + D) of numeric offsets (Cayley: vee(2D(2I + D)⁻¹))."""
        G = self.group
        D = self._numeric_offset(f)
        eye = np.eye(G.n)
        if G.retraction == "cayley":
            return tuple(float(v) for v in G._numeric_vee(2.0 * D @ np.linalg.inv(2 * eye + D)))
        return tuple(float(v) for v in G._numeric_log(eye + D))

    # --- names -------------------------------------------------------------------------------
    def _named_offset(self, offset: int) -> sp.Matrix:
        """D_{k+offset} = F_{k+offset} − I as a matrix of named entries (F_{k} − I)_{ij}."""
        base = subscripted(self.increment_latex, offset)
        return self.offset_matrix([StepSymbol(f"({base} - I)_{{{i + 1}{j + 1}}}")
                                   for i, j in self.group._free])

    def named_fibre(self, offset):
        """The arrow g_{k+o} = (q_{k+o−1}, F_{k+o−1} − I)."""
        return self._offset(self._named_offset(offset - 1))

    def named_source(self, offset):
        return self.group.named_fibre(offset - 1)

    def named_chart(self, offset):
        name = subscripted(self.increment_latex, offset - 1)
        return tuple(StepSymbol(f"(\\tau^{{-1}} {name})_{{{a + 1}}}") for a in range(self.rank))

    def symbols_by_name(self, offset):
        return {self.group.symbol_name: self.group.named_matrix(offset),
                self.increment_name: sp.eye(self.group.n) + self._named_offset(offset)}

    def configuration(self, value, name, check):
        """An element of the group (a configuration q; the arrows hold increments)."""
        return check.group_element(self.group, value, name)

    def named_groups(self):
        return {self.group.symbol_name: self.group, self.increment_name: self.group}

    def base_groups(self):
        return {self.group.symbol_name: self.group}

    def matrix_parts(self):
        return [(0, self.group)]

    def offset_parts(self):
        return [(self.base_dim, self.group)]

    # --- numerics ---------------------------------------------------------------------------
    def random_base_point(self, rng):
        G = self.group
        M = G.numeric_tau(G.random_chart(rng, scale=1.0))
        return tuple(float(M[i, j]) for i, j in G._free)

    def arrow_between(self, c0, c1):
        """(q₀, q₀⁻¹(q₁ − q₀)) for configurations q₀, q₁ (matrices)."""
        G = self.group
        M0, M1 = G._numeric_matrix(c0), G._numeric_matrix(c1)
        D = np.linalg.solve(M0, M1 - M0)
        return (tuple(float(M0[i, j]) for i, j in G._free)
                + tuple(float(D[i, j]) for i, j in G._free))

    def configurations_along(self, arrows, start=None):
        """q_0, …, q_N: each arrow's q_k, then q_{N−1}(I + D_{N−1}) (``start``, if given,
        must be q_0)."""
        G = self.group
        arrows = np.asarray(arrows, float).reshape(-1, self.arrow_dim)
        n = self.base_dim
        q = G.numeric_matrices(arrows[:, :n])
        if start is not None and not np.allclose(G._numeric_matrix(start), q[0], rtol=1e-12,
                                                 atol=1e-12):
            from .._errors import DomainError

            raise DomainError(f"{self.name}: start is not the configuration q_0 the first "
                              f"arrow holds (leave it out: the arrows hold their "
                              f"configurations)")
        last = q[-1] + q[-1] @ self._numeric_offset(arrows[-1, n:])
        return np.concatenate([q, last[None]])

    def spatial_momenta(self, momenta, arrows, start=None):
        """The sections move q_k on the right (q τ(tE_a)): body momenta, Ad*_{q⁻¹}μ."""
        sources = self.configurations_along(arrows, start)[:-1]
        return self.group.body_to_spatial(momenta, sources)

    def increments(self, a):
        _, d = self._split(a)
        return [(self.increment_name, self.group, np.eye(self.group.n)
                 + self._numeric_offset(d))]

    def configuration_after(self, c0, a):
        G = self.group
        q, d = self._split(a)
        M = G.numeric_matrix([float(v) for v in q])
        return M + M @ self._numeric_offset(d)

    def view(self, coords):
        return TrivialisedArrow(self, coords)

    def base_view(self, coords):
        return self.group.matrix(tuple(coords))

    def __repr__(self) -> str:
        return f"TrivialisedPairGroupoid({self.group!r}, increment={self.increment_name!r})"
