"""Jinja2 templates of the generated C kernels (installed as ``symgroupoid.templates``)."""
