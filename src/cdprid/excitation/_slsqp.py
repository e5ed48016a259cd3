"""SLSQP baseline of the excitation optimiser (SciPy), for comparison."""

from __future__ import annotations

import time

import jax
import jax.numpy as jnp
import numpy as np

from cdprid.excitation._constraints import _constraint_margins, _softmin
from cdprid.excitation._optimise import _as_module, initial_design
from cdprid.excitation._problem import ExcitationProblem, _objective_value, design_matrix


def slsqp_baseline(prob: ExcitationProblem, z0=None, maxiter: int = 200,
                   softness: float = 0.02) -> dict:
    """scipy SLSQP with finite-difference gradients on the same objective and constraints.

    The objective is the same jit-compiled smooth objective (no penalty); the constraints are
    soft minima (temperature ``softness``, normalised units) of the same per-sample margins:
    workspace, cable speed, tension, kinematics and clearance.

    Parameters
    ----------
    prob : ExcitationProblem
    z0 : array, optional
        Start coordinates (default: the initial design's).
    maxiter : int
        SLSQP iterations.
    softness : float
        Soft-minimum temperature of the constraints.

    Returns
    -------
    dict
        ``{"z", "objective", "time_s", "nfev", "success", "message"}`` (time in s, compilation
        excluded).
    """
    from scipy.optimize import minimize

    fam = prob.family
    if z0 is None:
        z0 = fam.from_params(initial_design(prob)[0])
    t = jnp.asarray(prob.grid(prob.rate_opt_hz))
    probm = _as_module(prob)

    @jax.jit
    def both(z):
        states = probm.family.states(z, t)
        W_ID = design_matrix(probm, states)
        cons = jnp.array([_softmin(c.ravel(), softness)
                          for c in _constraint_margins(probm, states)])
        return _objective_value(probm, W_ID), cons

    both(jnp.asarray(z0))  # compile outside the timing, to time the optimiser only
    last = {}

    def at(z):
        # SLSQP asks for the objective and the constraints at the same points: one compiled
        # evaluation serves both (memoised on the last point)
        key = np.asarray(z, float).tobytes()
        if last.get("key") != key:
            f, c = both(jnp.asarray(z))
            last.update(key=key, f=float(f), c=np.asarray(c))
        return last

    t0 = time.perf_counter()
    res = minimize(lambda z: at(z)["f"], np.asarray(z0, float), method="SLSQP", jac=None,
                   constraints=[{"type": "ineq", "fun": lambda z: at(z)["c"]}],
                   options={"maxiter": maxiter, "ftol": 1e-9})
    dt = time.perf_counter() - t0
    return {"z": res.x, "objective": float(res.fun), "time_s": dt, "nfev": int(res.nfev),
            "success": bool(res.success), "message": str(res.message)}
