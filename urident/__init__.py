"""urident: dynamic parameter identification for Universal Robots arms.

The Python API (:mod:`urident.api`) is available from here, imported on first use so that the
command line starts fast::

    import urident as ur
    ident = ur.identify(["ident.csv"], robot="ur10e")
"""

from importlib import import_module

from urident.version import __version__ as __version__


def __getattr__(name: str):
    """The API's names (:data:`urident.api.__all__`), loaded on first use."""
    if not name.startswith("_") and name != "api":
        api = import_module("urident.api")
        if name in api.__all__:
            return getattr(api, name)
    raise AttributeError(f"module 'urident' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted({*globals(), *import_module("urident.api").__all__})
