"""Losses of the gradient tuning: the stacked training arrays, the acceleration and
parameter objectives (:class:`ParamProblem`) and the response penalty's frequency grid.

Split from :mod:`cdprid.tuning._tuning` (which re-exports these names).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from cdprid.tuning._response import (
    PENALTY_WEIGHT,
    _noise_gain,
    response_penalty,
    sihd_linear_response,
)
from cdprid.tuning._sihd_params import _acc_channel, _theta_to_gains
from cdprid.tuning._training import TrainingSignal, noise_realisations


class ParamProblem:
    """4-parameter least squares (m, m s_G) on simulated tensions, differentiable in the
    estimated accelerations.

    The CRAFT-like robot follows the training signal (rotation-free); the cable
    wrench ``W(p) tau`` is computed at the true poses from the simulated
    tensions plus tension noise ``tension_std`` (one draw per seed).
    """

    def __init__(self, signal: TrainingSignal, seeds, tension_std: float = 0.5):
        from cdprid.model import (
            SampledTrajectory,
            craft_like_robot,
            craft_like_truth,
            regressor_translation,
            wrench_matrix,
        )
        from cdprid.simulation import SensorNoise, simulate

        robot = craft_like_robot()
        truth = craft_like_truth()
        vel = np.gradient(signal.position, signal.dt, axis=0)
        traj = SampledTrajectory(jnp.asarray(signal.t), jnp.asarray(signal.position),
                                 jnp.asarray(vel), jnp.asarray(signal.acceleration))
        sim = simulate(robot, traj, params=truth, noise=SensorNoise.off(),
                       rate_pose=1.0 / signal.dt, rate_tension=1.0 / signal.dt,
                       check_workspace_box=False)
        tau = np.asarray(sim.tension_true)
        n = min(tau.shape[0], signal.t.size)
        I3 = jnp.eye(3)
        W = np.asarray(jax.vmap(lambda p: wrench_matrix(robot, p, I3))(
            jnp.asarray(signal.position[:n])))
        rng_y = []
        for s in seeds:
            noise = np.random.default_rng(10_000 + int(s)).standard_normal(tau[:n].shape)
            rng_y.append(np.einsum("nij,nj->ni", W, tau[:n] + tension_std * noise))
        self.Y = np.stack(rng_y)  # (S, n, 6)
        self.n = n
        self.g = np.asarray(robot.gravity, float)
        self.theta_true = np.r_[truth.mass, truth.mass * np.asarray(truth.com, float)]
        self.scale = np.r_[truth.mass, np.full(3, np.linalg.norm(self.theta_true[1:]))]
        self._reg = jax.vmap(lambda a: regressor_translation(I3, a, jnp.asarray(self.g)))

    def rel_error(self, A_hat, mask):
        """Scaled parameter error per seed.

        Parameters
        ----------
        A_hat : array (n, S, 3)
            Estimated accelerations per seed, m/s^2.
        mask : array (n,)
            0/1 weights of the samples.

        Returns
        -------
        array (S,)
            Mean over the 4 parameters of the squared error, each scaled by the true mass or the
            norm of the true first moment (dimensionless).
        """
        A_hat = A_hat[: self.n]
        m = jnp.asarray(mask[: self.n], A_hat.dtype)

        def one(a, y):
            R = self._reg(a) * m[:, None, None]
            R = R.reshape(-1, 4)
            th = jnp.linalg.lstsq(R, (y * m[:, None]).reshape(-1))[0]
            return jnp.sum(((th - self.theta_true) / self.scale) ** 2) / 4

        errs = jax.vmap(one, in_axes=(1, 0))(A_hat, jnp.asarray(self.Y))
        return errs


def _stack_train(signal, noise_std, seeds):
    """Noisy positions and true accelerations of ``signal`` for the noise ``seeds``, stacked
    along the columns: (Y (n, 3 S), acc (n, 3 S))."""
    S = len(seeds)
    nz = noise_realisations(signal.t.size, seeds)
    y = signal.position[None] + noise_std * nz
    Y = np.transpose(y, (1, 0, 2)).reshape(signal.t.size, 3 * S)
    acc = np.tile(signal.acceleration, (1, S))
    return Y, acc


def penalty_freqs(dt: float, bandwidth_hz: float) -> np.ndarray:
    """Frequency grid of the response penalty (coarser than :func:`dense_freqs`).

    Parameters
    ----------
    dt : float
        Sampling period, s.
    bandwidth_hz : float

    Returns
    -------
    ndarray
        Frequencies, Hz: 120 log-spaced up to ``0.49 / dt`` and 25 linear up to the bandwidth.
    """
    return np.union1d(np.geomspace(0.02, 0.49 / dt, 120), np.linspace(0.02, bandwidth_hz, 25))


def _groups(sigs, noise_std, seeds, noisy: bool):
    """Training arrays grouped by length: (Y (n, 3 k S), acc (n, 3 k S), mask (n,), k)."""
    by_len: dict = {}
    for s in sigs:
        by_len.setdefault((s.t.size, float(s.t0)), []).append(s)
    out = []
    for group in by_len.values():
        Ys, As = [], []
        for s in group:
            if noisy:
                Y, A = _stack_train(s, noise_std, seeds)
            else:
                Y, A = s.position, s.acceleration
            Ys.append(Y)
            As.append(A)
        out.append((jnp.asarray(np.concatenate(Ys, 1)), jnp.asarray(np.concatenate(As, 1)),
                    jnp.asarray(group[0].mask.astype(float)), len(group)))
    return out


def _accel_loss(method, sigs, noise_std, seeds, zeta_min, bounds, constrain, dt):
    """``f(theta, None)``: mean over members of the log mean-square 3-D acceleration error,
    plus :data:`PENALTY_WEIGHT` x :func:`response_penalty` when ``constrain``.

    Constrained (alpha = 1, a linear observer), the noise term is exact: ``3 sigma^2`` times
    :func:`_noise_gain`, added to the noise-free tracking error of each member; otherwise the
    noise is simulated with ``seeds``.
    """
    groups = _groups(sigs, noise_std, seeds, noisy=not constrain)
    S = 1 if constrain else len(seeds)
    fa = 1.0 if constrain else None
    pf = penalty_freqs(dt, bounds.bandwidth_hz)

    def f(th, args):
        """``args``: multiplier of :data:`PENALTY_WEIGHT` (continuation stages)."""
        lams, alpha = _theta_to_gains(method, th, zeta_min, fa)
        nv = 3 * noise_std**2 * _noise_gain(method, lams, dt) if constrain else 0.0
        logs = []
        for Y, acc, mask, k in groups:
            A = jax.vmap(lambda c: _acc_channel(method, c, dt, lams, alpha), 1, 1)(Y)
            se = jnp.sum(((A - acc) ** 2) * mask[:, None], axis=0).reshape(k, S, 3)
            logs.append(jnp.log(jnp.sum(se, axis=(1, 2)) / (S * jnp.sum(mask)) + nv))
        L = jnp.mean(jnp.concatenate(logs))
        if constrain:
            H = sihd_linear_response(method, lams, dt, pf)
            L = L + args * PENALTY_WEIGHT * response_penalty(H, pf, bounds)
        return L

    return f


def _param_loss(method, signal, noise_std, seeds, objective, weight, zeta_min, bounds,
                constrain):
    """``f(theta, None)`` for the ``params``/``mix`` objectives (first training signal)."""
    pp = ParamProblem(signal, seeds)
    Y, acc = _stack_train(signal, noise_std, seeds)
    Y, acc = jnp.asarray(Y), jnp.asarray(acc)
    mask = signal.mask.astype(float)
    maskj = jnp.asarray(mask)
    h = float(signal.dt)
    a_ms = float(np.mean(np.sum(signal.acceleration[signal.mask] ** 2, axis=1)))
    fa = 1.0 if constrain else None
    pf = penalty_freqs(h, bounds.bandwidth_hz)

    def f(th, args):
        lams, alpha = _theta_to_gains(method, th, zeta_min, fa)
        A = jax.vmap(lambda c: _acc_channel(method, c, h, lams, alpha), 1, 1)(Y)
        pe = jnp.mean(pp.rel_error(A.reshape(A.shape[0], -1, 3), mask))
        if objective == "params":
            L = jnp.log(pe)
        else:
            se = jnp.sum(((A - acc) ** 2) * maskj[:, None]) / (jnp.sum(maskj) * len(seeds))
            L = jnp.log((1 - weight) * se / a_ms + weight * pe)
        if constrain:
            L = L + args * PENALTY_WEIGHT * response_penalty(
                sihd_linear_response(method, lams, h, pf), pf, bounds)
        return L

    return f
