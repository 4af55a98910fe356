"""The ``symgroupoid`` command line (also ``python -m symgroupoid``).

Commands on a system file ``FILE.py[:NAME]`` (:mod:`._system_file`)::

    symgroupoid derive   FILE.py [--document OUT.tex] [--pdf]
    symgroupoid emit     FILE.py -o DIR
    symgroupoid simulate FILE.py --steps N [--params h=0.01,...] [--initial STATE.json]
                                 [--every K] [-o TRAJ.npz|TRAJ.csv]
    symgroupoid bvp      FILE.py BOUNDARY.json [-o SOLUTION.npz|.csv] [--check]
    symgroupoid verify   FILE.py [--params ...] [--initial ...]

and ``cache info|clear``, ``demo``, ``generate OUTDIR``, ``--version``.  One module per
command group; the formats and exit statuses are documented in docs/cli.md and
:mod:`._main`.
"""

from ._derive import OVERFULL_TOLERANCE, lost_content
from ._errors import InputError, SystemFileError
from ._inputs import parse_count, parse_params
from ._main import build_parser, main
from ._seeds import generate_seed_kernels
from ._simulate import conservation_lines
from ._system_file import load_system
from ._verify import JACOBIAN_TOLERANCE, sample_points

__all__ = ["JACOBIAN_TOLERANCE", "OVERFULL_TOLERANCE", "InputError", "SystemFileError",
           "build_parser", "conservation_lines", "generate_seed_kernels", "load_system",
           "lost_content", "main", "parse_count", "parse_params", "sample_points"]
