"""The compiled kernel: C sources and their Python face.

``_kernel.c`` (with the ``_ik_*.h`` and ``_kernel_core.h`` headers it includes) is the C
extension ``poekin.kernel._kernel``: forward kinematics, Jacobians and the inverse kinematics
solver, and (``_distance.h``) the distances of convex shapes of :mod:`poekin.collision`, the
fast twin of the NumPy reference path, bit for bit. :mod:`poekin.kernel._fast`
turns models into programs for it and holds its settings (``poekin.compiled_kernel()``,
``poekin.set_threads``); :mod:`poekin.kernel._sincos` is its sine and cosine as array
arithmetic. Without a C compiler the extension is absent and poekin runs the NumPy path.
"""
