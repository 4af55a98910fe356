"""Names in the printed equations: Greek characters typeset as commands, abbreviation names
that no document compiles refused, and the stage notation of a Galerkin step never printed
with a system's name that reads as one of its symbols (docs/latex.md)."""

from __future__ import annotations

import re
import warnings

import pytest
import sympy as sp
from test_latex_pdf import equation_numbers, lost_content, needs_tex, typeset

import symgroupoid as sg
from symgroupoid.equations import LatexOptionError, UnusedAbbreviationWarning, latex

h = sp.Symbol("h", positive=True)


@pytest.mark.parametrize("name, tex", [
    ("θ", r"\theta"), ("θ1", r"\theta_{1}"), ("Ω", r"\Omega"), ("ϑ", r"\vartheta"),
    ("λ", r"\lambda"), ("ς", r"\varsigma"), ("xθ", r"x_{\theta}"), ("theta", r"\theta"),
    ("m_1", "m_{1}"), ("θ₁", r"\theta_{1}"), ("μ₀", r"\mu_{0}"), ("x₁₂", "x_{12}")])
def test_greek_characters_print_as_their_commands(name, tex):
    assert latex(sp.Symbol(name)) == tex


@pytest.mark.parametrize("name, tex", [
    ("ℓ", r"\ell"), ("ℓ1", r"\ell_{1}"), ("µ", r"\mu"), ("ħ", r"\hbar"), ("ẋ", r"\dot{x}"),
    ("ẋ1", r"\dot{x}_{1}"), ("q̈", r"\ddot{q}"), ("é", r"\acute{e}"), ("x̄", r"\bar{x}")])
def test_letters_outside_ascii_print_as_their_commands(name, tex):
    """ℓ, ħ, the micro sign µ (not the Greek μ) and letters with a combining accent: a LaTeX
    engine typesets their commands, not the characters (pdflatex stopped at ℓ)."""
    assert latex(sp.Symbol(name)) == tex


def _lengths():
    """An oscillator in ẋ with a length ℓ and a mass µ: names with letters outside ASCII."""
    ell, mu = sp.symbols("ℓ µ", positive=True)
    G = sg.PairGroupoid(sg.EuclideanSpace(["ẋ"]))
    return sg.DiscreteSystem(G, lambda a: (mu * (a.target[0] - a.source[0]) ** 2 / (2 * h)
                                           - h * ell * a.target[0] ** 2 / 2),
                             parameters=[h, ell, mu], name="lengths").euler_lagrange()


def test_names_outside_ascii_print_as_commands():
    text = _lengths().latex()
    assert text.isascii(), text
    assert r"\dot{x}_{k+1}" in text and r"\ell" in text and r"\mu" in text


@needs_tex
def test_a_document_with_names_outside_ascii_typesets_them(tmp_path):
    log, text = typeset(_lengths().latex(document=True), tmp_path)
    assert equation_numbers(text) == [1]
    assert "Missing character" not in log


def test_a_parameter_no_engine_typesets_is_refused_by_name():
    snow = sp.Symbol("m☃", positive=True)
    G = sg.PairGroupoid(sg.EuclideanSpace("x"))
    with pytest.raises(sg.ParameterDeclarationError, match="☃"):
        sg.DiscreteSystem(G, lambda a: snow * (a.target[0] - a.source[0]) ** 2 / h,
                          parameters=[h, snow], name="snow").euler_lagrange()


@pytest.mark.parametrize("name", ["x\u0302y", "m☃"])
def test_a_coordinate_no_engine_typesets_is_refused_by_name(name):
    with pytest.raises(sg.CoordinateNameError, match="does not typeset"):
        sg.EuclideanSpace([name])


@pytest.mark.parametrize("name", ["two\nlines", "tab\there", "nul\0"])
def test_a_system_name_with_control_characters_is_refused(name):
    G = sg.PairGroupoid(sg.EuclideanSpace("x"))
    with pytest.raises(sg.ShapeError, match="control characters"):
        sg.DiscreteSystem(G, lambda a: (a.target[0] - a.source[0]) ** 2 / h, parameters=[h],
                          name=name)


def _oscillator():
    w = sp.Symbol("ω", positive=True)
    G = sg.PairGroupoid(sg.EuclideanSpace("θ"))
    return sg.DiscreteSystem(G, lambda a: ((a.target[0] - a.source[0]) ** 2 / (2 * h)
                                           - h * w**2 * ((a.source[0] + a.target[0]) / 2) ** 2
                                           / 2),
                             parameters=[h, w], name="osc").euler_lagrange()


def test_greek_coordinate_and_parameter_names_print_as_commands():
    text = _oscillator().latex()
    assert text.isascii(), text
    assert r"\theta_{k+1}" in text and r"\omega^{2}" in text


@needs_tex
def test_a_document_with_greek_names_typesets_them(tmp_path):
    log, text = typeset(_oscillator().latex(document=True), tmp_path)
    assert equation_numbers(text) == [1]
    assert "Missing character" not in log
    assert lost_content(log, tolerance=1.0) == []


def _pendulum():
    """The double pendulum of docs/latex.md, whose rows hold m₁ + m₂."""
    g, m1, m2, l1, l2 = sp.symbols("g m_1 m_2 l_1 l_2", positive=True)

    def L(arrow):
        q0, q1 = sp.Matrix(arrow.source), sp.Matrix(arrow.target)
        (a, b), (va, vb) = (q0 + q1) / 2, (q1 - q0) / h
        kinetic = ((m1 + m2) * l1**2 * va**2 / 2 + m2 * l2**2 * vb**2 / 2
                   + m2 * l1 * l2 * va * vb * sp.cos(a - b))
        return h * (kinetic + (m1 + m2) * g * l1 * sp.cos(a) + m2 * g * l2 * sp.cos(b))

    G = sg.PairGroupoid(sg.EuclideanSpace("theta1 theta2"))
    step = sg.DiscreteSystem(G, L, parameters=[h, g, m1, m2, l1, l2],
                             name="double_pendulum").euler_lagrange()
    return step, m1 + m2


@pytest.mark.parametrize("name, tex", [("Ω", r"\Omega"), ("Ωx", r"\Omega x"),
                                       ("α1", r"\alpha_{1}"),  # as a coordinate's (docs)
                                       (r"\Omega", r"\Omega"), ("M_{1}", "M_{1}")])
def test_an_abbreviation_named_by_a_greek_character_prints_its_command(name, tex):
    step, value = _pendulum()
    text = step.latex(abbreviations={name: value})
    assert f"{tex} &= m_{{1}} + m_{{2}}" in text, text
    assert text.isascii()


@pytest.mark.parametrize("name, why", [("M_{1", "unbalanced braces"), ("G#", "'#'"),
                                       ("x☃", "'☃'"), ("a$b", "'\\$'"), ("}{", "unbalanced")])
def test_an_abbreviation_name_no_document_compiles_is_refused(name, why):
    step, value = _pendulum()
    with pytest.raises(LatexOptionError, match=why):
        step.latex(abbreviations={name: value})


#: command names refused alone, and why
COMMANDS_ALONE = [
    (r"\frac", "takes an argument and is given none"), (r"\sqrt", "takes an argument"),
    (r"\hat", "takes an argument"), (r"\over", "is an operator"), (r"\sum", "operator"),
    (r"M \phantom{x}", "operator"), (r"\big", "operator")]


@pytest.mark.parametrize("name, why", COMMANDS_ALONE)
def test_an_abbreviation_name_that_is_an_operator_or_lacks_its_argument_is_refused(name, why):
    """(\\frac and \\sqrt alone printed '\\frac l_{1} ...', which pdflatex refuses;
    \\over compiled and made the whole row a fraction.)"""
    step, value = _pendulum()
    with pytest.raises(LatexOptionError, match=why):
        step.latex(abbreviations={name: value})


def test_an_abbreviation_named_by_a_command_with_its_argument_stays_a_name():
    """A command with its argument stays a name (the refusals above are of the command
    alone; this was checked after each of them, the same printing seven times), also
    after the step has refused every one of them."""
    step, value = _pendulum()
    for name, why in COMMANDS_ALONE:
        with pytest.raises(LatexOptionError, match=why):
            step.latex(abbreviations={name: value})
    assert r"\hat{m}" in step.latex(abbreviations={r"\hat{m}": value})


J = sp.diag(*sp.symbols("I1:4", positive=True))
mgl = sp.Symbol("mgl", positive=True)


def _top(group):
    system = sg.ContinuousSystem(group, lambda R, xi: (xi.T * J * xi)[0, 0] / 2 - mgl * R[2, 2],
                                 parameters=[h, mgl, *J.diagonal()], name="top")
    return system.discretize(h, sg.GaussLegendre(2)).euler_lagrange(progress=False)


@pytest.mark.parametrize("name, printed", [("X", "X"), ("V", "V"), ("Xi", r"\\Xi")])
def test_a_group_named_like_a_stage_symbol_is_refused_by_name(name, printed):
    """The notation's X_{j,i}, V_{j,i}, Ξ_{j,i} would stand for two things (its check used to
    fail with a bare ValueError); the step is too large to print otherwise."""
    with pytest.raises(sg.UnsupportedFeatureError, match=f"names {printed} read as its symbols"):
        _top(sg.SO3(name)).latex()


@pytest.mark.slow
def test_the_node_derivative_is_written_with_the_groups_own_name():
    """(The explanation of N_b read ⟨∂L/∂R, R E_b⟩ whatever the group was called: a body
    named Y had an R that appeared nowhere else in its document.)"""
    text = _top(sg.SO3("Y")).latex()
    assert r"\partial L/\partial Y, Y E_b" in text and r"\partial R" not in text


@pytest.mark.slow
def test_abbreviations_of_a_step_in_the_group_stage_notation_are_reported_unused():
    """The notation names its own parts; the step used to be refused as too large."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        text = _top(sg.SO3("R")).latex(abbreviations={"K": 2 * mgl})
    assert text.count("0 &=") == 3
    unused = [w for w in caught if issubclass(w.category, UnusedAbbreviationWarning)]
    assert len(unused) == 1 and "stage notation names its own parts" in str(unused[0].message)
    assert unused[0].filename == __file__
    with pytest.raises(LatexOptionError):  # still checked
        _top(sg.SO3("R")).latex(abbreviations={"K#": 2 * mgl})


def test_the_basis_and_the_lie_poisson_momentum_are_defined():
    """E_1, E_2, E_3 appeared in the rigid body's (heavy top's, plate-ball's) rows undefined,
    though their signs decide the equations'; μ in the Lie–Poisson form too."""
    from symgroupoid import systems

    text = systems.rigid_body().euler_lagrange(progress=False).latex()
    where = text.split(r"\intertext{where, with $e_{i}$ the $i$-th standard unit vector of "
                       r"$\mathbb{R}^{3}$,}")[1]
    printed = {a: where.split(f"E_{{{a}}} " + ("&= " if a == 1 else "= "))[1].split(",")[0]
               .split(r" \notag")[0].strip() for a in (1, 2, 3)}
    for a, E in enumerate(sg.SO3("R").basis_matrices(), start=1):  # Σ ±e_i e_jᵀ, as printed
        terms = [("- " if v < 0 else "+ ") + f"e_{{{i + 1}}} e_{{{j + 1}}}^{{T}}"
                 for i in range(3) for j in range(3) for v in [E[i, j]] if v != 0]
        assert printed[a] == " ".join(terms).removeprefix("+ "), (a, printed[a])
    lie_poisson = systems.rigid_body().lie_poisson().latex()
    assert r"where $\mu_{j}$ is the momentum the integrator carries" in lie_poisson


@pytest.mark.parametrize("name", [r"\Delta \theta_{2}", r"\bar{\theta}_{1}",
                                  r"(\bar{\theta}_{1})_{k-1/2}"])
def test_an_abbreviation_may_not_print_as_a_piece(name):
    """A name printed like a named piece was accepted: Δθ₂ then stood for m₁ + m₂ in one
    term and for the difference quotient in the next."""
    step, value = _pendulum()
    with pytest.raises(sg.SymgroupoidError, match="prints like a symbol of double_pendulum"):
        step.latex(abbreviations={name: value})


def test_an_abbreviation_reads_only_the_steps_symbols():
    """An expression in a symbol the step does not have occurs nowhere in its equations:
    it was accepted with only an unused-abbreviation warning."""
    step, value = _pendulum()
    with pytest.raises(sg.SymgroupoidError, match="reads zz, not a symbol of double_pendulum"):
        step.latex(abbreviations={"M": value + sp.Symbol("zz")})


@pytest.mark.parametrize("name", ["m__2", "m^2", "theta__12", "a__b"])
def test_a_name_printed_with_a_superscript_of_digits_is_refused(name):
    """SymPy prints m__2 as m^{2}: the equations of m__2 printed exactly as those of m²
    (and a__b as a^{b}, a to the b)."""
    with pytest.raises(sg.CoordinateNameError, match="reads as a power"):
        sg.EuclideanSpace([name])
    mass = sp.Symbol(name, positive=True)
    G = sg.PairGroupoid(sg.EuclideanSpace("x"))
    with pytest.raises(sg.ParameterDeclarationError, match="reads as a power"):
        sg.DiscreteSystem(G, lambda a: mass * (a.target[0] - a.source[0]) ** 2 / h,
                          parameters=[h, mass], name="powers").euler_lagrange()


def test_a_parameter_written_as_a_coordinate_is_refused():
    """A parameter x beside the coordinate x printed x next to x_{k}; the same name as an
    abbreviation was already refused."""
    x = sp.Symbol("x", positive=True)
    G = sg.PairGroupoid(sg.EuclideanSpace("x y"))
    with pytest.raises(sg.ParameterDeclarationError, match="as the coordinate 'x'"):
        sg.DiscreteSystem(G, lambda a: (a.target[0] - a.source[0]) ** 2 / h
                          - h * x * a.target[0], parameters=[h, x], name="same")


def test_a_parameter_written_as_the_multipliers_is_refused_with_constraints_only():
    """A parameter lambda in a constrained step printed h λ beside (λ_{k})_{1}; without
    constraints λ names no multiplier (Lamé's λ) and is kept."""
    lam = sp.Symbol("lambda", positive=True)
    G = sg.PairGroupoid(sg.EuclideanSpace("x y"))

    def L(a):
        return sum((t - s) ** 2 for s, t in zip(a.source, a.target)) / h - h * lam * a.target[0]

    with pytest.raises(sg.ParameterDeclarationError, match="as the multipliers"):
        sg.DiscreteSystem(G, L, parameters=[h, lam], name="tied",
                          constraints=lambda a: [a.target[0] - a.source[1]])
    free = sg.DiscreteSystem(G, L, parameters=[h, lam], name="free")
    assert r"\lambda" in free.euler_lagrange().latex()


def _body(name: str):
    """A rigid body on SO(3), L = −tr(J_d W)/h − h k W_33, its last parameter k named
    ``name``."""
    from symgroupoid import systems

    inertias, k = systems.inertia_symbols(), sp.Symbol(name, positive=True)
    Jd = systems.discrete_inertia(*inertias)
    return sg.DiscreteSystem(sg.SO3("W"), lambda g: -(Jd * g.matrix).trace() / h
                             - h * k * g.matrix[2, 2], parameters=[h, *inertias, k],
                             name="body").euler_lagrange(progress=False)


@pytest.mark.parametrize("name, tex", [("E1", "E_{1}"), ("e_2", "e_{2}")])
def test_a_parameter_written_as_a_basis_element_keeps_the_basis_out_of_the_equations(name, tex):
    """A parameter E1 printed E_{1}, as the basis element of so(3) that the "where" list
    defined as a matrix: "0 = E_{1} h (…) + (tr(J_d E_1 W_{k+1}) − …)/h" (and e_2 as the
    unit vector the basis is written in).  The step now prints with the entries of W, where
    the name is the parameter alone; named c it keeps the papers' tr(J_d E_a W) and
    defines E_a."""
    text = _body(name).latex()
    assert r"\operatorname{tr}" not in text and r"\intertext{where}" not in text
    assert f"{tex} h" in text


def test_an_abbreviation_written_as_a_basis_element_is_refused():
    """An abbreviation E_{1} printed beside tr(J_d E_{1} W_{k+1}), and e_{2} beside the
    "where" list's E_1 = −e_2 e_3ᵀ + e_3 e_2ᵀ."""
    step = _body("c")
    kept = step.latex()
    assert r"\operatorname{tr}(J_{d} E_{1} W_{k+1})" in kept and r"E_{1} &= " in kept
    c = sp.Symbol("c", positive=True)
    for name, what in [("E_{1}", "the constant matrix E_{1}"), ("e_{2}", "the unit vector")]:
        with pytest.raises(LatexOptionError, match=f"prints like {re.escape(what)}"):
            step.latex(abbreviations={name: c * h})


def _double_pendulum(third: str):
    """A double pendulum in the angles x, y by the midpoint rule, L written in the pieces
    x̄, Δx, with parameters h, a and one named ``third``."""
    a, c = sp.symbols(f"a {third}", positive=True)

    def L(arrow):
        q0, q1 = sp.Matrix(arrow.source), sp.Matrix(arrow.target)
        (p, q), (vp, vq) = (q0 + q1) / 2, (q1 - q0) / h
        return h * (a * vp ** 2 / 2 + vq ** 2 / 2 + vp * vq * sp.cos(p - q)
                    + c * sp.cos(p) + sp.cos(q))

    return sg.DiscreteSystem(sg.PairGroupoid(sg.EuclideanSpace("x y")), L,
                             parameters=[h, a, c], name="pendulum")


def test_a_parameter_written_as_a_piece_or_as_l_keeps_those_forms_out():
    """A parameter xbar printed \\bar{x} beside the midpoints x̄ of the pieces, and one named
    L as a factor of ∂_{Δx} L: the forms in pieces (and with L's partial derivatives) are
    not offered where a parameter prints as one of their names."""
    plain = _double_pendulum("c").euler_lagrange(progress=False).latex()
    assert r"\partial_{\Delta x} L" in plain and r"\bar{x}_{j-1/2}" in plain
    bar = _double_pendulum("xbar").euler_lagrange(progress=False).latex()
    assert r"\bar{x}" in bar and "k+1/2" not in bar
    length = _double_pendulum("L").euler_lagrange(progress=False).latex()
    assert r"\partial" not in length and r"\frac{L h}{2}" in length
    assert r"\Delta x_{k+1/2}" in length  # (still in pieces)


@pytest.mark.parametrize("name, why", [("tr", "the word tr"), ("sin", "the word sin"),
                                       ("x_", "an empty subscript")])
def test_a_name_that_prints_as_an_operator_or_with_an_empty_subscript_is_refused(name, why):
    """A parameter tr printed "- tr (W_k)_{13}" beside tr(J_d E_1 W_{k+1}); a coordinate x_
    printed x_{}, and a parameter x beside it as the same glyph."""
    p = sp.Symbol(name, positive=True)
    G = sg.PairGroupoid(sg.EuclideanSpace("q"))
    with pytest.raises(sg.ParameterDeclarationError, match=why):
        sg.DiscreteSystem(G, lambda a: (a.target[0] - a.source[0]) ** 2 / h
                          - h * p * a.source[0] ** 2, parameters=[h, p], name="named")
    with pytest.raises(sg.CoordinateNameError, match=why):
        sg.EuclideanSpace(name)


def test_a_parameter_written_as_a_multiplier_with_its_index_is_refused_with_constraints():
    """lambda_1 printed \\lambda_{1} beside the multipliers (\\lambda_{k})_{1}; λ alone was
    already refused."""
    lam = sp.Symbol("lambda_1", positive=True)
    G = sg.PairGroupoid(sg.EuclideanSpace("x y"))

    def L(a):
        return sum((t - s) ** 2 for s, t in zip(a.source, a.target)) / h - h * lam * a.target[0]

    with pytest.raises(sg.ParameterDeclarationError, match=r"as the multipliers"):
        sg.DiscreteSystem(G, L, parameters=[h, lam], name="tied",
                          constraints=lambda a: [a.target[0] - a.source[1]])
    assert r"\lambda_{1}" in sg.DiscreteSystem(G, L, parameters=[h, lam],
                                               name="free").euler_lagrange().latex()


@pytest.mark.parametrize("name, why", [
    (r"\partial_{\bar{\theta}_{1}} L", r"uses \\partial"),
    (r"(\theta_{1})_{k+2}", "the step index k or j in a subscript"),
    (r"\theta_{1,k}", "the step index k or j in a subscript"),
    (r"\overline{\theta}_{1}", "prints like a symbol"),
    (r"\mathrm{h}", "prints like a symbol"),
    (r"\foo", r"uses \\foo, which is not a Greek letter"),
    (r"\input{nonexistent_file}", r"uses \\input"),
    (r"\def\h{X}M", r"uses \\def"),
    ("M\nN", "control character"),
])
def test_an_abbreviation_must_read_as_itself(name, why):
    """Accepted before (a reviewer's PDFs): ∂_{θ̄₁}L defined twice in the "where" list, once
    in terms of itself; (θ₁)_{k+2} and θ_{1,k} read as the coordinate at a step; \\overline
    and \\mathrm{h} print like θ̄₁ and h; \\foo, \\input, \\def stopped pdflatex; a newline
    printed nothing."""
    step, value = _pendulum()
    with pytest.raises(LatexOptionError, match=why):
        step.latex(abbreviations={name: value})


def test_names_made_of_greek_letters_accents_and_fonts_are_kept():
    step, value = _pendulum()
    for name in (r"\hat{\Omega}", r"\mathcal{M}", "K_{1}", r"m_{kin}", r"\text{mass}"):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UnusedAbbreviationWarning)
            assert "where" in step.latex(abbreviations={name: value})
