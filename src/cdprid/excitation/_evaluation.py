"""Evaluation of an excitation design: the design report and the optimiser's result."""

from __future__ import annotations

import dataclasses

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from cdprid.excitation._check import SafetyCertificate, certify_trajectory
from cdprid.excitation._currents import currents_regressor
from cdprid.excitation._objective import d_optimality, predicted_sigma, stacked_regressor
from cdprid.excitation._problem import CERTIFICATE_SCOPE, ExcitationProblem, _objective_value
from cdprid.model import PARAMETER_NAMES


@dataclasses.dataclass(frozen=True)
class DesignReport:
    """Metrics of one design (with its moves from and back to home) on the 100 Hz grid.

    ``cond``/``cond_scaled`` by numpy SVD of W_ID (:func:`cdprid.core.condition_number`; with
    ``--source currents`` of the joint platform and drive regressor,
    :func:`cdprid.excitation._problem.design_matrix`), ``sigma`` the predicted standard
    deviations (of the platform's parameters) at ``sigma_rho`` (N per row) and ``rel_sigma``
    relative to the nominal parameters (None where the nominal value is 0: not meaningful);
    ``certificate`` the exact check of every limit (:mod:`cdprid.excitation._check`).
    """

    params: dict
    z: np.ndarray
    cond: float
    cond_scaled: float
    dopt: float
    objective: float
    sigma: dict
    rel_sigma: dict
    certificate: SafetyCertificate
    t_move: float
    duration: float

    @property
    def certified(self) -> bool:
        """True when the design passes every safety check."""
        return self.certificate.certified

    @property
    def min_tension_margin_N(self) -> float:
        """Worst tension margin over the samples and the uncertainty box (N)."""
        return self.certificate.robust_margin_N

    def as_json(self) -> dict:
        """JSON of the design (``initial`` / ``optimised`` of ``cdprid excite --json``).

        Returns
        -------
        dict
            Conditioning, objective, parameters, predicted sigmas, tension margins (N), peaks,
            failed checks, move and total durations (s), ``certified``.
        """
        c = self.certificate
        return {
            "cond": self.cond, "cond_scaled": self.cond_scaled, "dopt": self.dopt,
            "objective": self.objective,
            "params": {k: np.asarray(v).tolist() for k, v in self.params.items()},
            "sigma": self.sigma, "rel_sigma": self.rel_sigma,
            "min_tension_margin_N": c.robust_margin_N,
            "robust_tension_margin_N": c.robust_margin_N,
            "nominal_tension_margin_N": c.nominal_margin_N,
            "max_cable_speed_m_s": c.peaks["cable_speed_m_s"],
            "workspace_ok": c.peaks["workspace_distance_m"] >= 0.0,
            "cable_speed_ok": not any(f.startswith("cable_speed") for f in c.failed),
            "peaks": c.peaks, "failed_checks": list(c.failed),
            "worst_corner_parameters": dict(zip(PARAMETER_NAMES["full"], c.worst_corner,
                                                strict=True)),
            "n_lp_solved": c.n_lp,
            "move_duration_s": self.t_move, "duration_s": self.duration,
            "certified": self.certified,
        }


@eqx.filter_jit
def _homed_W_ID(traj, t, gravity, model: str):
    states = traj.states(t)
    return states, stacked_regressor(states, gravity, model)


@eqx.filter_jit
def _homed_joint(traj, t, robot, model: str, theta, k, reference: int, tmin: float,
                 tmax: float):
    states = traj.states(t)
    return states, currents_regressor(robot, states, model, theta, k, reference, tmin, tmax)


def _homed_design(prob, traj, t):
    """The states and the design matrix (:func:`design_matrix`) on the homed trajectory."""
    if prob.source == "currents":
        return _homed_joint(traj, t, prob.robot, prob.model, prob.nominal.vector(prob.model),
                            jnp.asarray(prob.drive_k), prob.reference, prob.limits.tension_min,
                            prob.limits.tension_max)
    return _homed_W_ID(traj, t, prob.robot.gravity, prob.model)


def _meaningful_rel(sig, x):
    """Relative sigmas, None where the nominal value is 0 (a percentage of 0 means nothing)."""
    scale = max(abs(float(x[0])), 1e-12)
    return [float(s / abs(v)) if abs(v) > 1e-9 * scale else None
            for s, v in zip(sig, x, strict=True)]


def evaluate_design(prob: ExcitationProblem, z, rate_hz: float = 100.0,
                    certify: bool = True, dense_hz: float = 500.0) -> DesignReport:
    """Metrics of coordinates z (with the home moves) and the exact certificate.

    Parameters
    ----------
    prob : ExcitationProblem
    z : array (n_params,)
        The family's coordinates.
    rate_hz : float
        Grid of the metrics, tensions and clearances, Hz.
    certify : bool
        Unused: the certificate is always computed.
    dense_hz : float
        Grid of the kinematic checks, Hz.

    Returns
    -------
    DesignReport
    """
    from cdprid.core import condition_number

    z = jnp.asarray(z, float)
    traj = prob.homed(z)
    t = np.arange(int(np.floor(traj.t_end * rate_hz + 1e-9)) + 1) / rate_hz
    states, W_ID = _homed_design(prob, traj, jnp.asarray(t))
    W_ID = np.asarray(W_ID)
    obj = float(_objective_value(prob, jnp.asarray(W_ID)))
    td = np.arange(int(np.floor(traj.t_end * dense_hz + 1e-9)) + 1) / dense_hz
    dense = traj.evaluate(td)
    cert = certify_trajectory(prob.robot, states, dense, prob.limits, prob.box)
    sig = np.asarray(predicted_sigma(jnp.asarray(W_ID), prob.sigma_rho))[:len(prob.names)]
    x = np.asarray(prob.nominal.vector(prob.model))
    params = {k: np.asarray(v) for k, v in prob.family.to_params(z).items()}
    return DesignReport(
        params=params, z=np.asarray(z),
        cond=condition_number(W_ID), cond_scaled=condition_number(W_ID, scaled=True),
        dopt=float(d_optimality(jnp.asarray(W_ID))), objective=obj,
        sigma={n: float(s) for n, s in zip(prob.names, sig, strict=True)},
        rel_sigma=dict(zip(prob.names, _meaningful_rel(sig, x), strict=True)),
        certificate=cert, t_move=traj.t_move, duration=traj.t_end,
    )


@dataclasses.dataclass(frozen=True)
class ExcitationResult:
    """Outcome of :func:`optimise_excitation`.

    ``optimised`` is always certified (or equal to ``initial`` with ``note`` saying why);
    ``starts`` lists each start's penalised objective, steps and certification.
    """

    problem: ExcitationProblem
    initial: DesignReport
    optimised: DesignReport
    trajectory: object
    starts: list
    wall_time_s: float
    optimiser_time_s: float
    note: str
    initial_rule: str = ""

    def as_json(self) -> dict:
        """JSON of ``cdprid excite``.

        Returns
        -------
        dict
            Both designs, timings (s), family, model, objective, limits, uncertainty box, home (m),
            safety fractions, starts, note and the certificate's scope.
        """
        prob = self.problem
        return {
            "initial": self.initial.as_json(),
            "optimised": self.optimised.as_json(),
            "wall_time_s": self.wall_time_s,
            "optimiser_time_s": self.optimiser_time_s,
            "family": prob.family.name,
            "model": prob.model,
            "objective": prob.objective,
            "source": prob.source,
            **({"regressor": "joint: platform and every drive (k without the reference's, J, "
                             "fv, fc, c), column-scaled",
                "reference_drive": prob.reference + 1,
                "drive_k_nominal": list(prob.drive_k)} if prob.source == "currents" else {}),
            "limits": prob.limits.as_json(),
            "defaults_used": list(prob.limits.defaults_used) + list(
                prob.box.description.get("defaults_used", [])),
            "uncertainty": {"source": prob.box.source, **prob.box.description,
                            "corners": prob.box.corners.tolist(),
                            "parameter_order": list(PARAMETER_NAMES["full"])},
            "home": [float(v) for v in prob.home],
            "safety_fractions": dataclasses.asdict(prob.fractions),
            "tension_margin_target_N": prob.tension_target,
            "starts": self.starts,
            "note": self.note,
            "initial_design": self.initial_rule,
            "certificate_scope": CERTIFICATE_SCOPE,
        }
