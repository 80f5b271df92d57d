"""The package's version (``mapassoc.__version__``), kept apart so that the command
line and run folders can read it without importing the package's public API."""

__all__ = ["__version__"]

__version__ = "0.1.0"
"""The package's version (PEP 440)."""
