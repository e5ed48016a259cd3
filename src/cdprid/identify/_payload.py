"""The payload pair as scale reference (``identify --source currents --reference
payload:DIR:KG[:STD_KG]``): two recordings of the same robot and drives, the second with a
known mass added to the platform.

Each recording is identified with the same provisional reference (drive 1's constant taken as
1 N/A): every estimate is then the truth divided by one common factor ``rho = k_1``. The masses
differ by the payload, so ``rho = dm / (m_B - m_A)``, and recording A's parameters are
``rho theta_A``. The covariance: the delta method over ``theta_A``, ``m_B`` (an independent
recording) and ``dm`` (its stated std), with ``d rho / d m_A = rho^2 / dm``, ``d rho / d m_B =
-rho^2 / dm``, ``d rho / d dm = rho / dm``. The payload may sit anywhere on the platform: only
its mass is used (the first moment and inertia of B are not).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from cdprid.base import InputError
from cdprid.identify._currents import CurrentsReport, identify_currents
from cdprid.identify._scale import ScaleReference
from cdprid.io import read_drives

__all__ = ["identify_currents_payload", "parse_payload"]

_PROVISIONAL = "drive:1"


def parse_payload(spec: str) -> tuple[str, float, float]:
    """``payload:DIR:KG[:STD_KG]`` -> ``(DIR, KG, STD_KG)``.

    Parameters
    ----------
    spec : str
        The ``--reference`` value.

    Returns
    -------
    direction : str
        The second dataset (with the payload).
    kg, std_kg : float
        The payload's mass and its standard deviation (0 when not given), kg.

    Raises
    ------
    InputError
        Malformed ``spec``, a mass not > 0 or a std < 0 (one sentence).
    """
    parts = spec.split(":")
    try:
        if parts[0] != "payload" or len(parts) not in (3, 4):
            raise ValueError
        kg = float(parts[2])
        std = float(parts[3]) if len(parts) == 4 else 0.0
    except ValueError:
        raise InputError(f"--reference {spec}: expected payload:DIR:KG[:STD_KG].") from None
    if not (math.isfinite(kg) and kg > 0 and math.isfinite(std) and std >= 0):
        raise InputError(f"--reference {spec}: the payload's mass must be > 0 kg and its std "
                         ">= 0.")
    return parts[1], kg, std


def identify_currents_payload(ds_a, ds_b, payload_kg: float, payload_std: float = 0.0,
                              **kw) -> CurrentsReport:
    """Recording A's platform and drives, the scale from the payload pair.

    Parameters
    ----------
    ds_a, ds_b : Dataset
        Without and with the payload (same robot and drives).
    payload_kg, payload_std : float
        The added mass and its std, kg.
    **kw
        Options of :func:`cdprid.identify.identify_currents` (not ``reference``, ``drives``).

    Returns
    -------
    CurrentsReport
        Recording A's, with ``reference.kind == "payload"``.
    """
    if ds_a.robot.n_cables != ds_b.robot.n_cables:
        raise InputError(f"{ds_b.path}: the payload recording has {ds_b.robot.n_cables} cables, "
                         f"the first {ds_a.robot.n_cables}.")
    unit = _unit_drives(ds_a)
    a = identify_currents(ds_a, reference=_PROVISIONAL, drives=unit, **kw)
    b = identify_currents(ds_b, reference=_PROVISIONAL, drives=unit, **kw)
    dm_hat = b.theta[0] - a.theta[0]
    var_dm = a.cov[0, 0] + b.cov[0, 0]
    if dm_hat <= 3.0 * math.sqrt(var_dm):
        raise InputError(f"{ds_b.path}: the payload recording's mass is not larger than the "
                         f"first's beyond its noise ({dm_hat:.3g} +- {math.sqrt(var_dm):.2g} in "
                         "provisional units): check the recordings or use a heavier payload.")
    rho = payload_kg / dm_hat
    theta = rho * a.theta
    g = np.zeros(len(a.theta))
    g[0] = rho ** 2 / payload_kg  # d rho / d m_A
    J = rho * np.eye(len(a.theta)) + np.outer(a.theta, g)
    drho = np.array([rho ** 2 / payload_kg, rho / payload_kg])  # d rho / d (m_B, dm)
    ext = np.outer(a.theta, drho) @ np.diag([b.cov[0, 0], payload_std ** 2]) @ np.outer(
        a.theta, drho).T
    cov = J @ a.cov @ J.T + ext
    cov_iid = J @ a.cov_iid @ J.T + ext
    ref = ScaleReference("payload", float(payload_kg), float(payload_std), None,
                         f"payload pair: {payload_kg:g} kg (std {payload_std:g} kg) added in "
                         f"{ds_b.path}; the mass difference of the two recordings fixes the "
                         "scale")
    sheet = read_drives(ds_a.path) if ds_a.path is not None else None
    return dataclasses.replace(a, theta=theta, cov=cov, cov_iid=cov_iid, reference=ref,
                               crb_std=None, nominal_k=None if sheet is None else
                               sheet.k_nominal, cells=None)


def _unit_drives(ds):
    """Drive data whose drive 1 has k = 1 N/A exactly (the provisional reference)."""
    from cdprid.io import DriveData

    m = ds.robot.n_cables
    one = np.ones(m)
    return DriveData(one, one, one, np.full(m, np.nan), np.zeros(m, bool))
