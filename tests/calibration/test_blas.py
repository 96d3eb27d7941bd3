"""poekin._blas: calibration's linear algebra runs on one BLAS thread, and the count
comes back."""

from __future__ import annotations

import importlib
from typing import Any

import numpy as np
import pytest
import threadpoolctl

import poekin
from poekin import _blas


def _blas_threads() -> list[int]:
    return [
        int(lib["num_threads"])
        for lib in threadpoolctl.threadpool_info()
        if lib["user_api"] == "blas"
    ]


def test_one_thread_limits_and_restores() -> None:
    if not _blas_threads():
        pytest.skip("NumPy reports no BLAS library threadpoolctl knows")
    with threadpoolctl.threadpool_limits(limits=2, user_api="blas"):
        before = _blas_threads()
        with _blas.one_thread():
            assert _blas_threads() == [1] * len(before)
        assert _blas_threads() == before


def test_calibrate_fits_on_one_blas_thread(ur5e: poekin.Chain, monkeypatch: Any) -> None:
    """Inside poekin.calibrate the fit sees one BLAS thread; the caller's count is restored,
    also when the call raises."""
    if not _blas_threads():
        pytest.skip("NumPy reports no BLAS library threadpoolctl knows")
    module = importlib.import_module("poekin.calibration")
    seen: list[list[int]] = []
    real = module.fit

    def spy(*args: Any, **kwargs: Any) -> Any:
        seen.append(_blas_threads())
        return real(*args, **kwargs)

    monkeypatch.setattr(module, "fit", spy)
    q = poekin.sample_joint_values(ur5e, 30, seed=1)
    with threadpoolctl.threadpool_limits(limits=2, user_api="blas"):
        before = _blas_threads()
        poekin.calibrate(ur5e, q, ur5e.fk(q), folds=0)
        assert seen and all(t == [1] * len(before) for t in seen)
        assert _blas_threads() == before
        with pytest.raises(poekin.errors.InputError):
            poekin.calibrate(ur5e, q, np.full((30, 3), np.nan))
        assert _blas_threads() == before
