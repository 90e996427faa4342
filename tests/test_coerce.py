"""Systems in: Plant, python-control and scipy systems converted in one place (issue 16, item 1)."""

from __future__ import annotations

import subprocess
import sys

import control
import numpy as np
import pytest
import scipy.signal as signal

from optdesign import Plant, kalman
from optdesign.errors import BackendUnavailableError, DimensionError, ValidationError
from optdesign.model.coerce import as_plant, as_system, system_kind

A = [[0.0, 1.0], [-6.0, -5.0]]
B = [[0.0], [1.0]]
C = [[1.0, 0.0]]
AD = [[0.9, 0.2], [-0.1, 0.8]]


# ------------------------------------------------------------------ accepted kinds
def test_plant_passes_through_and_takes_missing_noise_data():
    plant = Plant(A, C)
    assert as_plant(plant) is plant
    filled = as_plant(plant, Q=np.eye(2), R=[[2.0]])
    np.testing.assert_array_equal(filled.R, [[2.0]])
    np.testing.assert_array_equal(filled.Q, np.eye(2))
    g = as_plant(plant, G=[[0.0], [1.0]], Q=[[3.0]])
    assert g.m == 1 and g.Q[0, 0] == 3.0
    assert as_plant(plant, name="renamed").name == "renamed"


@pytest.mark.parametrize("dt", [0, None, 0.1])
def test_python_control_statespace(dt):
    sys_ = control.ss(AD if dt else A, B, C, 0, dt)
    plant = as_plant(sys_, Q=np.eye(2), R=[[1.0]])
    np.testing.assert_array_equal(plant.A, AD if dt else A)
    np.testing.assert_array_equal(plant.C, C)
    np.testing.assert_array_equal(plant.B, B)
    assert plant.dt == (0.1 if dt else None)
    assert plant.name is None                      # python-control's generated "sys[k]" is not kept
    named = control.ss(A, B, C, 0, name="motor")
    assert as_plant(named).name == "motor"


def test_scipy_systems():
    for sys_, dt in ((signal.lti(A, B, C, [[0.0]]), None), (signal.StateSpace(A, B, C, [[0.0]]), None),
                     (signal.dlti(AD, B, C, [[0.0]], dt=0.25), 0.25)):
        plant = as_plant(sys_, Q=np.eye(2), R=[[1.0]])
        np.testing.assert_array_equal(plant.B, B)
        assert plant.dt == dt
        assert system_kind(sys_) == "scipy"


def test_every_kind_gives_the_same_kalman_filter():
    ref = kalman(Plant(A, C, Q=np.eye(2), R=[[0.5]], B=B))
    for sys_ in (control.ss(A, B, C, 0), signal.lti(A, B, C, [[0.0]])):
        kf = kalman(sys_, Q=np.eye(2), R=[[0.5]])
        np.testing.assert_array_equal(kf.L, ref.L)
        np.testing.assert_array_equal(kf.P, ref.P)
        assert kf.success
    refd = kalman(Plant(AD, C, Q=np.eye(2), R=[[0.5]], dt=0.1))
    for sys_ in (control.ss(AD, B, C, 0, 0.1), signal.dlti(AD, B, C, [[0.0]], dt=0.1)):
        kf = kalman(sys_, Q=np.eye(2), R=[[0.5]])
        np.testing.assert_array_equal(kf.L, refd.L)
        np.testing.assert_array_equal(kf.Kf, refd.Kf)


def test_feedthrough_is_kept_by_as_system_and_refused_by_as_plant():
    sys_ = control.ss(A, B, C, [[0.5]])
    data = as_system(sys_, Q=np.eye(2), R=[[1.0]])
    np.testing.assert_array_equal(data.D, [[0.5]])
    assert data.H is None and data.source == "python-control StateSpace"
    with pytest.raises(ValidationError, match=r"nonzero feedthrough D \(max \|D\| = 0.5\).*estimator_system"):
        as_plant(sys_)
    assert as_system(control.ss(A, B, C, 0)).D is None


# ------------------------------------------------------------------ sensors and known (MATLAB kalman)
def test_known_and_sensors_split_inputs_and_outputs():
    Bfull = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 2.0]])        # inputs: u, w1, w2
    Cfull = np.array([[1.0, 0.0], [0.0, 1.0], [1.0, 1.0]])
    Dfull = np.array([[0.0, 0.0, 0.0], [0.3, 0.0, 0.1], [0.0, 0.0, 0.0]])
    sys_ = control.ss(A, Bfull, Cfull, Dfull)
    data = as_system(sys_, Q=np.eye(2), R=np.eye(2), sensors=[1, 2], known=[0])
    np.testing.assert_array_equal(data.plant.B, Bfull[:, [0]])
    np.testing.assert_array_equal(data.plant.G, Bfull[:, [1, 2]])
    np.testing.assert_array_equal(data.plant.C, Cfull[[1, 2]])
    np.testing.assert_array_equal(data.D, Dfull[np.ix_([1, 2], [0])])
    np.testing.assert_array_equal(data.H, Dfull[np.ix_([1, 2], [1, 2])])
    assert data.sensors == (1, 2) and data.known == (0,)
    # every input noise: no B
    every = as_system(sys_, Q=np.eye(3), R=np.eye(3), known=[])
    assert every.plant.B is None and every.plant.m == 3
    # a Plant: sensors select rows of C and the sub-block of R
    plant = Plant(A, Cfull, Q=np.eye(2), R=np.diag([1.0, 2.0, 3.0]))
    sel = as_system(plant, sensors=[2, 0]).plant
    np.testing.assert_array_equal(sel.C, Cfull[[2, 0]])
    np.testing.assert_array_equal(sel.R, np.diag([3.0, 1.0]))


@pytest.mark.parametrize("kw,match", [
    (dict(sensors=[3]), r"sensors\[0\] = 3 is out of range: the system has 3 outputs "
                        r"\(valid 0-based indices 0..2\)"),
    (dict(sensors=[-1]), r"sensors\[0\] = -1 is out of range"),
    (dict(sensors=[0, 0]), "sensors lists output 0 twice"),
    (dict(sensors=[]), "sensors must select at least one output"),
    (dict(sensors="0"), "sensors must be a list of 0-based output indices; found '0'"),
    (dict(sensors=[True]), r"sensors\[0\] must be an integer index; found True"),
    (dict(sensors=[0.0]), r"sensors\[0\] must be an integer index; found 0.0"),
    (dict(known=[5]), r"known\[0\] = 5 is out of range: the system has 3 inputs"),
    (dict(known=[0], G=np.eye(2)), r"G given twice: with known=\[0\] the other inputs \[1, 2\]"),
    (dict(Q=np.eye(4)), r"Q is 4 x 4 but sys has 3 input\(s\) and the plant has n = 2 states: say how the "
                        r"noise enters -- G= \(n x 4\), or known="),
])
def test_selection_errors(kw, match):
    sys_ = control.ss(A, np.ones((2, 3)), np.ones((3, 2)), 0)
    with pytest.raises(ValidationError, match=match):
        as_system(sys_, **kw)


# ------------------------------------------------------------------ refusals
def test_transfer_functions_are_refused_with_how_to_convert():
    with pytest.raises(ValidationError, match=r"python-control TransferFunction.*control.ss\(sys\)"):
        as_plant(control.tf([1.0], [1.0, 2.0]))
    with pytest.raises(ValidationError, match=r"scipy.signal TransferFunctionContinuous.*sys.to_ss\(\)"):
        as_plant(signal.lti([1.0], [1.0, 2.0]))
    with pytest.raises(ValidationError, match=r"scipy.signal ZerosPolesGainContinuous.*to_ss"):
        as_plant(signal.ZerosPolesGain([], [-1.0], 1.0))
    with pytest.raises(ValidationError, match=r"TransferFunction.*control.ss\(sys\)"):
        kalman(control.tf([1.0], [1.0, 2.0]), Q=[[1.0]], R=[[1.0]])


def test_other_objects_are_refused_with_one_message():
    kinds = r"plant must be an optdesign.Plant, a python-control StateSpace or a scipy.signal StateSpace"
    with pytest.raises(ValidationError, match=kinds + r".*; found ndarray"):
        as_plant(np.eye(2))
    with pytest.raises(ValidationError, match=r"found tuple \(a tuple of matrices\? build optdesign.Plant"):
        as_plant((A, B, C, 0))
    with pytest.raises(ValidationError, match=r"found the python-control FrequencyResponseData, which is"):
        as_plant(control.frd([1.0, 2.0], [0.1, 1.0]))


def test_unspecified_sampling_time_is_one_and_said():
    """dt=True (control.drss, scipy's dlti default): discrete with dt = 1, said in the notes and the
    Kalman result (issue 27 item 4; it was refused)."""
    for sys_ in (control.ss(AD, B, C, 0, True), signal.dlti(AD, B, C, [[0.0]])):
        data = as_system(sys_, G=np.eye(2), Q=np.eye(2), R=[[1.0]])
        assert data.plant.dt == 1.0 and data.dt_unspecified
        assert any("unspecified sampling period (dt=True): designed with dt = 1" in t for t in data.notes)
        kf = kalman(sys_, G=np.eye(2), Q=np.eye(2), R=[[1.0]])
        ref = kalman(Plant(AD, C, Q=np.eye(2), R=[[1.0]], dt=1.0))
        np.testing.assert_array_equal(kf.L, ref.L)
        assert "dt = 1" in kf.message and kf.extra["dt_unspecified"] is True
    assert not as_system(control.ss(AD, B, C, 0, 0.5)).dt_unspecified


def test_data_given_twice_or_misplaced():
    plant = Plant(A, C, Q=np.eye(2), R=[[1.0]])
    with pytest.raises(ValidationError, match=r"Q given twice: the plant already has Q; use plant.replace"):
        as_plant(plant, Q=np.eye(2))
    with pytest.raises(ValidationError, match="R given twice"):
        as_plant(plant, R=[[1.0]])
    with pytest.raises(ValidationError, match="G given twice: the plant already has G"):
        as_plant(plant, G=[[1.0], [0.0]])
    with pytest.raises(ValidationError, match="known applies to a system whose inputs mix"):
        as_system(plant, known=[0])
    with pytest.raises(DimensionError, match="R has the wrong shape"):
        as_plant(control.ss(A, B, C, 0), R=np.eye(2))


def test_python_control_is_optional():
    """Without python-control: Plants and scipy systems convert, estimators come back as arrays, and
    asking for a python-control system names the package."""
    code = """
import sys
sys.modules["control"] = None          # import control -> ImportError
import numpy as np, scipy.signal as signal
from optdesign import Plant, kalman
from optdesign.model.coerce import as_plant
from optdesign.design.estimator import EstimatorArrays
from optdesign.errors import BackendUnavailableError
sys_ = signal.lti([[0., 1.], [-6., -5.]], [[0.], [1.]], [[1., 0.]], [[0.]])
kf = kalman(as_plant(sys_, Q=np.eye(2), R=[[1.]]))
est = kf.estimator()
assert isinstance(est, EstimatorArrays), type(est)
A, B, C, D = est
assert B.shape == (2, 2) and C.shape == (3, 2)
try:
    kf.estimator(output="control")
except BackendUnavailableError as exc:
    assert "pip install control" in str(exc)
else:
    raise SystemExit("no error")
print("ok")
"""
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "ok"
    assert issubclass(BackendUnavailableError, ImportError)
