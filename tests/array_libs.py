"""JAX and PyTorch behind one small interface, for the tests that run the same checks on both:
make an array, read one back, and differentiate (forward- and reverse-mode)."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from typing import Any

import numpy as np
from helpers import import_extra

LIBRARIES = ["jax", "torch"]


@dataclasses.dataclass(frozen=True)
class Lib:
    """One array library, as the tests use it."""

    name: str
    module: Any
    asarray: Callable[..., Any]  # (NumPy array, dtype name) -> array
    # derivatives of f at each row of x (vmap): (batch, *f's shape, *a row's shape)
    jacobian: Callable[[Callable[[Any], Any], Any], Any]  # forward mode
    jacobian_rev: Callable[[Callable[[Any], Any], Any], Any]  # reverse mode
    grad: Callable[..., Any]  # grad(f, *args, argnums=0) of a scalar f

    def numpy(self, x: Any) -> np.ndarray:
        if self.name == "torch":
            return np.asarray(x.detach().cpu().numpy())
        return np.asarray(x)

    def dtype(self, x: Any) -> str:
        return str(x.dtype).removeprefix("torch.")


def _jax() -> Lib:
    jax = import_extra("jax")
    import_extra("array_api_compat")
    jax.config.update("jax_enable_x64", True)
    import jax.numpy as jnp

    def grad(f: Callable[..., Any], *args: Any, argnums: int = 0) -> Any:
        return jax.grad(f, argnums=argnums)(*args)

    return Lib(
        "jax",
        jax,
        lambda x, dtype="float64": jnp.asarray(x, dtype=dtype),
        lambda f, x: jax.vmap(jax.jacfwd(f))(x),
        lambda f, x: jax.vmap(jax.jacrev(f))(x),
        grad,
    )


def _torch() -> Lib:
    torch = import_extra("torch")
    import_extra("array_api_compat")

    def grad(f: Callable[..., Any], *args: Any, argnums: int = 0) -> Any:
        return torch.func.grad(f, argnums=argnums)(*args)

    return Lib(
        "torch",
        torch,
        lambda x, dtype="float64": torch.tensor(np.asarray(x), dtype=getattr(torch, dtype)),
        lambda f, x: torch.func.vmap(torch.func.jacfwd(f))(x),
        lambda f, x: torch.func.vmap(torch.func.jacrev(f))(x),
        grad,
    )


def load(name: str) -> Lib:
    """The library ``name`` (skips the test if it is not installed; see ``import_extra``)."""
    return _jax() if name == "jax" else _torch()
