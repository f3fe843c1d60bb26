"""urident's version, in a module of its own: code that records it (log sidecars, trajectory files)
need not import the package, whose ``__init__`` loads the API on first use."""

__version__ = "0.1.0"
