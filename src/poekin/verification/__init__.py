"""Verification against MuJoCo and its figures.

:func:`poekin.verify` (:mod:`~poekin.verification.verify`), :func:`poekin.diagnose`
(:mod:`~poekin.verification.diagnose`), the metrics file (:mod:`~poekin.verification.metrics`)
and the error plots (:mod:`~poekin.verification.plotting`).
"""
