"""The per-call path of :meth:`Simulator.step`: one step of a control loop for under two
microseconds of Python.

``state = sim.step(state, p)`` in a loop used to parse its parameters (SymPy's printer on
every symbol), check the state's group parts and evaluate its constraints on every call,
some 350 µs per step around a kernel step of 1 µs (plate-ball).  Everything a call needs
is prepared once per simulator here, as closure cells:

- the parameter names, and one compiled test of the assumptions of every parameter
  (:func:`~symgroupoid.runtime._validate.assumptions_test`); a parameter vector whose bytes
  passed the test before is not tested again;
- which parameters the constraints use, and the *trusted* states: the bytes of states this
  simulator produced or checked, with the values of those parameters.  A state of the table
  is on the constraints and in the group (it was checked, or it is a step's output, as the
  states inside a run are), so it is not checked again; any other state goes through every
  check of :meth:`Simulator.state`;
- the *chain*: a loop that passes back the very array the last call returned, unchanged,
  with the same parameters object holding the same values and the same options, makes a
  link: its state is a step's output and its parameters were screened, so the call is the
  kernel's entry (:meth:`~symgroupoid.runtime._backends._Kernel.step_entry`) on the views
  kept from the last call, after a few comparisons.  The state a chain ends with (when
  another call breaks it) joins the table; a state from inside a chain is checked once if
  it is given again.

Whatever the fast path does not recognise — another kind of state or parameters, a value
that fails a test, a state not in the table, a failed step — takes the checked path
(``Simulator._checked_call``), which reports exactly what :meth:`Simulator.simulate`
reports.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from ._options import NewtonOptions
from ._runs import OK
from ._singular import zero_divisors
from ._validate import assumptions_test, constraint_check, parameter_names

#: at most this many trusted states and accepted parameter vectors are kept (a full table
#: is emptied: the loop's next state is trusted again at once, other loops after one
#: checked call)
MAX_TRUSTED = 1024

#: what the fast path's inputs screen returns for inputs it does not take
_REFUSED = object()
#: native float64, compared by identity first, then by equality: an array unpickled, or
#: received from another process, has a dtype object of its own (without the second test,
#: every call of a loop with such parameters would take the checked path, some 600 µs)
_FLOAT64 = np.dtype(np.float64)
_CONTIGUOUS = (8,)  # the strides of a C-contiguous float64 vector
#: a list or tuple of inputs whose entries are all of these types is converted to a vector
#: on the fast path (a controller's ``inputs=[-k * x]``); any other entry (a bool, a string,
#: an array, a SymPy number) takes the checked path, which accepts or refuses it
_SEQUENCES = (list, tuple)
_REALS = (float, int, np.float64)


class FastStep:
    """The fast path of one simulator: :attr:`call` (state, params, options=, inputs=) → the
    next state, through the checked path when the fast one cannot decide; :meth:`trust`
    adds a state checked by that path."""

    def __init__(self, sim):
        parameters = tuple(sim.equations.parameters)
        self.used = _used_index([i for i, _ in constraint_check(sim.equations).used],
                                len(parameters))
        self.trusted: dict[bytes, None] = {}
        kernel = sim.kernel
        self.run = kernel.stepper() if hasattr(kernel, "stepper") else kernel.step_once
        self.parameters = _parameter_screen(parameter_names(parameters),
                                            assumptions_test(parameters), self.used,
                                            lambda: tuple(zero_divisors(sim.equations)))
        self.call = _fast_call(sim, self)

    def key_tail(self, p: np.ndarray) -> bytes:
        """The bytes of the parameters the constraints use (the tail of a state's key)."""
        used = self.used
        return p.tobytes() if used is None else used if type(used) is bytes else \
            p[used].tobytes()

    def trust(self, known: np.ndarray, p: np.ndarray) -> None:
        """Trust a state checked under the parameters ``p``."""
        _remember(self.trusted, known.tobytes() + self.key_tail(p))


def _used_index(used: list, n: int):
    """How to take the parameters the constraints use from a parameter vector, cheapest
    first: None (all of them: the whole vector's bytes), b"" (none: the key's tail is
    empty), a slice (a contiguous run), else an index array."""
    if len(used) == n:
        return None
    if not used:
        return b""
    if used == list(range(used[0], used[-1] + 1)):
        return slice(used[0], used[-1] + 1)
    return np.array(used, dtype=np.intp)


def _remember(table: dict, key, value=None) -> None:
    if len(table) >= MAX_TRUSTED:
        table.clear()
    table[key] = value


def _parameter_screen(names: tuple, test: Callable | None, used,
                      divisors: Callable[[], tuple]):
    """The function params → (p, the bytes of the parameters the constraints use), or None
    unless ``params`` is a float64 vector of the right length or a dict of Python numbers
    naming every parameter, whose values pass ``test`` and are not a zero the equations
    divide by (``divisors()``: their indices, asked for at the first zero).

    Values tested before are not tested again: a vector by its bytes; a dict by its values,
    whose vector is then kept and given again (the same array, so the kernel's caller keeps
    its C view too; a zero, whose sign an equality test cannot see, is never looked up).
    Finiteness is left to the kernel, which refuses non-finite parameters (then the checked
    path reports them)."""
    shape, n = (len(names),), len(names)
    accepted: dict[bytes, None] = {}
    by_values: dict[tuple, tuple] = {}
    zeros: list = []  # [the indices of divisors()], once asked for

    def vector(p):
        whole = p.tobytes()
        if whole not in accepted:
            values = p.tolist()
            if test is not None and not test(values):
                return None
            if 0 in values:
                if not zeros:
                    zeros.append(divisors())
                if any(values[i] == 0 for i in zeros[0]):
                    return None
            _remember(accepted, whole)
        return p, (whole if used is None else used if type(used) is bytes else
                   p[used].tobytes())

    ndarray, float64, contiguous = np.ndarray, _FLOAT64, _CONTIGUOUS

    def screen(params):
        if type(params) is ndarray:
            if ((params.dtype is not float64 and params.dtype != float64)
                    or params.shape != shape
                    or params.strides != contiguous):
                return None
            whole = params.tobytes()  # vector(params), inline
            if whole not in accepted:
                return vector(params)
            return params, (whole if used is None else used if type(used) is bytes else
                            params[used].tobytes())
        if type(params) is dict and len(params) == n:
            try:
                values = tuple([params[name] for name in names])
            except KeyError:
                return None
            for v in values:  # Python numbers only (hashable; anything else: checked path)
                if type(v) is not float and type(v) is not int:
                    return None
            known = by_values.get(values)
            if known is not None:
                return known
            try:
                p = np.array(values, dtype=float)
            except OverflowError:
                return None
            found = vector(p)
            if found is not None and 0 not in values:
                _remember(by_values, values, found)
            return found
        if params is None and not names:
            return vector(np.zeros(0))
        return None

    return screen


def _fast_call(sim, fast: FastStep):
    """:attr:`FastStep.call`: :meth:`Simulator.step` itself (``call(state, params, *,
    options=None, inputs=None)``), which the simulator makes its own ``step`` at the first
    call, so that a loop's call is one Python call.

    A loop's call is a *link* of the chain when it passes back the very array the last call
    returned, unchanged (its bytes, as float64 in one dimension: with the bytes, their
    number fixes the shape), with the same parameters object holding the same values and
    the same options: that state is trusted (it is a step's output), its parameters were
    screened, and the C views of all three are at hand, so the call is the kernel's entry
    and a few comparisons, in this one function (each Python call and each array attribute
    read costs about a tenth of a microsecond).  Any other call looks its state up in the
    table."""
    shape, trusted, screen = (sim.layout.n_known,), fast.trusted, fast.parameters
    entry, view_of, options_of, no_inputs = sim.kernel.step_entry()
    ndarray, float64, contiguous, newton_options = np.ndarray, _FLOAT64, _CONTIGUOUS, \
        NewtonOptions
    next_row = sim.kernel.result_rows(sim.layout.n_known)
    #: the last link: (the state returned, its bytes, its view, the call's setting: (the
    #: params object, their bytes or a copy of a dict (None: never the same), the parameter
    #: vector, its view, the options, what the entry takes for them, the tail of a state's
    #: key)), replaced as a whole (another thread sees one link or the other, never half of
    #: one).  Its state joins the table when the chain breaks.  The held inputs are the
    #: array of the last call, whose shape (m,) an in-place change of shape keeps while it
    #: stays one-dimensional (its size is fixed).
    chain = [(None, None, None, (None,) * 7)]
    #: the last inputs array and its view (the view points at the array's buffer, so it
    #: stays right when the caller refills the same array between calls)
    m = sim.layout.n_inputs
    held_inputs = [(None, _REFUSED if m else no_inputs)]
    inputs_shape = (m,)
    checked = sim._checked_call
    #: the inputs' declared assumptions (positive=True, …) as one test of their values, or
    #: None; with one, inputs are tested at every call (an array refilled in place too)
    input_test = sim.layout.input_test

    def inputs_view(u):
        """What the entry takes for the inputs ``u``: ``no_inputs`` for a system without
        inputs and none given; for one with inputs, the view of a C-contiguous float64
        vector of its m inputs (whose finiteness the kernel checks: a non-finite input
        fails the step, and the checked path reports it); else :data:`_REFUSED`."""
        if u is None:
            return _REFUSED if m else no_inputs
        if type(u) in _SEQUENCES:  # [u1, …, um] of Python or NumPy reals: as a vector
            if not m or len(u) != m or not all(type(x) in _REALS for x in u):
                return _REFUSED
            try:
                u = np.array(u, float64)
            except OverflowError:  # an int beyond float64: the checked path reports it
                return _REFUSED
        elif (not m or type(u) is not ndarray
                or (u.dtype is not float64 and u.dtype != float64)
                or u.shape != inputs_shape or u.strides != contiguous):
            return _REFUSED
        if input_test is not None and not input_test(u.tolist()):
            return _REFUSED  # the checked path names the input and its assumption
        held = held_inputs[0]
        if held[0] is not u:
            held = held_inputs[0] = (u, view_of(u))
        return held[1]

    def call(state, params, *, options=None, inputs=None):
        link = chain[0]
        setting = link[3]
        if state is link[0] and params is setting[0]:
            if options is None:
                options = sim.options
            if (options is setting[4] and state.dtype is float64 and state.ndim == 1
                    and state.tobytes() == link[1]):  # (the state is an array of ours)
                same = setting[1]
                if type(same) is bytes:
                    dtype = params.dtype
                    same = (params.tobytes() == same and params.ndim == 1
                            and (dtype is float64 or dtype == float64))
                else:
                    same = same is not None and _same_dict(params, same)
                if same:
                    held = held_inputs[0]  # the inputs of the last call, inline
                    if inputs is held[0] and (inputs is None or (
                            input_test is None and inputs.dtype is float64
                            and inputs.ndim == 1 and inputs.strides == contiguous)):
                        u_view = held[1]
                    else:
                        u_view = inputs_view(inputs)
                    if u_view is not _REFUSED:
                        after, view = next_row()
                        if entry(link[2], setting[3], u_view, setting[5], view) == OK:
                            chain[0] = (after, after.tobytes(), view, setting)
                            return after
                    return checked(state, params, options, inputs)
        after = table_call(state, params, options, link, inputs)
        return checked(state, params, options, inputs) if after is None else after

    def table_call(state, params, options, link, u=None):
        """:func:`call` for a state of the table under screened parameters, else None."""
        if link[0] is not None:  # the chain broke: its last state joins the table
            _remember(trusted, link[1] + link[3][6])
        if options is None:
            options = sim.options
        if (type(state) is not ndarray or (state.dtype is not float64 and state.dtype != float64)
                or state.shape != shape or state.strides != contiguous
                or type(options) is not newton_options):
            return None
        screened = screen(params)
        if screened is None:
            return None
        p, tail = screened
        if state.tobytes() + tail not in trusted:
            return None
        u_view = inputs_view(u)
        if u_view is _REFUSED:
            return None
        setting = link[3]
        p_view = setting[3] if p is setting[2] else view_of(p)
        c_options = setting[5] if options is setting[4] else options_of(options)
        after, view = next_row()
        if entry(view_of(state), p_view, u_view, c_options, view) != OK:
            return None
        chain[0] = (after, after.tobytes(), view,
                    (params, _fingerprint(params, p), p, p_view, options, c_options, tail))
        return after

    return call


def _fingerprint(params, p: np.ndarray):
    """What tells that ``params`` still holds the values it had when it gave ``p``: a
    vector's bytes (with its dtype and shape, checked beside them), a copy of a dict of Python
    numbers with no zero (a zero's sign escapes an equality test) with its values' types,
    or None (never the same)."""
    if params is p:
        return p.tobytes()
    if type(params) is dict and 0 not in p:
        return params.copy(), tuple(map(type, params.values()))
    return None


def _same_dict(params: dict, kept: tuple) -> bool:
    """Whether a dict still equals the copy :func:`_fingerprint` kept, value for value and
    type for type (``True == 1``, but a bool is no parameter value: the checked path refuses
    it); a value whose comparison does not give one truth value (an array put in by the
    caller) counts as a change (the table's path then reports it)."""
    copy, types = kept
    try:
        return params == copy and tuple(map(type, params.values())) == types
    except (TypeError, ValueError):
        return False
