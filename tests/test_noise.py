"""Output-noise models (seed 003 eq (10)-(14)): polynomials, realizations, signals, validation."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from optdesign.classical.placement import pole_error
from optdesign.errors import DimensionError, NotFiniteError, ValidationError
from optdesign.noise import NoiseModel, Polynomial, Sinusoid, Step


def _ctrb(N, M):
    return np.hstack([np.linalg.matrix_power(N, k) @ M for k in range(N.shape[0])])


# ------------------------------------------------------------------------------ step
def test_step_is_the_pi_observer_model():
    s = Step()
    assert s.coefficients.tolist() == [1.0, -1.0]
    assert s.order == 1
    np.testing.assert_array_equal(s.N, [[1.0]])
    np.testing.assert_array_equal(s.M, [[1.0]])
    np.testing.assert_array_equal(s.Gamma, [[1.0]])
    np.testing.assert_allclose(s.modes, [1.0])
    assert s.dt is None
    np.testing.assert_allclose(s.signal(5, 0.3), 0.3)
    assert np.max(np.abs(s.annihilate(s.signal(20, -2.0)))) == 0.0
    # a non-constant signal is not annihilated
    assert np.max(np.abs(s.annihilate(np.arange(5.0)))) == pytest.approx(1.0)


# -------------------------------------------------------------------------- sinusoid
def test_sinusoid_reproduces_seed003_polynomial_and_N():
    # seed 003 section 5: 0.2 sin(2 pi t), T = 0.01 s -> P(q) = q^2 - 1.9961 q + 1 (printed to 4 decimals),
    # N = [[0, 1], [-1, 1.9961]], M = [0; 1] (M lost by the OCR, eq (14) gives e_r)
    s = Sinusoid(1.0, 0.01)
    assert s.coefficients[1] == pytest.approx(-1.9961, abs=5e-5)
    assert s.coefficients[1] == pytest.approx(-2 * math.cos(2 * math.pi * 0.01), rel=1e-15)
    np.testing.assert_allclose(s.N, [[0.0, 1.0], [-1.0, 1.9961]], atol=5e-5)
    np.testing.assert_array_equal(s.M, [[0.0], [1.0]])
    np.testing.assert_array_equal(s.Gamma, [[1.0, 0.0]])
    np.testing.assert_allclose(np.abs(s.modes), 1.0, rtol=1e-14)
    np.testing.assert_allclose(np.sort(np.angle(s.modes)), [-s.theta, s.theta], rtol=1e-14)
    assert s.theta == pytest.approx(2 * math.pi * 0.01)
    assert s.frequency == pytest.approx(1.0)


def test_sinusoid_angular_frequency_is_equivalent():
    a, b = Sinusoid(1.0, 0.01), Sinusoid(omega=2 * math.pi, dt=0.01)
    assert a == b
    np.testing.assert_allclose(a.coefficients, b.coefficients, rtol=1e-15)


@pytest.mark.parametrize("amp,phase", [(0.2, 0.0), (-1.3, 0.7), (5.0, 2.0)])
def test_sinusoid_annihilates_any_amplitude_and_phase(amp, phase):
    s = Sinusoid(3.0, 0.02)
    x = s.signal(200, amp, phase)
    np.testing.assert_allclose(x[:3], amp * np.sin(s.theta * np.arange(3) + phase))
    assert np.max(np.abs(s.annihilate(x))) < 1e-13 * max(1, abs(amp))
    # a sinusoid of another frequency is not annihilated
    other = Sinusoid(4.0, 0.02).signal(200, amp, phase)
    assert np.max(np.abs(s.annihilate(other))) > 1e-3 * abs(amp)


@pytest.mark.parametrize(
    "kwargs,match",
    [
        (dict(frequency=0.0, dt=0.01), r"frequency must be finite and > 0"),
        (dict(frequency=-1.0, dt=0.01), r"frequency must be finite and > 0"),
        (dict(frequency=float("nan"), dt=0.01), r"frequency must be finite"),
        (dict(frequency=50.0, dt=0.01), r"below the Nyquist frequency 1/\(2 dt\) = 50 Hz"),
        (dict(frequency=80.0, dt=0.01), r"Nyquist.*found 80 Hz"),
        (dict(omega=math.pi / 0.01, dt=0.01), r"Nyquist"),
        (dict(frequency=1.0, dt=0.0), r"dt must be finite and > 0"),
        (dict(frequency=1.0, dt=-0.1), r"dt must be finite and > 0"),
        (dict(frequency=1.0, dt=float("inf")), r"dt must be finite"),
        (dict(frequency=1.0), r"needs the sampling period dt"),
        (dict(frequency=1.0, dt=0.01, omega=6.0), r"exactly one of frequency \(Hz\) and omega"),
        (dict(dt=0.01), r"exactly one of frequency"),
        (dict(frequency="fast", dt=0.01), r"frequency must be a real number"),
    ],
)
def test_sinusoid_validation(kwargs, match):
    with pytest.raises(ValidationError, match=match):
        Sinusoid(**kwargs)


# ------------------------------------------------------------------------ polynomial
def test_polynomial_is_made_monic_and_reads_q_or_q_inverse_alike():
    p = Polynomial([2.0, -4.0, 2.0])  # 2 (q - 1)^2: a ramp
    np.testing.assert_array_equal(p.coefficients, [1.0, -2.0, 1.0])
    assert p.order == 2
    np.testing.assert_allclose(p.modes, [1.0, 1.0], atol=1e-7)
    ramp = 0.5 + 0.25 * np.arange(30)
    assert np.max(np.abs(p.annihilate(ramp))) < 1e-13
    np.testing.assert_allclose(p.N, [[0, 1], [-1, 2]])


@pytest.mark.parametrize("m", [2, 3, 4, 5])
def test_polynomial_repeated_roots_are_accepted(m):
    step_m = np.poly(np.ones(m))
    assert Polynomial(step_m).order == m
    pair = np.poly([np.exp(0.3j), np.exp(-0.3j)] * min(m, 3)).real
    assert Polynomial(pair).order == 2 * min(m, 3)
    # two genuine modes 5e-4 rad apart are both accepted
    close = np.poly(np.exp(1j * np.array([0.3, -0.3, 0.3005, -0.3005]))).real
    assert Polynomial(close).order == 4
    # a repeated root just inside the circle is still rejected
    with pytest.raises(ValidationError, match="off the unit circle"):
        Polynomial(np.poly(np.full(m, 0.999)))


def test_polynomial_triple_root_on_the_circle_is_accepted():
    # (q - 1)^3: roots computed only to ~1e-5, the cluster mean is exact
    p = Polynomial([1, -3, 3, -1])
    assert p.order == 3
    quad = (np.arange(40.0) - 3) ** 2
    assert np.max(np.abs(p.annihilate(quad))) < 1e-10


@pytest.mark.parametrize(
    "coeffs,exc,match",
    [
        ([0.0, 1.0, -1.0], ValidationError, r"non-zero leading coefficient"),
        ([1.0], ValidationError, r"degree >= 1"),
        ([], ValidationError, r"degree >= 1"),
        ([1.0, float("nan")], NotFiniteError, r"coefficients must be finite; found nan at index 1"),
        ([1.0, float("inf")], NotFiniteError, r"must be finite"),
        ([[1.0, -1.0]], DimensionError, r"must be 1-D"),
        ([1.0, 1j], ValidationError, r"must be real"),
        (["a", "b"], ValidationError, r"sequence of real numbers"),
        ([1.0, -0.5], ValidationError, r"root\(s\) off the unit circle: 0.5 \(\|z\| = 0.5\)"),
        ([1.0, -2.0], ValidationError, r"off the unit circle: 2 \(\|z\| = 2\).*growing"),
        ([1.0, 0.0, 0.25], ValidationError, r"off the unit circle.*decays by itself"),
        # palindromic, so 1/z is a root with z, but both are real and off the circle (growing 0.3 %/sample)
        ([1.0, -2.00001, 1.0], ValidationError, r"off the unit circle: 1.00317 \(\|z\| = 1.00317\)"),
    ],
)
def test_polynomial_validation(coeffs, exc, match):
    with pytest.raises(exc, match=match):
        Polynomial(coeffs)


def test_polynomial_tolerance_and_dt():
    with pytest.raises(ValidationError, match="off the unit circle"):
        Polynomial([1.0, -1.001])
    assert Polynomial([1.0, -1.001], tol=1e-2).order == 1
    with pytest.raises(ValidationError, match="tol must be finite and > 0"):
        Polynomial([1.0, -1.0], tol=0.0)
    with pytest.raises(ValidationError, match="dt must be finite and > 0"):
        Polynomial([1.0, -1.0], dt=-1.0)
    assert Polynomial([1, 1], dt=0.1).dt == 0.1


# ---------------------------------------------------------------------- combinations
def test_step_plus_sinusoid_is_the_product_of_distinct_modes():
    s = Sinusoid(1.0, 0.01)
    c = Step() + s
    assert c.order == 3
    np.testing.assert_allclose(c.coefficients, np.polymul([1, -1], s.coefficients), atol=1e-14)
    assert c.dt == 0.01
    assert "step" in c.label and "sinusoid" in c.label
    x = 0.7 + s.signal(100, 0.2, 1.0)
    assert np.max(np.abs(c.annihilate(x))) < 1e-13
    assert np.max(np.abs(Step().annihilate(x))) > 1e-3  # neither part alone annihilates the sum
    assert np.max(np.abs(s.annihilate(x))) > 1e-3


def test_sum_is_the_lcm_not_the_product():
    assert Step() + Step() == Step()
    ramp = Polynomial([1, -2, 1])
    assert (Step() + ramp).order == 2  # (q - 1)^2 already contains the step
    assert (ramp + Step()) == ramp
    s = Sinusoid(2.0, 0.05)
    assert (s + s).order == 2


def test_sum_validation():
    with pytest.raises(ValidationError, match=r"different sampling periods.*dt=0.01.*dt=0.02"):
        Sinusoid(1.0, 0.01) + Sinusoid(1.0, 0.02)
    with pytest.raises(TypeError):
        Step() + 1.0


# ----------------------------------------------------------------------- realization
@pytest.mark.parametrize("model", [Step(), Sinusoid(1.0, 0.01), Polynomial([1, -2, 1]),
                                   Step() + Sinusoid(5.0, 0.01)])
@pytest.mark.parametrize("p", [1, 2, 3])
def test_realization_structure(model, p):
    N, M, G = model.realization(p)
    r = model.order
    assert N.shape == (r * p, r * p) and M.shape == (r * p, p) and G.shape == (p, r * p)
    # one copy of the model per channel: char poly of N is P^p
    assert pole_error(np.linalg.eigvals(N), np.tile(model.modes, p)) < 1e-4
    # (N, M) controllable and (Gamma, N) observable: what the internal-model argument needs
    assert np.linalg.matrix_rank(_ctrb(N, M)) == r * p
    assert np.linalg.matrix_rank(_ctrb(N.T, G.T)) == r * p
    # Gamma N^k d0 is a signal of the class, channel by channel
    d0 = np.random.default_rng(1).standard_normal(r * p)
    sig = np.array([G @ np.linalg.matrix_power(N, k) @ d0 for k in range(r + 6)])
    assert np.max(np.abs(model.annihilate(sig))) < 1e-9


@pytest.mark.parametrize("p", [0, -1, 1.5, True, "2"])
def test_realization_rejects_bad_p(p):
    with pytest.raises(ValidationError, match="p must be a positive integer"):
        Step().realization(p)


# --------------------------------------------------------------------------- signals
@settings(max_examples=30, deadline=None)
@given(angles=st.lists(st.floats(0.05, 3.0), min_size=1, max_size=3),
       step=st.booleans(), seed=st.integers(0, 2**31 - 1))
def test_simulate_generates_signals_of_the_class(angles, step, seed):
    # angles may repeat (hypothesis found a triple pair 0.0625: roots computed only to ~1e-4, accepted by the
    # cluster-centroid test)
    roots = [1.0] if step else []
    for a in angles:
        roots += [complex(math.cos(a), math.sin(a)), complex(math.cos(a), -math.sin(a))]
    model = Polynomial(np.real(np.poly(roots)), tol=1e-5)
    rng = np.random.default_rng(seed)
    d0 = rng.standard_normal((model.order, 2))
    x = model.simulate(40, d0)
    np.testing.assert_array_equal(x[: model.order], d0)
    assert np.max(np.abs(model.annihilate(x))) < 1e-9 * max(1.0, np.max(np.abs(x)))


def test_signal_and_simulate_validation():
    with pytest.raises(ValidationError, match=r"steps must be an integer >= 2; found 1"):
        Sinusoid(1, 0.01).simulate(1, [0, 1])
    with pytest.raises(ValidationError, match=r"steps must be an integer >= 2; found 10.0"):
        Sinusoid(1, 0.01).simulate(10.0, [0, 1])
    # issue 11, item 5: numbers written as strings were converted silently (or raised a bare ValueError)
    with pytest.raises(ValidationError, match="initial must be numeric"):
        Step().simulate(10, ["1"])
    with pytest.raises(ValidationError, match="signal must be numeric"):
        Step().annihilate(["1", "1", "1"])
    with pytest.raises(ValidationError, match="signal must be numeric"):
        Step().annihilate(["a", "b", "c"])
    with pytest.raises(ValidationError, match=r"level must be a real number; found '2' \(a string\)"):
        Step().signal(5, "2")
    with pytest.raises(ValidationError, match=r"amplitude must be a real number; found '1' \(a string\)"):
        Sinusoid(1, 0.01).signal(5, amplitude="1")
    with pytest.raises(ValidationError, match=r"phase must be a real number; found None"):
        Sinusoid(1, 0.01).signal(5, phase=None)
    with pytest.raises(ValidationError, match=r"dt must be a real number; found '0.01' \(a string\)"):
        Sinusoid(1, "0.01")
    with pytest.raises(NotFiniteError, match=r"signal must be finite; found nan at index 1"):
        Step().annihilate([1.0, np.nan, 1.0])
    with pytest.raises(DimensionError, match=r"initial must have shape \(2,\) or \(2, p\); found \(3,\)"):
        Sinusoid(1, 0.01).simulate(10, [0, 1, 2])
    with pytest.raises(NotFiniteError, match="initial must be finite"):
        Step().simulate(10, [np.nan])
    with pytest.raises(DimensionError, match=r"signal must be \(T,\) or \(T, p\) with T > 2"):
        Sinusoid(1, 0.01).annihilate([1.0, 2.0])
    with pytest.raises(ValidationError, match="steps must be an integer >= 0; found -3"):
        Sinusoid(1, 0.01).signal(-3)


@pytest.mark.parametrize("model", [Step(), Sinusoid(1.0, 0.01), Polynomial([1, -2, 1], dt=0.1),
                                   Step() + Sinusoid(2.0, 0.01)])
def test_models_pickle(model):
    import pickle

    back = pickle.loads(pickle.dumps(model))
    assert type(back) is type(model) and back == model and back.label == model.label
    np.testing.assert_array_equal(back.N, model.N)
    assert not back.coefficients.flags.writeable
    if isinstance(model, Sinusoid):
        assert back.frequency == model.frequency


def test_models_are_immutable():
    s = Sinusoid(1.0, 0.01)
    with pytest.raises(AttributeError, match="immutable"):
        s.dt = 0.02
    with pytest.raises(ValueError):
        s.coefficients[0] = 2.0
    assert isinstance(s, NoiseModel)
    assert hash(s) == hash(Sinusoid(1.0, 0.01))
    assert "Sinusoid(1, dt=0.01)" == repr(s)
