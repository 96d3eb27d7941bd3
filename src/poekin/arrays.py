"""JAX arrays and PyTorch tensors: which library an array belongs to, its array-API namespace,
and the dtype rules of the generic FK path.

``chain.fk``, ``fk_body``, the chain Jacobians, ``tree.fk`` and ``tree.jacobian`` take JAX arrays
(tracers included: ``jit``, ``vmap``, ``grad``) and PyTorch tensors (autograd, ``torch.func``,
``torch.compile``) as well as NumPy arrays. NumPy goes to the compiled kernel; the others run the
NumPy reference formulas themselves (:mod:`poekin._pose`) through their library's array-API
namespace (`array-api-compat <https://data-apis.org/array-api-compat/>`_), and get back their own
kind of array, on their own device, in their own float dtype:

* a floating input keeps its dtype (float32 in, float32 out); integers and booleans become the
  library's default float (``torch.get_default_dtype()``; JAX's ``float64`` with
  ``jax_enable_x64``, else ``float32``). NumPy input gives float64, as always.
* model constants enter the computation as Python floats, so they take the input's dtype and
  device (no transfer, nothing to cache per device).
* shapes are checked (they are static under ``jit``); values are not: NaN or inf in gives NaN
  or inf out, with no check that would synchronise a device or branch on a traced value.

Nothing here imports JAX or PyTorch: an array is recognised by its type once the user's program
has imported its library.
"""

from __future__ import annotations

import sys
from collections.abc import Iterable
from typing import Any, Literal

import numpy as np

from poekin.errors import InputError

__all__ = [
    "Kind",
    "as_numpy",
    "convert",
    "float_dtype",
    "kind_of",
    "namespace",
    "namespace_of",
    "scalar",
]

Kind = Literal["jax", "torch"]
_namespaces: dict[str, Any] = {}


def kind_of(x: object) -> Kind | None:
    """``"jax"`` for a JAX array or tracer, ``"torch"`` for a PyTorch tensor, else None."""
    if isinstance(x, np.ndarray | float | int | list | tuple):
        return None
    torch = sys.modules.get("torch")
    if torch is not None and isinstance(x, torch.Tensor):
        return "torch"
    jax = sys.modules.get("jax")
    if jax is not None and isinstance(x, jax.Array):
        return "jax"
    return None


def namespace(kind: Kind) -> Any:
    """The array-API namespace of ``kind``'s arrays (``jax.numpy``; array-api-compat's torch).

    Imported by ``import`` statements, never ``importlib``: under ``torch.compile``, the first
    call of a process runs inside Dynamo's trace, which executes an ``import`` statement but
    refuses ``importlib.import_module`` (a graph break, an error with ``fullgraph=True``).
    """
    xp = _namespaces.get(kind)
    if xp is None:
        try:
            import array_api_compat  # noqa: F401  # the extra's requirement, JAX's included
        except ImportError as e:
            from poekin._extras import missing_extra

            what = "JAX arrays" if kind == "jax" else "PyTorch tensors"
            raise missing_extra("array-api-compat", kind, what) from e
        if kind == "jax":
            import jax.numpy as xp
        else:
            import array_api_compat.torch as xp
        _namespaces[kind] = xp
    return xp


def namespace_of(values: Iterable[object], what: str = "arrays") -> tuple[Any, Kind | None]:
    """The namespace and kind shared by ``values`` (NumPy's when none is a JAX array or a
    PyTorch tensor); :class:`InputError` if they mix JAX and PyTorch."""
    kinds = {k for k in map(kind_of, values) if k is not None}
    if len(kinds) > 1:
        raise InputError(f"{what} mix JAX arrays and PyTorch tensors; use one library")
    if not kinds:
        return np, None
    kind = kinds.pop()
    return namespace(kind), kind


def float_dtype(xp: Any, values: Iterable[Any]) -> Any:
    """The floating dtype (of ``xp``) of a result computed from ``values``: their promoted
    floating dtype, integers and booleans counting as the library's default float. NumPy arrays
    and lists among them count by their NumPy dtype."""
    default = xp.__array_namespace_info__().default_dtypes()["real floating"]
    dtypes = []
    for a in values:
        if kind_of(a) is None:
            kind = np.asarray(a).dtype
            if kind.kind == "f":
                dtypes.append(getattr(xp, kind.name))
            elif kind.kind in "biu":
                dtypes.append(default)
            else:
                raise InputError(f"expected real numbers, got an array of dtype {kind}")
        elif xp.isdtype(a.dtype, "real floating"):
            dtypes.append(a.dtype)
        elif xp.isdtype(a.dtype, ("integral", "bool")):
            dtypes.append(default)
        else:
            raise InputError(f"expected real numbers, got an array of dtype {a.dtype}")
    return xp.result_type(*dtypes) if dtypes else default


def convert(x: Any, xp: Any, dtype: Any, like: Any) -> Any:
    """``x`` as an array of ``xp`` in ``dtype``, on the device of ``like`` (an array of
    ``xp``): JAX and PyTorch arrays are cast, anything else (NumPy, lists) converted."""
    if kind_of(x) is not None:
        return x if x.dtype == dtype else xp.astype(x, dtype)
    if xp is np:
        return np.asarray(x, dtype=dtype)
    if kind_of(like) == "torch":  # a copy: torch would warn of a read-only array's view
        return xp.asarray(np.asarray(x), dtype=dtype, device=like.device, copy=True)
    return xp.asarray(np.asarray(x), dtype=dtype)


def scalar(c: float, xp: Any, like: Any) -> Any:
    """The constant ``c`` as an operand of ``xp``'s ``minimum`` or ``maximum`` with ``like``:
    itself for NumPy (and for JAX, whose Python floats are weakly typed), else a 0-d array of
    ``like``'s dtype and device (array-api-compat's PyTorch ``minimum`` promotes a Python float
    through ``result_type``, which torch.compile cannot trace)."""
    if kind_of(like) != "torch":
        return c
    return xp.asarray(c, dtype=like.dtype, device=like.device)


def as_numpy(x: Any, what: str) -> Any:
    """A NumPy copy of ``x`` (a JAX array, a PyTorch tensor, or anything NumPy takes).

    Raises:
        InputError: ``x`` is a traced value (inside ``jit``/``vmap``/``grad``), which has none.
    """
    kind = kind_of(x)
    if kind == "torch":
        return x.detach().cpu().numpy().copy()
    if kind == "jax":
        jax = sys.modules["jax"]
        if isinstance(x, jax.core.Tracer):
            raise InputError(
                f"{what} is a traced JAX value; build the model outside jit, vmap and grad"
            )
    return np.array(x, dtype=np.float64)
