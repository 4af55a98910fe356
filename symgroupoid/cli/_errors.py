"""Errors of the command line's own inputs (system files, data files, external tools).

Like every :class:`~symgroupoid.SymgroupoidError` they end a command with exit status 1 and
their one-line message (see :mod:`symgroupoid.cli`).
"""

from __future__ import annotations

from .._errors import SymgroupoidError


class SystemFileError(SymgroupoidError, ValueError):
    """A system file cannot be imported, or does not define the system asked for (none,
    several without a NAME to choose, a NAME that is not a system)."""


class InputError(SymgroupoidError, ValueError):
    """A data file (initial state, boundary data) or an option's text is malformed: not
    JSON, an unknown key, a value of the wrong kind; the message names the file and key."""


class ExternalToolError(SymgroupoidError, RuntimeError):
    """A program the command needs (``pdflatex``) is missing or failed."""


class LostContentError(ExternalToolError):
    """pdflatex wrote the PDF but reported content it could not place: a line wider than the
    page or a display taller than it beyond :data:`~symgroupoid.cli._derive.OVERFULL_TOLERANCE`,
    or characters missing from the fonts.  The PDF does not show all the equations."""
