"""Tests of cdprid.signal._differentiators (SIHD, filters, Kalman/RTS, public interface)."""

import jax

jax.config.update("jax_enable_x64", True)

import math  # noqa: E402

import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402

import cdprid.signal as D  # noqa: E402
from cdprid.signal import METHODS, differentiate, zero_phase_filter  # noqa: E402
from cdprid.signal import _scan as D_scan  # noqa: E402

H = 0.01


def _t(T, h=H):
    return np.arange(int(round(T / h))) * h


# ---------------------------------------------------------------------------
# plain-Python reference of the SIHD equations (docs/sihd.md, D2 and D3)
# ---------------------------------------------------------------------------


def _py_proj(e, q, lam, alpha, mu, h):
    p = q * (1.0 - alpha)
    lq = lam * (mu * h) ** q
    s = (e > 0) - (e < 0)
    if abs(e) ** p < lq:
        return s * abs(e) ** p / lq
    return float(s)


def _py_corr(e, q, lam, alpha, mu, h):
    return lam * mu**q * abs(e) ** (q * alpha - (q - 1)) * _py_proj(e, q, lam, alpha, mu, h)


def _py_cascade(y, h, l1, l2, l3, l4, alpha, mu):
    z1, z2 = float(y[0]), 0.0
    w1, w2 = 0.0, 0.0
    d1, d2 = [], []
    for yk in y:
        e = float(yk) - z1
        z2 = z2 + h * _py_corr(e, 2, l2, alpha, mu, h)
        z1 = z1 + h * (z2 + _py_corr(e, 1, l1, alpha, mu, h))
        e2 = z2 - w1
        w2 = w2 + h * _py_corr(e2, 2, l4, alpha, mu, h)
        w1 = w1 + h * (w2 + _py_corr(e2, 1, l3, alpha, mu, h))
        d1.append(z2)
        d2.append(w2)
    return np.array(d1), np.array(d2)


def _py_sihd3(y, h, l1, l2, l3, alpha, mu):
    z1, z2, z3 = float(y[0]), 0.0, 0.0
    d1, d2 = [], []
    for yk in y:
        e = float(yk) - z1
        z3 = z3 + h * _py_corr(e, 3, l3, alpha, mu, h)
        z2 = z2 + h * (z3 + _py_corr(e, 2, l2, alpha, mu, h))
        z1 = z1 + h * (z2 - 0.5 * h * z3 + _py_corr(e, 1, l1, alpha, mu, h))
        d1.append(z2 - h * z3)
        d2.append(z3)
    return np.array(d1), np.array(d2)


def test_scan_equals_python_loop():
    rng = np.random.default_rng(3)
    t = _t(6.0)
    y = 0.3 * np.cos(1.57 * t) + 5e-4 * rng.standard_normal(t.size)
    p = METHODS["sihd2-cascade"].params
    ref = _py_cascade(y, H, *p.values())
    got = differentiate(y, H, "sihd2-cascade")
    for r, g in zip(ref, got, strict=True):
        np.testing.assert_allclose(g, r, rtol=0, atol=1e-12)
    p3 = METHODS["sihd3"].params
    ref = _py_sihd3(y, H, *p3.values())
    got = differentiate(y, H, "sihd3")
    for r, g in zip(ref, got, strict=True):
        np.testing.assert_allclose(g, r, rtol=0, atol=1e-12 * max(1.0, np.abs(r).max()))


def test_projector_is_implicit_sign_solution():
    # N_q solves e+ = e - lam (mu h)^q |e|^(q alpha - q + 1) N, N in Sign(e+)
    lam, alpha, mu, h = 50.0, 0.9, 1.3, 0.02
    for q in (1, 2, 3):
        for e in np.concatenate([-np.logspace(-12, 2, 40), [0.0], np.logspace(-12, 2, 40)]):
            n = float(D.projector(jnp.asarray(e), q, lam, alpha, mu, h))
            assert -1.0 <= n <= 1.0
            ep = e - lam * (mu * h) ** q * abs(e) ** (q * alpha - q + 1) * n
            if abs(n) < 1.0:  # interior of Sign: e+ must be exactly 0
                assert abs(ep) <= 1e-12 * max(abs(e), 1e-300)
            else:  # saturated: no overshoot, e+ keeps the sign of e
                assert ep * e >= 0.0


# ---------------------------------------------------------------------------
# exactness on polynomials (noise free)
# ---------------------------------------------------------------------------


def test_sihd2_cascade_ramp_exact():
    t = _t(10.0)
    y = np.c_[0.3 + 0.7 * t, -0.2 - 1.3 * t]
    d1, d2 = differentiate(y, H, "sihd2-cascade")
    s = t >= 5.0
    np.testing.assert_allclose(d1[s], np.broadcast_to([0.7, -1.3], d1[s].shape), atol=1e-10)
    np.testing.assert_allclose(d2[s], 0.0, atol=1e-8)


def test_sihd2_cascade_parabola_second_derivative_exact():
    t = _t(30.0)
    a = 0.74
    y = 0.1 + 0.2 * t + 0.5 * a * t**2
    d1, d2 = differentiate(y, H, "sihd2-cascade")
    s = t >= 20.0
    assert np.max(np.abs(d2[s] - a)) < 1e-6
    # first stage: a ramp in velocity with a constant lag (type-1 tracking)
    lag = (0.2 + a * t[s]) - d1[s]
    assert np.ptp(lag) < 1e-6


def test_sihd3_parabola_exact():
    t = _t(12.0)
    y = 1.0 - 0.4 * t + 0.3 * t**2
    d1, d2 = differentiate(y, H, "sihd3")
    s = t >= 6.0
    np.testing.assert_allclose(d1[s], -0.4 + 0.6 * t[s], atol=1e-8)
    np.testing.assert_allclose(d2[s], 0.6, atol=1e-8)


def test_savgol_exact_on_quintic_everywhere():
    t = _t(5.0)
    c = [0.3, -1.0, 0.5, 0.2, -0.05, 0.01]
    y = sum(ci * t**i for i, ci in enumerate(c))
    dy = sum(i * ci * t ** (i - 1) for i, ci in enumerate(c) if i >= 1)
    ddy = sum(i * (i - 1) * ci * t ** (i - 2) for i, ci in enumerate(c) if i >= 2)
    d1, d2 = differentiate(y, H, "savgol")
    np.testing.assert_allclose(d1, dy, atol=1e-8)
    np.testing.assert_allclose(d2, ddy, atol=1e-7)


@pytest.mark.parametrize("method", ["rts", "kalman"])
def test_kalman_rts_exact_on_cubic(method):
    t = _t(10.0)
    y = 0.2 + 0.5 * t - 0.3 * t**2 + 0.02 * t**3
    d1, d2 = differentiate(y, H, method)
    s = (t >= 4.0) & (t <= 9.0)
    np.testing.assert_allclose(d1[s], 0.5 - 0.6 * t[s] + 0.06 * t[s] ** 2, atol=1e-6)
    np.testing.assert_allclose(d2[s], -0.6 + 0.12 * t[s], atol=1e-5)


def test_euler_filtfilt_exact_ramp_and_interior_parabola():
    t = _t(10.0)
    d1, d2 = differentiate(0.2 + 0.9 * t, H, "euler-filtfilt")
    np.testing.assert_allclose(d1, 0.9, atol=1e-9)
    np.testing.assert_allclose(d2, 0.0, atol=1e-6)
    # zero-phase filter keeps the curvature of a parabola away from the ends
    d1, d2 = differentiate(0.4 * t**2, H, "euler-filtfilt")
    s = (t > 3.0) & (t < 7.0)
    np.testing.assert_allclose(d2[s], 0.8, atol=1e-6)


# ---------------------------------------------------------------------------
# convergence order with the sampling period (sinusoid, noise free)
# ---------------------------------------------------------------------------


def _slope(hs, errs):
    return np.polyfit(np.log(hs), np.log(errs), 1)[0]


def test_error_order_in_h():
    hs = np.array([0.01, 0.005, 0.0025, 0.00125])
    e3 = {1: [], 2: []}
    el = {1: [], 2: []}
    for h in hs:
        t = _t(16.0, h)
        y = np.sin(t)
        s = t >= 8.0
        # SIHD-3 with the linear part's pole scaled with the sampling (omega h fixed):
        # exact on parabolas, so the error is driven by y''' -> O(h^2) on d1, O(h) on d2
        w = 0.15 / h
        d1, d2 = differentiate(y, h, "sihd3", lambda1=3 * w, lambda2=3 * w**2, lambda3=w**3)
        e3[1].append(np.max(np.abs(d1 - np.cos(t))[s]))
        e3[2].append(np.max(np.abs(d2 + np.sin(t))[s]))
        # explicit Levant differentiator: discrete accuracy O(L h) on d2
        d1, d2 = differentiate(y, h, "levant", L=2.0)
        el[1].append(np.max(np.abs(d1 - np.cos(t))[s]))
        el[2].append(np.max(np.abs(d2 + np.sin(t))[s]))
    assert 1.8 < _slope(hs, e3[1]) < 3.0
    assert 0.8 < _slope(hs, e3[2]) < 1.5
    assert 0.8 < _slope(hs, el[2]) < 1.5
    assert _slope(hs, el[1]) > 0.8


# ---------------------------------------------------------------------------
# robustness
# ---------------------------------------------------------------------------


@pytest.mark.parametrize("method", ["sihd2-cascade", "sihd3"])
def test_finite_across_six_decades_of_gains_and_steps(method):
    t = _t(4.0)
    rng = np.random.default_rng(0)
    y = np.c_[
        np.where(t >= 1.0, 1.0, 0.0),  # unit step
        np.where(t >= 2.0, -5e3, 0.0),  # large step
        0.3 * np.sin(1.57 * t) + 1e-3 * rng.standard_normal(t.size),
    ]
    base = METHODS[method].params
    lams = [k for k in base if k.startswith("lambda")]
    for scale in 10.0 ** np.arange(-3, 4):
        kw = {k: base[k] * scale for k in lams}
        d1, d2 = differentiate(y, H, method, **kw)
        assert np.all(np.isfinite(d1)) and np.all(np.isfinite(d2)), (method, scale)
        # no overshoot beyond a few backward differences (projection bounds corrections)
        assert np.max(np.abs(d1)) < 10.0 * np.max(np.abs(np.diff(y, axis=0))) / H


@pytest.mark.parametrize("method", ["levant", "kalman", "rts"])
def test_other_causal_methods_finite_for_steps(method):
    t = _t(3.0)
    y = np.c_[np.where(t >= 1.0, 1.0, 0.0), np.where(t >= 2.0, -5e3, 0.0)]
    key = "L" if method == "levant" else "q"
    for scale in 10.0 ** np.arange(-3, 4):
        d1, d2 = differentiate(y, H, method, **{key: METHODS[method].params[key] * scale})
        assert np.all(np.isfinite(d1)) and np.all(np.isfinite(d2))


# ---------------------------------------------------------------------------
# interface
# ---------------------------------------------------------------------------


def test_no_recompilation_for_new_data_same_shape():
    rng = np.random.default_rng(1)
    for method in ("sihd2-cascade", "sihd3", "kalman"):
        differentiate(rng.standard_normal((300, 3)), H, method)
        n_trace = D.TRACE_COUNTS[method]
        n_cache = D_scan._jax_kernel._cache_size()
        for i in range(3):
            # new data, new gains, new dt: all traced, so no new trace/compile
            p = {
                k: v * (1.0 + 0.1 * i)
                for k, v in METHODS[method].params.items()
                if k.startswith("lambda") or k == "q"
            }
            differentiate(jnp.asarray(rng.standard_normal((300, 3))), H * (1 + i), method, **p)
        assert D.TRACE_COUNTS[method] == n_trace
        assert D_scan._jax_kernel._cache_size() == n_cache


@pytest.mark.parametrize("method", list(METHODS))
def test_shapes_and_types(method):
    t = _t(3.0)
    y1 = 0.3 * np.cos(t)
    yk = np.c_[y1, 0.3 * np.sin(t), 0.0 * t]
    for y in (y1, yk, jnp.asarray(yk)):
        d1, d2 = differentiate(y, H, method)
        assert isinstance(d1, np.ndarray) and isinstance(d2, np.ndarray)
        assert d1.shape == d2.shape == np.shape(y)
        assert d1.dtype == d2.dtype == np.float64
        assert np.all(np.isfinite(d1)) and np.all(np.isfinite(d2))
    # channels are processed independently
    d1k, d2k = differentiate(yk, H, method)
    d11, d21 = differentiate(y1, H, method)
    np.testing.assert_allclose(d1k[:, 0], d11, atol=1e-12)
    np.testing.assert_allclose(d2k[:, 0], d21, atol=1e-9)


def test_method_registry():
    assert set(METHODS) == {
        "sihd2-cascade",
        "sihd3",
        "euler-filtfilt",
        "euler-butter-causal",
        "levant",
        "savgol",
        "kalman",
        "rts",
        "sihd4",
        "sihd5",
    }
    causal = {k for k, m in METHODS.items() if m.causal}
    assert causal == {"sihd2-cascade", "sihd3", "euler-butter-causal", "levant", "kalman",
                      "sihd4", "sihd5"}
    p = METHODS["sihd2-cascade"].params
    assert (p["lambda1"], p["lambda2"], p["lambda3"], p["lambda4"]) == (210, 210, 525, 525)
    assert (p["alpha"], p["mu"]) == (0.95, 1.0)
    assert METHODS["euler-filtfilt"].params["cutoff_hz"] == 4.0
    with pytest.raises(AttributeError):
        METHODS["sihd3"].name = "x"  # frozen


@pytest.mark.parametrize("method", ["sihd2-cascade", "euler-butter-causal", "levant", "kalman"])
def test_causality(method):
    rng = np.random.default_rng(2)
    y = rng.standard_normal(400).cumsum() * 1e-3
    y2 = y.copy()
    y2[250:] += 0.5
    a1, a2 = differentiate(y, H, method)
    b1, b2 = differentiate(y2, H, method)
    np.testing.assert_array_equal(a1[:250], b1[:250])
    np.testing.assert_array_equal(a2[:250], b2[:250])


def test_zero_phase_filter_matches_euler_filtfilt():
    rng = np.random.default_rng(4)
    t = _t(5.0)
    y = np.c_[np.cos(t), np.sin(t)] + 1e-3 * rng.standard_normal((t.size, 2))
    f = zero_phase_filter(y, H)
    assert f.shape == y.shape
    d1, _ = differentiate(y, H, "euler-filtfilt")
    np.testing.assert_allclose(d1, np.gradient(f, H, axis=0, edge_order=2), atol=1e-12)
    # zero phase: a 1 Hz sine is not delayed (cross-correlation peak at lag 0)
    x = np.sin(2 * math.pi * 1.0 * t)
    fx = zero_phase_filter(x, H)
    lags = np.arange(-10, 11)
    xc = [np.dot(fx[100:-100], x[100 + k : x.size - 100 + k]) for k in lags]
    assert lags[int(np.argmax(xc))] == 0


@pytest.mark.parametrize("order,cutoff,fs", [(1, 4.0, 100.0), (2, 4.0, 100.0), (2, 4.0, 1000.0),
                                              (3, 0.5, 1000.0), (4, 30.0, 100.0),
                                              (5, 1.0, 200.0)])
def test_butterworth_and_filtering_match_scipy_signal(order, cutoff, fs):
    """The SciPy-free Butterworth design and filters (cdprid.signal._filters) against
    scipy.signal."""
    ss = pytest.importorskip("scipy.signal")
    from cdprid.signal import (
        butter_lowpass,
        butter_sos,
        lfilter,
        lfilter_zi,
        sosfilt,
        sosfilt_zi,
        sosfiltfilt,
    )

    b, a = butter_lowpass(order, cutoff, fs)
    b_ref, a_ref = ss.butter(order, cutoff, btype="low", fs=fs)
    np.testing.assert_allclose(b, b_ref, rtol=1e-12, atol=1e-300)
    np.testing.assert_allclose(a, a_ref, rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(lfilter_zi(b, a), ss.lfilter_zi(b_ref, a_ref), rtol=1e-11)
    sos, sos_ref = butter_sos(order, cutoff, fs), ss.butter(order, cutoff, fs=fs, output="sos")
    assert sos.shape == sos_ref.shape
    w = np.linspace(0.0, 0.5 * fs, 64, endpoint=False)
    np.testing.assert_allclose(ss.sosfreqz(sos, w, fs=fs)[1], ss.sosfreqz(sos_ref, w, fs=fs)[1],
                               rtol=1e-9, atol=1e-12)
    x = np.cumsum(np.random.default_rng(order).normal(size=(3000, 3)), axis=0)
    scale = np.abs(x).max()
    if order <= 2:  # the (b, a) recursion, for the orders where it is well conditioned
        zi = ss.lfilter_zi(b_ref, a_ref)[:, None] * x[0]
        np.testing.assert_allclose(lfilter(b, a, x, zi), ss.lfilter(b_ref, a_ref, x, axis=0,
                                                                    zi=zi)[0], atol=1e-12 * scale)
    y = sosfilt(sos, x, sosfilt_zi(sos)[:, :, None] * x[0])
    y_ref = ss.sosfilt(sos_ref, x, axis=0, zi=ss.sosfilt_zi(sos_ref)[:, :, None] * x[0])[0]
    np.testing.assert_allclose(y, y_ref, atol=1e-11 * scale)
    for pad in (0, 7, 125, 2999):
        y_ref = ss.sosfiltfilt(sos_ref, x, axis=0, padtype="odd", padlen=pad)
        np.testing.assert_allclose(sosfiltfilt(sos, x, pad), y_ref, atol=1e-11 * scale)
        np.testing.assert_allclose(sosfiltfilt(sos, x[:, 0], pad), y_ref[:, 0],
                                   atol=1e-11 * scale)
        if order <= 2:
            y_ba = ss.filtfilt(b_ref, a_ref, x, axis=0, padtype="odd", padlen=pad)
            np.testing.assert_allclose(sosfiltfilt(sos, x, pad), y_ba, atol=1e-12 * scale)


def test_identify_path_does_not_import_scipy_signal():
    """Cold start (issue 13): the default differentiator needs no scipy.signal."""
    import subprocess
    import sys

    code = ("import sys, numpy as np; from cdprid.signal._differentiators import differentiate;"
            "differentiate(np.ones((50, 3)), 0.01, 'euler-filtfilt');"
            "differentiate(np.ones((50, 3)), 0.01, 'euler-butter-causal');"
            "print('scipy.signal' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"


def test_value_errors():
    y = np.zeros(50)
    with pytest.raises(ValueError, match="valid names are"):
        differentiate(y, H, "nope")
    with pytest.raises(ValueError, match="valid parameters"):
        differentiate(y, H, "sihd3", lambda4=1.0)
    with pytest.raises(ValueError):
        differentiate(y, H, "sihd2-cascade", alpha=0.3)
    with pytest.raises(ValueError):
        differentiate(y, H, "kalman", q=-1.0)
    with pytest.raises(ValueError):
        differentiate(y, H, "euler-filtfilt", cutoff_hz=80.0)
    with pytest.raises(ValueError):
        differentiate(y, 0.0)
    with pytest.raises(ValueError):
        differentiate(np.zeros((5, 2, 2)), H)
    with pytest.raises(ValueError):
        differentiate(y, H, "savgol", polyorder=2.5)


@pytest.mark.parametrize("block", [0, 1, 2, 3, 7, 16, 200])
def test_scan_blocked_equals_lax_scan(block):
    # the output blocking (one block of outputs per outer step, padded input)
    # returns exactly what lax.scan returns, for lengths not multiple of block
    rng = np.random.default_rng(3)
    xs = jnp.asarray(rng.standard_normal((101, 2)))

    def step(c, x):
        c = 0.9 * c + jnp.sin(x)
        return c, (c, c * x)

    c_ref, ref = jax.lax.scan(step, jnp.zeros(2), xs)
    c_got, got = D.scan_blocked(step, jnp.zeros(2), xs, block, return_carry=True)
    np.testing.assert_array_equal(np.asarray(c_got), np.asarray(c_ref))
    for r, g in zip(ref, got, strict=True):
        assert g.shape == r.shape
        np.testing.assert_array_equal(np.asarray(g), np.asarray(r))
    # pytree inputs
    got2 = D.scan_blocked(lambda c, x: step(c, x[0] + x[1]), jnp.zeros(2), (xs, 0 * xs), block)
    np.testing.assert_array_equal(np.asarray(got2[0]), np.asarray(ref[0]))


def test_block_size_keeps_output_blocks_small():
    assert D_scan._block_size(3) > 1
    assert D_scan._block_size(3) * 3 * 8 <= D_scan._SMALL_BUFFER_BYTES
    assert D_scan._block_size(3000) == 0


def test_sharded_batch_equals_single_device(tmp_path):
    # with two host devices, wide arrays are split by channel; same numbers
    import subprocess
    import sys
    import textwrap

    code = textwrap.dedent(
        """
        import os
        os.environ["XLA_FLAGS"] = "--xla_force_host_platform_device_count=2"
        import jax
        jax.config.update("jax_enable_x64", True)
        import numpy as np
        import jax.numpy as jnp
        from cdprid.signal import _differentiators as D
        from cdprid.signal import _scan as D_scan
        assert jax.local_device_count() == 2
        rng = np.random.default_rng(0)
        y = np.cumsum(rng.standard_normal((300, 131)), axis=0) * 1e-3  # odd width: padding
        for m in ("sihd2-cascade", "kalman"):
            d1, d2 = D.differentiate(y, 0.01, m)
            p = jnp.asarray(list(D.METHODS[m].params.values()))
            r1, r2 = D_scan._jax_kernel(m, jnp.asarray(y), jnp.asarray(0.01), p)
            assert np.array_equal(d1, np.asarray(r1)) and np.array_equal(d2, np.asarray(r2)), m
        assert ("sihd2-cascade", 2) in D_scan._SHARDED
        print("ok")
        """
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stdout.strip().endswith("ok")
