"""Jupyter views (issue 30): ``_repr_html_`` of design results and of Plant -- a compact table with
the status, the main numbers, the poles and every check -- well-formed and escaped."""

from __future__ import annotations

from html.parser import HTMLParser

import numpy as np
import pytest

import optdesign
from optdesign import Plant
from optdesign.regions import Disk, HalfPlane
from optdesign.results import Check, DesignResult, Status, Verification


class _Balance(HTMLParser):
    """Counts open tags: a well-formed fragment closes every table, row and cell it opens."""

    def __init__(self):
        super().__init__()
        self.depth = {"table": 0, "tr": 0, "td": 0, "th": 0, "pre": 0}
        self.text = []

    def handle_starttag(self, tag, attrs):
        if tag in self.depth:
            self.depth[tag] += 1

    def handle_endtag(self, tag):
        if tag in self.depth:
            self.depth[tag] -= 1

    def handle_data(self, data):
        self.text.append(data)


def _parse(fragment: str) -> str:
    p = _Balance()
    p.feed(fragment)
    p.close()
    assert all(v == 0 for v in p.depth.values()), p.depth
    return " ".join(" ".join(p.text).split())


@pytest.fixture(scope="module")
def plant():
    return Plant([[0.0, 1.0], [-2.0, -1.0]], [[1.0, 0.0]], G=np.eye(2), Q=np.eye(2), R=np.eye(1), name="<osc>")


def test_plant_html_shows_sizes_time_and_matrices(plant):
    text = _parse(plant._repr_html_())
    assert "Plant <osc>" in text  # escaped in the markup, restored by the parser
    assert "n = 2 states, p = 1 outputs, m = 2 noise inputs" in text and "continuous" in text
    for k in ("A", "C", "G", "Q", "R"):
        assert f" {k} " in f" {text} "
    assert "-2. -1." in text
    assert "<osc>" not in plant._repr_html_()
    pd = Plant([[1.0]], [[1.0]], dt=0.5)
    assert "discrete, dt = 0.5" in _parse(pd._repr_html_())


def test_result_html_has_status_numbers_poles_and_checks(plant):
    res = optdesign.well_conditioned_observer(plant, region=HalfPlane(1.0) & Disk(0.0, 8.0), seed=0)
    text = _parse(res._repr_html_())
    assert text.startswith("ObserverDesign")
    assert f"{res.status.value} (success: {res.success})" in text
    assert "kappa2" in text and f"{res.kappa2:.6g}" in text
    assert "poles" in text and f"{res.poles[0].real:.4g}" in text
    for c in res.verification:
        assert c.name in text
    assert text.count(" ok ") + text.count(" FAIL ") >= len(res.verification)


def test_kalman_and_robust_results_html(plant):
    kf = optdesign.kalman(plant)
    text = _parse(kf._repr_html_())
    assert "KalmanFilter" in text and "riccati_residual" in text and "poles" in text
    assert " L " in text and " P " in text and f"{kf.residual:.6g}" in text  # its main numbers
    ms = optdesign.ModelSet.vary(plant, [(1, 0)], 0.2)
    rob = optdesign.robust_observer(ms, region=HalfPlane(0.5))
    text = _parse(rob._repr_html_())
    assert "RobustObserverDesign" in text and "poles (per model) [0] -1" in text  # one line per model


def test_failed_check_and_escaping():
    res = DesignResult(status=Status.NOT_FOUND, message="x < 1 & y > 2",
                       verification=Verification.of([Check.at_most("pole_error", 1.0, 1e-8)]))
    html = res._repr_html_()
    assert "x &lt; 1 &amp; y &gt; 2" in html and "<b>FAIL</b>" in html
    text = _parse(html)
    assert "not_found (success: False)" in text and "1.000e+00 <= 1.000e-08" in text
