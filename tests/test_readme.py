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


def test_readme_examples_are_silent_on_stderr(capfd):
    """Issue 26 item 3: library code never prints -- no solver chatter (CasADi, IPOPT, cvxpy) reaches the
    terminal while the README's examples run (the compat block included); stdout carries the example's
    own prints only, and no warning is raised."""
    import warnings

    pytest.importorskip("control")
    text = README.read_text(encoding="utf-8")
    section = text[text.index("## Example"):text.index("## Documentation")]
    blocks = re.findall(r"```python\n(.*?)```", section, flags=re.S)
    assert len(blocks) >= 2, "the example and the drop-ins' block"
    ns: dict = {}
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        for code in blocks:
            exec(compile(code, "README.md", "exec"), ns)  # noqa: S102 - our own README
    out, err = capfd.readouterr()
    assert err == "", err[-2000:]
    assert "WARNING" not in out and "Ipopt" not in out and "inaccurate" not in out, out[-2000:]
