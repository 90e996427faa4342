"""optdesign.plot: pole maps over every region type, robust model clouds, result.plot(), Region.plot,
and the study figures moved from optdesign.studies -- checked without images (the artists drawn,
the axes limits containing the poles and the region's visible part)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

matplotlib = pytest.importorskip("matplotlib")
matplotlib.use("Agg")  # the test chooses the backend; the library never does
import matplotlib.pyplot as plt  # noqa: E402
from matplotlib.patches import Polygon  # noqa: E402

import optdesign  # noqa: E402
from optdesign import Plant  # noqa: E402
from optdesign.errors import ValidationError  # noqa: E402
from optdesign.plot import pole_map, region_extent, region_outline, robust_pole_map, view_box  # noqa: E402
from optdesign.regions import Disk, Ellipse, HalfPlane, HorizontalStrip, Sector, VerticalStrip  # noqa: E402

REGIONS = [
    HalfPlane(1.0),
    HalfPlane(-0.5),
    Disk(-2.0, 1.0),
    Disk.unit(0.9),
    Sector.from_damping(0.5),
    Sector(0.6, apex=-1.0),
    VerticalStrip(-3.0, -1.0),
    HorizontalStrip(2.0),
    Ellipse(-2.0, 1.5, 1.0),
    HalfPlane(1.0) & Sector.from_damping(0.5) & Disk(0.0, 10.0),
    VerticalStrip(-4.0, -1.0) & HorizontalStrip(1.5),
    Disk(0.0, 0.95) & Disk(0.3, 0.6),
]


@pytest.fixture(autouse=True)
def _close_figures():
    yield
    plt.close("all")


def _limits(ax):
    (x0, x1), (y0, y1) = ax.get_xlim(), ax.get_ylim()
    return x0, x1, y0, y1


def _inside(points, ax):
    x0, x1, y0, y1 = _limits(ax)
    z = np.asarray(points, dtype=complex)
    return bool(np.all((z.real >= x0) & (z.real <= x1) & (z.imag >= y0) & (z.imag <= y1)))


def _region_patch(ax):
    patches = [p for p in ax.patches if isinstance(p, Polygon)]
    assert len(patches) == 1, ax.patches
    return patches[0]


@pytest.mark.parametrize("region", REGIONS, ids=repr)
def test_region_plot_shades_the_region_and_shows_its_visible_part(region):
    ax = region.plot()
    patch = _region_patch(ax)
    xy = patch.get_xy()
    z = xy[:, 0] + 1j * xy[:, 1]
    size = float(np.ptp(xy[:, 0]) + np.ptp(xy[:, 1]))
    # every vertex lies in the closed region (to the bisection's accuracy) ...
    assert np.max(region.distance(z)) <= 1e-7 * size
    # ... and inside the axes, which show the region's extent (its bounding box, or a window at its edges)
    x0, x1, y0, y1 = region_extent(region)
    assert _inside(z, ax)
    assert _inside([x0 + 1j * y0, x1 + 1j * y1], ax)
    # the region's own edge is drawn as a line
    assert any(np.isfinite(line.get_xdata()).sum() > 10 for line in ax.lines)


@pytest.mark.parametrize("region", [Disk(-2.0, 1.0), Ellipse(-2.0, 1.5, 1.0), Disk.unit(0.9)], ids=repr)
def test_outline_of_a_bounded_region_is_its_boundary(region):
    z, on_region = region_outline(region, (-5.0, 5.0, -5.0, 5.0), n_rays=400)
    assert on_region.all()  # the box holds the whole region: every vertex is on the region's edge
    assert np.max(np.abs(region.distance(z))) <= 1e-8
    # an inscribed polygon: its area is the region's to O((pi/n)^2)
    area = 0.5 * abs(np.dot(z.real, np.roll(z.imag, 1)) - np.dot(z.imag, np.roll(z.real, 1)))
    exact = np.pi * (region.radius ** 2 if isinstance(region, Disk) else region.a * region.b)
    assert area == pytest.approx(exact, rel=1e-3)


def test_outline_is_empty_where_the_region_is_out_of_the_box():
    z, _ = region_outline(HalfPlane(1.0), (0.0, 2.0, -1.0, 1.0))
    assert z.size == 0
    with pytest.raises(ValidationError, match="box must be"):
        region_outline(HalfPlane(1.0), (1.0, 0.0, -1.0, 1.0))


@pytest.mark.parametrize("region", REGIONS, ids=repr)
def test_pole_map_limits_contain_poles_and_region(region):
    poles = np.array([-20.0 + 3j, -20.0 - 3j, -0.2, 0.4 + 0.1j, 0.4 - 0.1j])
    ax = pole_map(poles, region=region)
    _region_patch(ax)
    assert _inside(poles, ax)
    x0, x1, y0, y1 = region_extent(region)
    assert _inside([x0 + 1j * y0, x1 + 1j * y1], ax)
    # the poles are drawn as one scatter with every pole
    offsets = [c.get_offsets() for c in ax.collections]
    assert any(len(o) == poles.size for o in offsets)


def test_view_box_brings_the_imaginary_axis_or_the_unit_circle_into_view():
    x0, x1, y0, y1 = view_box([-2.0, -3.0 + 1j, -3.0 - 1j])
    assert x0 < -3.0 and x1 >= 0.0 and y0 == -y1 and y1 > 1.0
    # far from the axis: not forced into view (the poles would be squeezed)
    assert view_box([-1000.0, -1001.0])[1] < -900.0
    x0, x1, y0, y1 = view_box([0.5, 0.2 + 0.1j, 0.2 - 0.1j], discrete=True)
    assert x0 <= -1.0 and x1 >= 1.0 and y1 >= 1.0


def test_bare_poles_without_region_and_errors():
    ax = pole_map([-1.0, -2.0], open_loop=[1.0])
    assert not ax.patches
    assert _inside([-1.0, -2.0, 1.0], ax)
    with pytest.raises(ValidationError, match="region must be an optdesign Region"):
        pole_map([-1.0], region="left half-plane")
    with pytest.raises(ValidationError, match="ax must be a matplotlib Axes"):
        pole_map([-1.0], ax="axes")
    with pytest.raises(optdesign.NotFiniteError):
        pole_map([np.nan])


# ----------------------------------------------------------------------------- result.plot()
A2 = np.array([[0.0, 1.0], [-2.0, -1.0]])
C2 = np.array([[1.0, 0.0]])


@pytest.fixture(scope="module")
def plant():
    return Plant(A2, C2, G=np.eye(2), Q=np.eye(2), R=np.eye(1))


def test_observer_result_plot(plant):
    region = HalfPlane(1.0) & Sector.from_damping(0.5) & Disk(0.0, 8.0)
    res = optdesign.well_conditioned_observer(plant, region=region, seed=0)
    assert res.success
    ax = res.plot()
    _region_patch(ax)
    assert _inside(res.poles, ax) and _inside(np.linalg.eigvals(A2), ax)
    labels = ax.get_legend_handles_labels()[1]
    assert any("eig(A - LC)" in t for t in labels) and any("open loop" in t for t in labels)
    assert any(t.startswith("region: Re s <= -1 and damping >= 0.5") for t in labels)
    assert "ObserverDesign" in ax.get_title()


def test_kalman_results_plot(plant):
    kf = optdesign.kalman(plant)
    ax = kf.plot()
    assert not ax.patches and _inside(kf.poles, ax)
    ik = optdesign.kalman_for_poles(plant, [-2.0, -3.0])
    ax = ik.plot()
    labels = ax.get_legend_handles_labels()[1]
    assert "requested" in labels and _inside(ik.poles, ax)


def test_discrete_kalman_plot_draws_the_unit_circle():
    pd = Plant([[1.0, 0.1], [0.0, 0.9]], [[1.0, 0.0]], G=np.eye(2), Q=np.eye(2), R=np.eye(1), dt=0.1)
    kf = optdesign.kalman(pd)
    ax = kf.plot()
    assert "unit circle" in ax.get_legend_handles_labels()[1]
    assert _inside([-1.0, 1.0, 1j, -1j], ax) and ax.get_aspect() == 1.0


def test_feedback_result_plot():
    B = np.array([[0.0], [1.0]])
    res = optdesign.place(A2, B, [-2.0, -3.0])
    ax = res.plot(ax=plt.subplots()[1])
    labels = ax.get_legend_handles_labels()[1]
    assert any("eig(A - BK)" in t for t in labels) and _inside(res.computed_poles, ax)


def test_robust_result_and_model_set_plot(plant):
    ms = optdesign.ModelSet.vary(plant, [(1, 0)], 0.2)
    res = optdesign.robust_observer(ms, region=HalfPlane(0.5))
    ax = res.plot()
    _region_patch(ax)
    every = np.concatenate(res.poles)
    assert _inside(every, ax)
    assert any(t.startswith("worst: model") for t in ax.get_legend_handles_labels()[1])
    # a model set and a gain: the worst model is the one whose poles sit furthest right
    L = np.array([[1.0], [0.0]])
    ax = robust_pole_map(ms, L, region=HalfPlane(0.5))
    margins = [HalfPlane(0.5).margin(np.linalg.eigvals(p.A - L @ p.C)) for p in ms]
    k = int(np.argmax(margins))
    assert any(t.startswith(f"worst: {ms.label(k)}") for t in ax.get_legend_handles_labels()[1])
    with pytest.raises(ValidationError, match=r"gain must have shape \(n, p\) = \(2, 1\)"):
        robust_pole_map(ms, np.ones((1, 2)))
    with pytest.raises(ValidationError, match="needs the gain L"):
        robust_pole_map(ms)


def test_a_result_without_poles_says_so(plant):
    from optdesign.results import DesignResult, Status

    with pytest.raises(ValidationError, match="has no poles to draw"):
        DesignResult(status=Status.NOT_FOUND, message="nothing found").plot()


# ----------------------------------------------------------------------------- study figures
def test_study_figures_moved_and_old_names_still_import():
    import optdesign.plot.studies as new
    from optdesign.studies import plot_pareto, plot_table
    from optdesign.studies.spec import LABELS

    assert plot_pareto is new.plot_pareto and plot_table is new.plot_table and LABELS is new.LABELS


def test_no_backend_is_selected_by_the_library():
    root = Path(optdesign.__file__).parent
    for path in [*root.joinpath("plot").glob("*.py"), root / "studies" / "reproduce.py"]:
        text = path.read_text()
        assert "matplotlib.use(" not in text, path


def test_well_conditioned_feedback_plot():
    B = np.array([[0.0], [1.0]])
    region = HalfPlane(1.0) & Disk(0.0, 8.0)
    res = optdesign.well_conditioned_feedback(Plant(A2, np.eye(2), B=B), region=region, seed=0)
    assert res.success
    ax = res.plot()
    _region_patch(ax)
    labels = ax.get_legend_handles_labels()[1]
    assert "closed loop  eig(A - BK)" in labels and _inside(res.poles, ax)
