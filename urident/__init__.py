"""urident: dynamic parameter identification for Universal Robots arms.

The Python API (:mod:`urident.api`) is available from here, imported on first use so that the
command line starts fast::

    import urident as ur
    ident = ur.identify(["ident.csv"], robot="ur10e")
"""

from urident.version import __version__

_API = ("Identification", "Validation", "check_trajectory", "diagnose_gap", "identify", "load_log",
        "validate", "design_excitation")
__all__ = ["__version__", *_API]


def __getattr__(name: str):
    if name in _API:
        from urident import api

        return getattr(api, name)
    raise AttributeError(f"module 'urident' has no attribute {name!r}")
