"""s2cl's version, in a module of its own so that every package can name it without importing ``s2cl``."""

__version__ = "0.1.0"
