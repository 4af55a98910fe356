"""Layer 4: C99 code generation for step equations (residual, Jacobian, chart, Newton)."""

from ._band import band_order, jacobian_pattern
from ._emit import (
    KernelSource,
    current_umask,
    emit_c,
    generate_c,
    generate_program_c,
    precompile_templates,
    template_dir,
    templates_digest,
)
from ._kernel import MAX_PREFIX, c_identifier, hoisted_values
from ._printer import KernelCPrinter, print_c
from ._time import time_layout

__all__ = ["MAX_PREFIX", "KernelCPrinter", "KernelSource", "band_order", "c_identifier",
           "current_umask", "emit_c", "generate_c", "generate_program_c", "hoisted_values",
           "jacobian_pattern", "precompile_templates", "print_c", "template_dir",
           "templates_digest", "time_layout"]
