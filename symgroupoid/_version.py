"""The library's version: a leaf module (it imports nothing), read by the package, the kernel
cache's key, the C emitter's headers, the command line and the build (pyproject.toml)."""

__version__ = "0.1.0"
