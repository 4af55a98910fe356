"""Hostile calls of the code generator's public face (:mod:`symgroupoid.codegen`): whatever
is passed where a step's equations or a program belongs, and names a program does not have,
are refused with a named :class:`~symgroupoid.SymgroupoidError` before any work (found by
this suite: every entry point but ``emit_c`` read attributes of anything it was given and
raised AttributeError or TypeError); valid calls give what the stepper uses."""

from __future__ import annotations

import pytest
from _hostile import (
    PROFILES,
    judge,
    junk,
    profile,
    scratch_cwd,  # noqa: F401  (autouse fixture)
)
from hypothesis import example, given
from hypothesis import strategies as st

import symgroupoid as sg
from symgroupoid import codegen, systems

STEP = systems.spherical_chain(1).euler_lagrange()
PROGRAM = STEP.program

#: the entry points that take a step, each with what a valid call must give
STEP_ENTRIES = {
    "generate_c": lambda step: codegen.generate_c(step),
    "jacobian_pattern": codegen.jacobian_pattern,
    "band_order": codegen.band_order,
    "time_layout": codegen.time_layout,
}


def _not_a_step():
    """Junk, and the objects nearest to a step: its program, its system, a SymPy matrix."""
    return st.one_of(junk(), st.sampled_from([PROGRAM, STEP.system, STEP.residuals,
                                              sg.systems, None]))


@pytest.mark.parametrize("entry", sorted(STEP_ENTRIES))
@pytest.mark.parametrize("run", PROFILES)
def test_step_entry_points_refuse_what_is_not_a_step(entry, run):
    @profile(run, 10, 200)
    @given(_not_a_step())
    def check(value):
        judge(f"codegen.{entry}", lambda: STEP_ENTRIES[entry](value), ["step"])

    check()


def test_step_entry_points_accept_a_step():
    """The valid calls: the pattern has a true diagonal, the chain of one body has no time
    and dense factors, and the C declares the step's sizes."""
    pattern = codegen.jacobian_pattern(STEP)
    assert pattern.shape == (3, 3) and pattern.diagonal().all()
    assert codegen.band_order(STEP) is None
    assert codegen.time_layout(STEP).unknown < 0
    assert "_N_UNKNOWNS 3" in codegen.generate_c(STEP).header


@pytest.mark.parametrize("run", PROFILES)
def test_hoisted_values_refuses_what_is_not_a_program_or_its_names(run):
    @profile(run, 12, 300)
    @given(st.one_of(
        st.tuples(st.just("program"), st.one_of(junk(), st.just(STEP))),
        st.tuples(st.just("names"), st.one_of(
            st.lists(st.sampled_from(["F", "J", "K", "u", ""]), min_size=1, max_size=3),
            junk())),
        st.tuples(st.just("over"), st.one_of(st.sampled_from(["v", "", "F"]), junk()))))
    @example(("names", ["F"]))  # valid: the known-only values the residual alone reads
    @example(("over", "u"))
    def check(drawn):
        argument, value = drawn
        kwargs = {"program": PROGRAM, argument: value}
        hoisted = judge("codegen.hoisted_values", lambda: codegen.hoisted_values(**kwargs),
                        ["program", "output", "input array", "names", "over"])
        if hoisted is not None:  # ascending operation nodes of the program's graph
            graph = PROGRAM.graph
            assert hoisted == sorted(set(hoisted))
            assert all(graph.args[n] for n in hoisted)

    check()


def test_hoisted_values_of_the_residual_alone_are_fewer():
    """F's known-only frontier is part of (F, J)'s (J reads every value F reads, and more of
    the known arrow besides); a single string is refused, not read letter by letter."""
    both = set(codegen.hoisted_values(PROGRAM))
    alone = set(codegen.hoisted_values(PROGRAM, names=["F"]))
    assert alone and alone < both
    with pytest.raises(sg.InputTypeError, match="names must be a list of strings"):
        codegen.hoisted_values(PROGRAM, names="FJ")


@pytest.mark.parametrize("run", PROFILES)
def test_generate_program_c_refuses_bad_programs_and_names(run):
    @profile(run, 12, 300)
    @given(st.one_of(
        st.tuples(st.just("label"), st.one_of(junk(), st.just(""))),
        st.tuples(st.just("program"), st.one_of(junk(), st.just(STEP))),
        st.tuples(st.just("inputs"), st.one_of(st.sampled_from(["v", "F", ""]), junk())),
        st.tuples(st.just("outputs"), st.one_of(st.sampled_from(["Q", "u", ""]), junk()))))
    @example(("label", "window"))  # valid: a batched evaluator of F over the unknowns
    def check(drawn):
        argument, value = drawn
        kwargs = {"label": "window", "program": PROGRAM, "inputs": "u", "outputs": "F",
                  argument: value}
        source = judge("codegen.generate_program_c",
                       lambda: codegen.generate_program_c(**kwargs),
                       ["label", "program", "output", "input array"])
        if source is not None:
            assert f"{source.prefix}_eval" in source.cdef
            assert f"void {source.prefix}_eval(" in source.source

    check()


@pytest.mark.parametrize("header_name, error", [
    ('a".h', sg.ShapeError), ('x.h"\n#error injected\n"', sg.ShapeError), ("..", sg.ShapeError),
    ("dir/x.h", sg.ShapeError), (3, sg.InputTypeError), (["a.h"], sg.InputTypeError),
])
def test_generate_c_refuses_a_header_name_that_is_not_a_file_name(header_name, error):
    """The source includes its header by this name: a quote or a newline in it wrote
    ``#include "a".h"`` or a line of C of the caller's choosing, and a list was printed as
    its repr."""
    with pytest.raises(error, match="header_name"):
        codegen.generate_c(STEP, header_name=header_name)
    with pytest.raises(sg.ShapeError, match="latex"):
        codegen.generate_c(STEP, latex="yes")
    assert '#include "my_kernel.h"' in codegen.generate_c(STEP, header_name="my_kernel.h").source


def test_emit_c_refuses_a_path_that_names_a_directory(tmp_path):
    """``out/`` wrote out.c and out.h beside the directory out."""
    (tmp_path / "out").mkdir()
    with pytest.raises(sg.ShapeError, match="got the directory"):
        STEP.emit_c(f"{tmp_path / 'out'}/")
    assert not list(tmp_path.glob("out.*")) and not list((tmp_path / "out").iterdir())
