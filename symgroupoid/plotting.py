"""Figures of trajectories and of the drift of their conserved quantities (matplotlib).

matplotlib is an optional dependency (``pip install 'symgroupoid[plot]'``), imported when a
figure is asked for.  Figures are :class:`matplotlib.figure.Figure` objects made without
pyplot (no global state; they display in Jupyter and save with ``fig.savefig``); pass
``path=`` to save one directly.

The rounding floor drawn (dashed) next to each drift is ε·(|Q|·√k + S)
(:func:`~symgroupoid.diagnostics.rounding_floor`): a conserved quantity Q computed in double
precision moves by about one rounding ε·|Q| per step, in random directions, so after k
steps its drift is of order ε·|Q|·√k; and each value of Q rounds at ε·S, S the size of the
terms it is computed from (far above |Q| for a momentum (x₁ − x₀)/h at large x).
Dotted: σ·√k with σ the measured step-to-step change of Q
(:attr:`~symgroupoid.diagnostics.Drift.step_variation`), the random walk of the rounding
the steps actually incur (a Newton residual at its own floor can exceed ε·|Q|).  A drift
that follows these lines is rounding; one that grows like k, far above them, is not.
"""

from __future__ import annotations

from collections.abc import Sequence
from os import PathLike

import numpy as np

from ._arguments import flag_argument, integer_argument, names_argument, path_argument
from ._errors import (
    DiagnosticsError,
    DomainError,
    InputNameError,
    InputTypeError,
    OutputError,
    SymgroupoidError,
)
from .runtime import (
    Drift,
    constraint_residuals,
    energy_changes,
    energy_drift,
    has_energy,
    noether_drifts,
    trajectory_programs,
)

__all__ = ["MissingDependencyError", "plot_conservation", "plot_trajectory"]


class MissingDependencyError(SymgroupoidError, ImportError):
    """An optional dependency (matplotlib for figures) is not installed."""


def _figure_class():
    try:
        from matplotlib.figure import Figure
    except ImportError as err:
        raise MissingDependencyError(
            "figures need matplotlib, which is not installed: pip install matplotlib (or "
            "pip install 'symgroupoid[plot]')") from err
    return Figure


def _output(path, owner: str):
    """``path`` checked before any drawing: None, or a path whose suffix names a format
    matplotlib writes (``.png``, ``.pdf``, ``.svg``, …)."""
    if path is None:
        return None
    path = path_argument(path, "path", owner=owner)
    from matplotlib.backend_bases import FigureCanvasBase

    formats = FigureCanvasBase.get_supported_filetypes()
    if path.suffix.lstrip(".").lower() not in formats:
        raise DomainError(f"{owner}: path {str(path)!r} must end in the suffix of a figure "
                          f"format ({', '.join('.' + f for f in sorted(formats))})")
    if not path.parent.is_dir():  # refused before any drawing
        raise OutputError(f"{owner}: the figure cannot be written to path {str(path)!r}: "
                          f"the directory {str(path.parent)!r} does not exist")
    return path


def _finish(fig, path: str | PathLike | None, owner: str):
    """Lay the figure out and, given a path, write it as every output of the library is
    written: into a temporary file beside the target, renamed into place at the end, so
    that a full disk or an interrupted write keeps the previous figure and leaves no
    truncated one."""
    fig.tight_layout()
    if path is not None:
        from .runtime import atomic_write  # (the file module loads when first used)

        target = path_argument(path, "path", owner=owner)
        kind = target.suffix.lstrip(".").lower()
        try:
            atomic_write(target, lambda f: fig.savefig(f, format=kind, dpi=120), binary=True)
        except OutputError as exc:
            raise OutputError(f"{owner}: the figure {exc}") from None
        except RuntimeError as exc:  # a format whose backend needs a missing tool (.pgf)
            raise OutputError(f"{owner}: matplotlib cannot write the figure to path "
                              f"{str(target)!r} in that format ({exc}); choose another "
                              f"format, e.g. .png or .pdf") from exc
        except Exception as exc:
            cause = _os_error_within(exc)
            if cause is None:
                raise
            # matplotlib's PDF writer, failing to write, raises its own error while closing
            raise OutputError(f"{owner}: the figure cannot be written to path "
                              f"{str(target)!r}: {cause.strerror or cause}") from None
    return fig


def _os_error_within(exc: BaseException) -> OSError | None:
    """The file system's error among the causes and contexts of ``exc``, or None."""
    seen = set()
    while exc is not None and id(exc) not in seen:
        if isinstance(exc, OSError):
            return exc
        seen.add(id(exc))
        exc = exc.__cause__ or exc.__context__
    return None


def _legend(ax, **options) -> None:
    """The panel's legend beside it, on the right, where it covers no curve."""
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0, **options)


def _semilogy(ax, x, y, **style) -> None:
    """``y`` against ``x`` on the log axis (values that are exactly 0 are gaps); a single
    point as a marker, which a line of one point would not show."""
    y = np.where(y > 0, y, np.nan)
    ax.semilogy(x, y, marker="o" if len(y) == 1 else None, ms=3, **style)


def _drift_label(q: Drift) -> str:
    """A drift's legend entry: its largest value, and where it is exactly 0 (gaps on the log
    axis, or no curve at all)."""
    drift = q.drift
    if len(drift) < 2:
        return f"{q.name} (one state: no drift to show)"
    if not np.any(drift[1:] > 0):
        return f"{q.name} (exactly Q_0 at every step: no curve)"
    gaps = ", gaps: exactly Q_0" if np.any(drift[1:] == 0) else ""
    return f"{q.name} (max {q.max_drift:.1e}{gaps})"


def _owner(trajectory) -> str:
    layout = getattr(trajectory, "_layout", None)
    if layout is None:
        raise InputTypeError(f"plot_trajectory: trajectory must be a Trajectory (from "
                             f"Simulator.simulate), got {type(trajectory).__name__}")
    return layout.step_name


def _part_positions(trajectory, name: str, n: int) -> np.ndarray:
    """Step positions of the n values of a named part (older values of the first state first,
    then the newest value of each state; see :class:`Trajectory`)."""
    idx = np.asarray(trajectory.step_indices, float)
    older = n - len(idx)
    return np.concatenate([idx[0] + np.arange(older), idx + older])


def _entry_label(name: str, shape: tuple, j: int) -> str:
    """``W[0, 2]``: entry j of a part of the given shape, its indices as plain integers."""
    return f"{name}[{', '.join(str(int(i)) for i in np.unravel_index(j, shape))}]"


def _time_axis(trajectory, time_step, owner: str) -> tuple[float | None, str]:
    """(h, its name) for a time axis t = k·h, or (None, "") for the step index: the
    parameter named by ``time_step``, or (None) the system's time step — declared
    (``time_step=`` of the system) or identified by the continuous limit, as the energy
    finds it — when it can be told; False: the step index."""
    if time_step is False:
        return None, ""
    if time_step is None:
        try:
            found = trajectory_programs(trajectory).time_step()
        except DiagnosticsError:  # a trajectory that does not know its equations
            found = None
        if found is None or str(found) not in trajectory.parameters:
            return None, ""
        time_step = str(found)
    if not isinstance(time_step, str) or time_step not in trajectory.parameters:
        raise InputNameError(f"{owner}: time_step must name a parameter (one of "
                             f"{', '.join(trajectory.parameters) or 'none'}) or be False, "
                             f"got {time_step!r}")
    return float(trajectory.parameters[time_step]), time_step


def _axis_label(h: float | None, h_name: str) -> str:
    return "step k" if h is None else f"time t = k·{h_name} ({h_name} = {h:g})"


def plot_trajectory(trajectory, parts: Sequence[str] | None = None, *,
                    path: str | PathLike | None = None, max_parts: int = 6,
                    time_step: str | bool | None = None):
    """One panel per named part (default: the first ``max_parts`` of ``trajectory.keys()``),
    every entry of the part against its position in time (a pair-groupoid coordinate at
    q_0 … q_{N+1}, a matrix part entry by entry, labelled ``W[0, 2]``).

    The horizontal axis is the time t = k·h when the time step h is known — named by
    ``time_step`` (a parameter's name), or declared by the system, or the one parameter that
    behaves as the step in the continuous limit — else the step index k
    (``time_step=False`` forces it).  Returns the figure."""
    Figure = _figure_class()
    owner = _owner(trajectory)
    max_parts = integer_argument(max_parts, "max_parts", minimum=1, owner=owner)
    h, h_name = _time_axis(trajectory, time_step, owner)
    names = (list(trajectory.keys())[:max_parts] if parts is None
             else list(names_argument([parts] if isinstance(parts, str) else parts, "parts",
                                      owner=owner)))
    for name in names:
        if name not in trajectory:
            raise InputNameError(f"{owner}: no part named {name!r}; available: "
                                 f"{', '.join(trajectory.keys())}")
    if not names:
        raise DomainError(f"{owner}: plot_trajectory: no parts to plot (parts is empty)")
    path = _output(path, owner)
    fig = Figure(figsize=(8.5, 2.2 * len(names) + 0.6))
    axes = fig.subplots(len(names), 1, sharex=True, squeeze=False)[:, 0]
    for ax, name in zip(axes, names):
        values = np.asarray(trajectory[name])
        flat = values.reshape(len(values), -1)
        x = _part_positions(trajectory, name, len(values))
        if h is not None:
            x = x * h
        for j in range(flat.shape[1]):
            label = name if flat.shape[1] == 1 else _entry_label(name, values.shape[1:], j)
            ax.plot(x, flat[:, j], lw=1, label=label)
        ax.set_ylabel(name)
        if 1 < flat.shape[1] <= 9:
            _legend(ax, fontsize="x-small")
    axes[-1].set_xlabel(_axis_label(h, h_name))
    axes[0].set_title(f"{trajectory._layout.step_name}: {trajectory.steps} steps")
    return _finish(fig, path, owner)


def _drift_panel(ax, quantities: list[Drift], h: float | None,
                 changes: Sequence[Drift] = ()) -> None:
    """Each quantity's drift |Q_k − Q_0| with its floors; ``changes``: quantities that are
    not conserved (a forced system's Noether quantity), their |Q_k − Q_0| thin and grey, for
    comparison with the balance that is."""
    for q in changes:
        k = np.asarray(q.step_indices, float) * (1.0 if h is None else h)
        _semilogy(ax, k, q.drift, color="0.55", lw=0.8, label=_drift_label(q))
    for i, q in enumerate(quantities):
        color = f"C{i}"
        k = np.asarray(q.step_indices, float) * (1.0 if h is None else h)
        _semilogy(ax, k, q.drift, color=color, lw=1, label=_drift_label(q))
        _semilogy(ax, k, q.floor, color=color, lw=1, ls="--", alpha=0.7)
        _semilogy(ax, k, q.measured_floor, color=color, lw=1, ls=":", alpha=0.7)
    ax.plot([], [], color="0.4", ls="--", lw=1, label="rounding floor ε·(|Q|·√k + S)")
    ax.plot([], [], color="0.4", ls=":", lw=1, label="step-to-step variation σ·√k")
    ax.set_ylabel("|Q_k − Q_0|")
    _legend(ax, fontsize="small")


def plot_conservation(trajectory, energy: bool | None = None, momenta: Sequence = (), *,
                      constraints: bool | None = None, step_parameter: str | None = None,
                      path: str | PathLike | None = None, time_step: str | bool | None = None):
    """The drift |Q_k − Q_0| of each conserved quantity on a log scale, each with its
    rounding floor ε·(|Q|·√k + S) dashed in the same colour, and (``constraints``) the constraint
    residual max_a |φ_a| of each state in a second panel.

    ``energy``: the discrete energy (see :func:`symgroupoid.diagnostics.energy`; None: when
    defined); ``momenta``: Noether quantities (:class:`~symgroupoid.NoetherQuantity`, or
    sections given to ``system.noether``; a mapping label → quantity names them).  The
    Noether quantity J of a forced system is not conserved: it changes by the forces'
    impulse (docs/conventions.md §20), so its balance J_k − Σ_{j<k} I_j is plotted with its
    floors, and |J_k − J_0| thin and grey beside it (the trajectory kept every step); nor is
    its energy, nor on a time groupoid the energy of an L that depends on the time or of a
    system with constraints (:func:`symgroupoid.diagnostics.energy_changes`): these are
    plotted only when asked for (``energy=True``);
    ``constraints``: None plots them when the system
    has constraints.  The horizontal axis is the time t = k·h when the time step h is known
    (``time_step``: a parameter's name; None: ``step_parameter``, else the step the system
    declares or the one its continuous limit identifies), else the step index k
    (``time_step=False`` forces it); the floors are functions of k either way.  Returns the
    figure (saved to ``path`` if given).
    """
    Figure = _figure_class()
    programs = trajectory_programs(trajectory)
    owner = programs.name
    energy = None if energy is None else flag_argument(energy, "energy", owner=owner)
    constraints = (None if constraints is None
                   else flag_argument(constraints, "constraints", owner=owner))
    path = _output(path, owner)
    h, h_name = _time_axis(trajectory, step_parameter if time_step is None else time_step,
                           owner)
    idx = trajectory.step_indices
    quantities = []
    defined = energy or (energy is None and has_energy(trajectory, step_parameter))
    changing = energy_changes(trajectory, step_parameter) if energy is None and defined \
        else None
    if defined and changing is None:
        quantities.append(energy_drift(trajectory, step_parameter))
    conserved, changes = noether_drifts(trajectory, programs, momenta)
    quantities += conserved
    show_phi = programs.has_constraints if constraints is None else constraints
    if show_phi and not programs.has_constraints:
        raise DomainError(f"{programs.name}: constraints=True, but the system has no "
                          f"constraints to plot")
    if not quantities and not show_phi:
        why = (f"the energy is not conserved ({changing}; energy=True plots it)" if changing
               else "no energy is defined (declare the system's time_step=, or pass "
                    "step_parameter=...)")
        raise DomainError(f"{programs.name}: nothing to plot: {why} and no Noether quantity "
                          f"was given (momenta=[...])")
    panels = int(bool(quantities)) + int(show_phi)
    fig = Figure(figsize=(9.5, 3 * panels + 0.6))
    axes = list(fig.subplots(panels, 1, sharex=True, squeeze=False)[:, 0])
    if quantities:
        _drift_panel(axes[0], quantities, h, changes)
    if show_phi:
        ax = axes[-1]
        phi = np.max(np.abs(constraint_residuals(trajectory)), axis=1)
        x = np.asarray(idx, float) * (1.0 if h is None else h)
        _semilogy(ax, x, phi, color="C7", lw=1, label=f"max |φ| (max {phi.max():.1e})"
                  if np.any(phi > 0) else "max |φ| (exactly 0 at every state: no curve)")
        ax.set_ylabel("constraints |φ|")
        _legend(ax, fontsize="small")
    axes[-1].set_xlabel(_axis_label(h, h_name))
    axes[0].set_title(f"{trajectory._layout.step_name}: conservation over "
                      f"{trajectory.steps} steps")
    return _finish(fig, path, owner)
