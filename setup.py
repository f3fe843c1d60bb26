"""Build the optional compiled regressor kernel; all other metadata lives in pyproject.toml.

``optional=True``: where no C compiler is available the install still succeeds and urident uses
its numpy implementation of the regressor (same results, slower).
"""

from setuptools import Extension, setup

setup(
    ext_modules=[
        Extension(
            "urident.model._regressor_kernel",
            sources=["urident/model/_regressor_kernel.c"],
            extra_compile_args=["-O3", "-fno-math-errno"],  # lets gcc fuse sin/cos
            optional=True,
        )
    ]
)
