"""mapassoc: MAP multi-target track-set estimation by optimization."""

__version__ = "0.1.0"
