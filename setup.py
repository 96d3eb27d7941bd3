"""Build the compiled FK kernel ``poekin.kernel._kernel``; everything else is in pyproject.toml.

The extension is optional: without a C compiler poekin installs anyway and runs its pure-NumPy
path (``poekin.compiled_kernel()`` is then False).
"""

import numpy as np
from setuptools import Extension, setup
from setuptools.command.build_ext import build_ext

# -ffp-contract=off: no fused multiply-add, so one configuration gives the same bits on every
# instruction set the kernel picks at run time. -fno-math-errno lets sqrt vectorise.
_UNIX_FLAGS = ["-O3", "-std=c11", "-ffp-contract=off", "-fno-math-errno", "-Wno-psabi", "-pthread"]


class _BuildExt(build_ext):
    def build_extensions(self) -> None:
        if self.compiler.compiler_type == "unix":
            for ext in self.extensions:
                ext.extra_compile_args = [*_UNIX_FLAGS, *ext.extra_compile_args]
                ext.extra_link_args = ["-pthread", *ext.extra_link_args]
        super().build_extensions()


setup(
    ext_modules=[
        Extension(
            "poekin.kernel._kernel",
            ["src/poekin/kernel/_kernel.c"],
            depends=[
                f"src/poekin/kernel/{name}.h"
                for name in (
                    "_kernel_core",
                    "_distance",
                    "_ik_all",
                    "_ik_common",
                    "_ik_core",
                    "_ik_step",
                    "_ik_type",
                )
            ],
            include_dirs=[np.get_include()],
            define_macros=[("NPY_TARGET_VERSION", "NPY_1_24_API_VERSION")],
            optional=True,
        )
    ],
    cmdclass={"build_ext": _BuildExt},
)
