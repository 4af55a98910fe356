"""The matrix (trace) form of forced steps on matrix groups (docs/conventions.md §20,
docs/latex.md): the unforced step's matrix form (tr(J_d W_k E_a)) with the named discrete
forces f^±_b added, their values in the "where" list — built from the existing forms and
checked against the explicit residuals as every printed form is.  The forced rigid body
printed only its component form (entries (W_k)_{23}, …) before: ``forced_form`` returned
None in matrix form, and the step's own matrix form, verified against the forced
residuals, did not exist."""

from __future__ import annotations

import re

import pytest
import sympy as sp
from test_forces import _plane_system, _torque_and_damping, u
from test_latex_pdf import assert_typesets_whole, needs_tex

import symgroupoid as sg
from symgroupoid import systems

h = sp.Symbol("h", positive=True)
TAUS = sp.symbols("tau1:4", real=True)


def _driven_rigid_body() -> sg.StepEquations:
    """The Moser–Veselov rigid body (``systems.rigid_body``) driven by body torques τ held
    over the step (``body_torque``: f⁻ = f⁺ = (h/2)·τ)."""
    I1, I2, I3 = systems.inertia_symbols()
    Jd = systems.discrete_inertia(I1, I2, I3)

    def L(g):
        return -(Jd * g.matrix).trace() / h

    return sg.DiscreteSystem(sg.SO3("W"), L, parameters=[h, I1, I2, I3],
                             forces=sg.body_torque(list(TAUS), h), inputs=list(TAUS),
                             name="driven_body", time_step=h).euler_lagrange()


DRIVEN = _driven_rigid_body()


def test_the_forced_rigid_body_prints_the_trace_form_and_its_forces():
    text = DRIVEN.latex()
    free = systems.rigid_body().euler_lagrange().latex()
    for a in (1, 2, 3):
        trace = (rf"\frac{{\operatorname{{tr}}(J_{{d}} E_{{{a}}} W_{{k+1}}) - "
                 rf"\operatorname{{tr}}(J_{{d}} W_{{k}} E_{{{a}}})}}{{h}}")
        assert trace in text and trace in free, text
        assert rf"f^{{+}}_{{{a}}}(g_{{k}}) + f^{{-}}_{{{a}}}(g_{{k+1}})" in text
        name = re.escape(rf"f^{{-}}_{{{a}}}(g_{{k+1}})")
        value = re.escape(rf"\frac{{h (\tau_{{{a}}})_{{k+1}}}}{{2}}")
        assert re.search(rf"{name} &?= {value}", text), text
    assert r"\intertext{where, with $e_{i}$ the $i$-th standard unit vector" in text
    assert "(W_{k})_{23}" not in text  # no entries: the component form is not the one chosen


@pytest.mark.slow
def test_a_forced_step_without_matrices_keeps_its_component_form():
    text = _plane_system(_torque_and_damping, [u]).euler_lagrange().latex()
    assert "f^{+}_{1}(g_{k})" in text and r"\operatorname{tr}" not in text


@needs_tex
def test_the_forced_rigid_body_document_typesets_whole(tmp_path):
    document = assert_typesets_whole(DRIVEN, tmp_path)
    assert r"\operatorname{tr}(J_{d} E_{1} W_{k+1})" in document
    assert (tmp_path / "doc.pdf").stat().st_size > 0


@pytest.mark.slow
@needs_tex
def test_the_forced_3d_chain_document_breaks_its_long_forces(tmp_path):
    """(The "where" rows f^±_a of the forced 3D chain, each one fraction of up to 1,700
    characters, were printed whole at half size and still ran 1,183 pt off the page.)  A
    literal definition too long to be read whole is collected and broken like an equation:
    no row is scaled, and the document typesets whole."""
    step = systems.spherical_chain(1, forced=True).euler_lagrange()
    document = assert_typesets_whole(step, tmp_path)
    assert "scalebox" not in document and "f^{+}_{1}(g_{k})" in document


def test_a_named_constant_matrix_is_defined_in_the_where_list():
    """(The heavy top's and rigid body's documents printed tr(J_d E_a W_{k+1}) without saying
    what J_d is.)  A constant printed by name gets its value in the "where" list."""
    for system in (systems.heavy_top(), systems.rigid_body()):
        document = system.euler_lagrange().latex(document=True)
        assert r"\operatorname{tr}(J_{d} E_{1} W_{k+1})" in document, system.name
        assert (r"J_{d} &= \operatorname{diag}\left(\frac{- I_{1} + I_{2} + I_{3}}{2}"
                in document), system.name
