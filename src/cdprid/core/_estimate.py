"""Typed estimates: one identified parameter with its value, std, interval and unit.

:class:`Estimate` is one parameter, :class:`Estimates` the ordered set of a fit with its
covariance matrices. Their ``as_json()`` is the ``parameters`` object of ``cdprid identify
--json`` (keys ``value``, ``std``, ``rel_std_percent``, ``std_iid``, ``crb_std``,
``efficiency``), computed with the same floating-point operations as before they were typed.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterator

import numpy as np

__all__ = ["PARAMETER_UNITS", "Z_95", "Estimate", "Estimates", "parameter_unit"]

#: SI unit of each inertial parameter (first moments m s_G in kg m, inertia in kg m^2)
PARAMETER_UNITS = {
    "m": "kg",
    **{n: "kg m" for n in ("mxG", "myG", "mzG")},
    **{n: "kg m^2" for n in ("Ixx", "Ixy", "Ixz", "Iyy", "Iyz", "Izz")},
}

Z_95 = 1.959963984540054
"""Two-sided 95 % quantile of the standard normal (the interval's half-width in std)."""


def parameter_unit(name: str) -> str:
    """The SI unit of a parameter name ("" when it is not an inertial parameter).

    Parameters
    ----------
    name : str
        ``m``, ``mxG``..``mzG`` or ``Ixx``..``Izz``.

    Returns
    -------
    str
        ``kg``, ``kg m``, ``kg m^2`` or ``""``.
    """
    return PARAMETER_UNITS.get(name, "")


@dataclasses.dataclass(frozen=True)
class Estimate:
    """One identified parameter.

    Attributes
    ----------
    name : str
        Parameter name (``m``, ``mxG``, ..., ``Izz``).
    value : float
        The estimate, in ``unit``.
    std : float
        Its standard deviation as chosen (HAC or eq. 20), in ``unit``.
    std_iid : float
        The i.i.d. standard deviation (the paper's eq. 20), in ``unit``.
    unit : str
        SI unit (:data:`PARAMETER_UNITS`).
    crb_std : float or None
        The recording's Cramer-Rao bound on the std, in ``unit`` (None: not computed).
    """

    name: str
    value: float
    std: float
    std_iid: float
    unit: str = ""
    crb_std: float | None = None

    @property
    def interval(self) -> tuple[float, float]:
        """``(low, high)``: the 95 % interval ``value -+ 1.96 std`` (normal approximation), in
        ``unit``."""
        return (self.value - Z_95 * self.std, self.value + Z_95 * self.std)

    @property
    def rel_std_percent(self) -> float:
        """``100 std / |value|`` (inf at a zero value, NaN when std is zero too)."""
        if self.value == 0.0:
            return math.inf if self.std > 0 else math.nan
        return 100.0 * self.std / abs(self.value)

    @property
    def efficiency(self) -> float | None:
        """``std / crb_std`` (1 is the best possible), None without a bound."""
        return None if self.crb_std is None else self.std / self.crb_std

    def as_json(self, bound: bool = True) -> dict:
        """One entry of the ``parameters`` object of ``cdprid identify --json``.

        Parameters
        ----------
        bound : bool
            Include ``crb_std`` and ``efficiency``; False for ``identify --online``, which computes
            no bound.

        Returns
        -------
        dict
            ``{"value", "std", "rel_std_percent", "std_iid"}`` and, with ``bound``,
            ``"crb_std", "efficiency"`` (SI units of the parameter; percent; efficiency
            dimensionless).
        """
        out = {"value": self.value, "std": self.std, "rel_std_percent": self.rel_std_percent,
               "std_iid": self.std_iid}
        if bound:
            out.update(crb_std=self.crb_std, efficiency=self.efficiency)
        return out


@dataclasses.dataclass(frozen=True, eq=False)
class Estimates:
    """The ordered estimates of one fit with their covariance matrices.

    Iterating gives the :class:`Estimate` items; ``est["m"]`` one by name, ``est[0]`` by
    position.

    Attributes
    ----------
    items : tuple of Estimate
    cov : ndarray (p, p)
        Covariance as chosen (HAC or eq. 20), units of the parameters' products.
    cov_iid : ndarray (p, p)
        The i.i.d. covariance (eq. 20).
    """

    items: tuple[Estimate, ...]
    cov: np.ndarray
    cov_iid: np.ndarray

    @classmethod
    def from_covariance(cls, names, x, cov, cov_iid, crb_std=None) -> Estimates:
        """The estimates of ``x`` with the std of ``cov``'s and ``cov_iid``'s diagonals.

        Parameters
        ----------
        names : sequence of str
            Parameter names (p).
        x : array (p,)
            Estimates, SI units (:data:`PARAMETER_UNITS`).
        cov, cov_iid : array (p, p)
            Covariances (chosen and i.i.d.); negative diagonal entries count as 0.
        crb_std : array (p,), optional
            Cramer-Rao bound of each std; entries that are not positive mean no bound.

        Returns
        -------
        Estimates
        """
        x = np.asarray(x, float)
        cov, cov_iid = np.asarray(cov, float), np.asarray(cov_iid, float)
        s = np.sqrt(np.clip(np.diag(cov), 0, None))
        si = np.sqrt(np.clip(np.diag(cov_iid), 0, None))
        items = tuple(
            Estimate(n, float(v), float(a), float(b), parameter_unit(n),
                     float(crb_std[k]) if crb_std is not None and crb_std[k] > 0 else None)
            for k, (n, v, a, b) in enumerate(zip(names, x, s, si, strict=True)))
        return cls(items, cov, cov_iid)

    @property
    def names(self) -> tuple[str, ...]:
        """Parameter names, in order."""
        return tuple(e.name for e in self.items)

    @property
    def values(self) -> np.ndarray:
        """The estimates as a vector (p,)."""
        return np.array([e.value for e in self.items], float)

    @property
    def std(self) -> np.ndarray:
        """The chosen std as a vector (p,)."""
        return np.array([e.std for e in self.items], float)

    def __iter__(self) -> Iterator[Estimate]:
        return iter(self.items)

    def __len__(self) -> int:
        return len(self.items)

    def __getitem__(self, key: str | int) -> Estimate:
        if isinstance(key, str):
            for e in self.items:
                if e.name == key:
                    return e
            raise KeyError(key)
        return self.items[key]

    def __contains__(self, name: object) -> bool:
        return name in self.names

    def as_json(self, bound: bool = True) -> dict:
        """The ``parameters`` object of the JSON: every estimate by name, in order.

        Parameters
        ----------
        bound : bool
            Passed to :meth:`Estimate.as_json` (False: no ``crb_std``/``efficiency``).

        Returns
        -------
        dict
            ``{name: Estimate.as_json(bound)}``.
        """
        return {e.name: e.as_json(bound) for e in self.items}
