"""Being written this session (issue #28)."""

from typing import Any


def line_path(*args: Any, **kwargs: Any) -> Any:
    raise NotImplementedError


def screw_path(*args: Any, **kwargs: Any) -> Any:
    raise NotImplementedError
