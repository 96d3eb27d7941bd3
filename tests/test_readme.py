"""The README's API tour runs as written, so the docs stay true."""

from __future__ import annotations

import pathlib
import re
import warnings

import poekin

README = pathlib.Path(__file__).resolve().parents[1] / "README.md"


def test_api_tour_runs() -> None:
    blocks = re.findall(r"```python\n(.*?)```", README.read_text(), re.S)
    assert blocks, "README has no python block"
    scope: dict[str, object] = {}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", poekin.AssetsStrippedWarning)
        for block in blocks:
            exec(compile(block, str(README), "exec"), scope)
    assert scope["T_world_ee"].shape == (1000, 4, 4)  # type: ignore[attr-defined]
    assert scope["report"].passed  # type: ignore[attr-defined]
