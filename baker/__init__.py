"""baker: an offline procedural animation baker for a many-legged creature."""

__version__ = "0.1.0"
