"""Searches of the tuning: the starting points and the BFGS with continuation of the SIHD
family, the golden section and the simulated response penalty of the baselines' grid search.

Split from :mod:`cdprid.tuning._tuning` (which re-exports these names).
"""

from __future__ import annotations

import math

import jax.numpy as jnp
import numpy as np

from cdprid.base import Status
from cdprid.tuning._response import ResponseBounds, acceleration_response, response_penalty
from cdprid.tuning._sihd_params import PAPER_PARAMS, _order, default_params, theta_from_params


def _init_candidates(method, noise_std):
    """A few starting points: the method's defaults and pole-placement patterns."""
    cands = [default_params(method)]
    if method == "sihd2-cascade":
        for l2, l4 in ((500.0, 800.0), (2000.0, 2000.0)):
            cands.append({**PAPER_PARAMS, "lambda2": l2, "lambda4": l4, "alpha": 0.99})
        return cands
    n = _order(method)
    # Butterworth patterns of a few bandwidths (Kalman-like pole sets), alpha near 1
    for om in (5.0, 8.0, 12.0, 18.0, 30.0):
        roots = [om * complex(math.cos(math.pi * (2 * k + n + 1) / (2 * n)),
                              math.sin(math.pi * (2 * k + n + 1) / (2 * n))) for k in range(n)]
        lam = np.real(np.poly(roots))[1:]
        p = {f"lambda{q + 1}": float(lam[q]) for q in range(n)}
        p.update(alpha=0.995, mu=1.0)
        cands.append(p)
    return cands


#: Penalty-weight multipliers of the continuation stages of the constrained BFGS: the gains
#: move from the unconstrained optimum into the bounds instead of starting far outside them.
CONTINUATION = (1e-3, 1e-2, 1e-1, 1.0)


def _minimise(loss_j, method, init, noise_std, zeta_min, fa, max_steps, constrain, say):
    """Best start (unpenalised loss), then BFGS.

    Unconstrained: one solve of ``max_steps``.  Constrained: two paths of solves of
    ``max(1, max_steps // 2)`` steps each (one compilation), (a) the full penalty weight twice
    from the start, (b) the stages of :data:`CONTINUATION`; the lower full-weight loss of
    start, (a) and (b) is kept.
    """
    import optimistix as optx

    cands = [init] if init is not None else _init_candidates(method, noise_std)
    best = None
    for c in cands:
        th0 = jnp.asarray(theta_from_params(method, c, zeta_min, fa))
        v = float(loss_j(th0, 0.0))
        if best is None or (math.isfinite(v) and v < best[0]):
            best = (v, th0)
    one = jnp.asarray(1.0, jnp.float64)
    v_start = float(loss_j(best[1], one))
    say(f"tune {method}: start loss {v_start:.4f} (best of {len(cands)} starts)")
    solver = optx.BFGS(rtol=1e-5, atol=1e-6)
    per = max(1, max_steps // 2) if constrain else max_steps
    paths = [(1.0, 1.0), CONTINUATION] if constrain else [(1.0,)]
    out, steps, status, code = (v_start, best[1]), 0, "", Status.CONVERGED
    for path in paths:
        th = best[1]
        for w in path:
            wj = jnp.asarray(w, jnp.float64)  # an array: one compilation for every stage
            sol = optx.minimise(loss_j, solver, th, args=wj, max_steps=per, throw=False)
            if math.isfinite(float(loss_j(sol.value, wj))):
                th = sol.value
            steps += int(sol.stats.get("num_steps", 0))
            code = Status.of_optimistix(sol.result)
            status = ("converged" if code.ok
                      else "not converged: " + optx.RESULTS[sol.result].split(".")[0])
        v = float(loss_j(th, one))
        if math.isfinite(v) and v < out[0]:
            out = (v, th)
    say(f"tune {method}: end loss {out[0]:.4f} after {steps} BFGS steps ({len(paths)} path(s); "
        f"last solve {status}; the lowest of start and ends is kept)")
    return out[1], steps, status, code


def _golden(f, lo, hi, iters):
    """Golden-section minimisation of ``f`` on ``[lo, hi]`` in ``iters`` steps: (x, f(x))."""
    g = (math.sqrt(5) - 1) / 2
    a, b = lo, hi
    c, d = b - g * (b - a), a + g * (b - a)
    fc, fd = f(c), f(d)
    for _ in range(iters):
        if fc < fd:
            b, d, fd = d, c, fc
            c = b - g * (b - a)
            fc = f(c)
        else:
            a, c, fc = c, d, fd
            d = a + g * (b - a)
            fd = f(d)
    return (c, fc) if fc < fd else (d, fd)


def simulated_penalty(method: str, params: dict, dt: float, bounds: ResponseBounds,
                      amplitude_m: float = 0.3) -> float:
    """:func:`response_penalty` of the simulated (describing) response on a 40-point grid.

    Parameters
    ----------
    method : str
    params : dict
    dt : float
        Sampling period, s.
    bounds : ResponseBounds
    amplitude_m : float
        Position amplitude of the test sinusoids, m.

    Returns
    -------
    float
    """
    f = np.union1d(np.geomspace(0.05, 0.45 / dt, 30), np.linspace(0.05, bounds.bandwidth_hz, 10))
    r = acceleration_response(method, params, dt, freqs_hz=f, amplitude_m=amplitude_m)
    H = r.gain * np.exp(1j * np.radians(r.phase_deg))
    return float(response_penalty(jnp.asarray(H), f, bounds))
