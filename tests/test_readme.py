"""The README's example runs and says what its comments claim (a newcomer copies it first)."""

from __future__ import annotations

import contextlib
import io
import re
from pathlib import Path

import numpy as np
import pytest

README = Path(__file__).resolve().parents[1] / "README.md"


def _example() -> str:
    text = README.read_text(encoding="utf-8")
    section = text[text.index("## Example"):]
    match = re.search(r"```python\n(.*?)```", section, flags=re.S)
    assert match, "README's Example section has a python block"
    return match.group(1)


def test_readme_example_runs_and_its_comments_hold():
    pytest.importorskip("control")
    code = _example()
    ns: dict = {}
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        exec(compile(code, "README.md", "exec"), ns)  # noqa: S102 - our own README
    res, est, obs = ns["res"], ns["est"], ns["obs"]
    assert res.success and np.allclose(res.L.ravel(), [8.0, -6.0])          # "True [ 8. -6.]"
    assert est.ninputs == 2 and est.noutputs == 3                           # [u; y] -> [y_hat; x_hat]
    assert "not Kalman-optimal" in out.getvalue() and "7.337" in out.getvalue()  # "at 7.34 rad/s"
    assert obs.success and obs.region.contains(obs.poles)
    K = ns["od"].lqr_for_poles(ns["sys"], [-5, -8]).K
    np.testing.assert_allclose(K, [[34.0, 8.0]], rtol=1e-9)                 # "[[34. 8.]]"
