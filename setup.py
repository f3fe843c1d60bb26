"""Build the optional compiled kernels (the regressor, the capsule distances); all other metadata lives in pyproject.toml.

``optional=True``: where no C compiler is available the install still succeeds and urident uses
its numpy implementations (same results, slower).
"""

from setuptools import Extension, setup

setup(
    ext_modules=[
        Extension(
            "urident.model._regressor_kernel",
            sources=["urident/model/_regressor_kernel.c"],
            extra_compile_args=["-O3", "-fno-math-errno"],  # lets gcc fuse sin/cos
            optional=True,
        ),
        Extension(
            "urident.excitation._capsule_kernel",
            sources=["urident/excitation/_capsule_kernel.c"],
            extra_compile_args=["-O3", "-fno-math-errno"],
            optional=True,
        ),
    ]
)
