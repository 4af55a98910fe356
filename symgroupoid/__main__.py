"""``python -m symgroupoid``: see :mod:`symgroupoid.cli`."""

import sys

from .cli import main

sys.exit(main())
