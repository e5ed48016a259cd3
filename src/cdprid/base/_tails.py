"""Tail probabilities of the normal and chi-square laws through ``scipy.special`` alone.

``scipy.stats`` costs about 0.65 s to import; the episodes' thresholds and p-values need a
few of its functions, which ``scipy.special`` computes with the same code (equal to the last
bit, scipy 1.17). Importing them from here keeps ``cdprid identify``'s start-up short;
``scipy.special`` itself is imported on first use (the base layer is on every command's
``--help`` path, which imports no SciPy).

The two quantiles every identification's episode thresholds need, :func:`normal_isf` and
:func:`chi2_isf` at integer degrees of freedom (q <= 0.5), need no SciPy at all (``scipy.special``
and the array-API layer it brings cost ~0.1 s of ``cdprid identify``'s start): the normal
one is the standard library's (Wichura's AS 241), the chi-square one solves the closed-form
tail of an integer number of degrees of freedom by Newton's method; both agree with
``scipy.stats`` to ~1e-15 relative (tests/base/test_tails.py).
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["chi2_isf", "chi2_logsf", "chi2_sf", "f_isf", "f_sf", "normal_isf", "normal_sf"]


def normal_sf(z):
    """Upper tail of the standard normal law, ``P(Z > z)`` (``scipy.stats.norm.sf``).

    Parameters
    ----------
    z : float or array_like
        Standardised value(s).

    Returns
    -------
    float or numpy.ndarray
        The probability, same shape as ``z``.
    """
    from scipy import special

    return special.ndtr(-np.asarray(z, float))


def normal_isf(q):
    """The standard normal value exceeded with probability ``q`` (``scipy.stats.norm.isf``).

    Parameters
    ----------
    q : float or array_like
        Upper-tail probability (0 < q < 1).

    Returns
    -------
    float or numpy.ndarray
        The value ``z`` with ``P(Z > z) = q``, same shape as ``q`` (nan outside (0, 1), inf
        at 0, -inf at 1).
    """
    q = np.asarray(q, float)
    return _scalar(np.vectorize(_normal_isf_one, otypes=[float])(q))


def _normal_isf_one(q: float) -> float:
    from statistics import NormalDist

    if not 0.0 <= q <= 1.0:
        return math.nan
    if q == 0.0 or q == 1.0:
        return math.inf if q == 0.0 else -math.inf
    return -NormalDist().inv_cdf(q)


def chi2_sf(x, k):
    """Upper tail of the chi-square law with ``k`` degrees of freedom (``scipy.stats.chi2.sf``).

    Parameters
    ----------
    x : float or array_like
        Statistic value(s), >= 0.
    k : float or array_like
        Degrees of freedom.

    Returns
    -------
    float or numpy.ndarray
        ``P(X > x)``, broadcast shape of ``x`` and ``k``.
    """
    from scipy import special

    x, k = np.asarray(x, float), np.asarray(k, float)
    # scipy.stats' support and argument checks: x < 0 has the whole mass above it, k <= 0
    # is no law
    p = np.where(x < 0, 1.0, special.chdtrc(k, np.maximum(x, 0.0)))
    return _scalar(np.where(k > 0, p, np.nan))


def chi2_logsf(x, k):
    """Log of the chi-square upper tail (``scipy.stats.chi2.logsf``, computed as it does:
    ``log(sf)`` above the median, ``log1p(-cdf)`` at or below it).

    Parameters
    ----------
    x : float or array_like
        Statistic value(s).
    k : float or array_like
        Degrees of freedom (> 0).

    Returns
    -------
    float or numpy.ndarray
        ``log P(X > x)``, broadcast shape of ``x`` and ``k``.
    """
    from scipy import special

    x, k = np.asarray(x, float), np.asarray(k, float)
    xp = np.maximum(x, 0.0)
    with np.errstate(divide="ignore"):
        lp = np.where(xp > special.chdtri(k, 0.5), np.log(special.chdtrc(k, xp)),
                      np.log1p(-special.chdtr(k, xp)))
    return _scalar(np.where(k > 0, np.where(x < 0, 0.0, lp), np.nan))


def f_sf(x, dfn, dfd):
    """Upper tail of the F law (``scipy.stats.f.sf``).

    Parameters
    ----------
    x : float or array_like
        Statistic value(s).
    dfn, dfd : float or array_like
        Numerator and denominator degrees of freedom (> 0).

    Returns
    -------
    float or numpy.ndarray
        ``P(F > x)``, broadcast shape of the arguments.
    """
    from scipy import special

    x, dfn, dfd = (np.asarray(v, float) for v in (x, dfn, dfd))
    p = np.where(x < 0, 1.0, special.fdtrc(dfn, dfd, np.maximum(x, 0.0)))
    return _scalar(np.where((dfn > 0) & (dfd > 0), p, np.nan))


def _scalar(a):
    """A 0-d result as a NumPy scalar (as scipy.stats returns it)."""
    a = np.asarray(a)
    return a[()] if a.ndim == 0 else a


def chi2_isf(q, k):
    """The chi-square value exceeded with probability ``q`` (``scipy.stats.chi2.isf``).

    Parameters
    ----------
    q : float or array_like
        Upper-tail probability (0 < q < 1); ``chi2_isf(1 - p, k)`` is the ``p`` quantile.
    k : float or array_like
        Degrees of freedom.

    Returns
    -------
    float or numpy.ndarray
        The value ``x`` with ``P(X > x) = q``, broadcast shape of ``q`` and ``k``.
    """
    q, k = np.asarray(q, float), np.asarray(k, float)
    # integer dof at or above the median (the thresholds' case): the closed-form tail, no
    # SciPy; below the median log P(X > x) = log(1 - small) is better left to scipy
    if (np.all((k >= 1) & (k == np.round(k)) & (k <= 64))
            and np.all((q >= 1e-250) & (q <= 0.5))):
        return _scalar(np.vectorize(_chi2_isf_int, otypes=[float])(q, k.astype(int)))
    from scipy import special

    return special.chdtri(k, q)


def _chi2_logsf_int(x: float, k: int) -> float:
    """``log P(X > x)`` for ``k`` integer degrees of freedom (x > 0): ``exp(-x/2)`` times
    the Poisson sum for even ``k``; ``erfc(sqrt(x/2))`` plus ``sqrt(2 x / pi) exp(-x/2)``
    times the odd terms for odd ``k`` (every term positive: no cancellation)."""
    h = 0.5 * x
    if k % 2 == 0:
        term, total = 1.0, 1.0
        for i in range(1, k // 2):
            term *= h / i
            total += term
        return -h + math.log(total)
    lead = math.erfc(math.sqrt(h))
    term, total = 1.0, 0.0
    for i in range((k - 1) // 2):
        total += term
        term *= x / (2 * i + 3)
    rest = math.sqrt(2.0 * x / math.pi) * total
    if rest == 0.0:
        return math.log(lead) if lead > 0 else -math.inf
    log_rest = math.log(rest) - h
    if lead == 0.0:
        return log_rest
    a, b = (math.log(lead), log_rest)
    m = max(a, b)
    return m + math.log(math.exp(a - m) + math.exp(b - m))


def _chi2_isf_int(q: float, k: int) -> float:
    """:func:`chi2_isf` for one ``q`` in (0, 0.5] and integer ``k``: Newton's method on
    ``log P(X > x) = log q`` from the Wilson-Hilferty start, safeguarded by a bracket."""
    target = math.log(q)
    z = _normal_isf_one(q)
    c = 2.0 / (9.0 * k)
    x = max(k * (1.0 - c + z * math.sqrt(c)) ** 3, 1e-300)
    lo, hi = 0.0, math.inf
    lg = math.lgamma(0.5 * k)
    for _ in range(200):
        logsf = _chi2_logsf_int(x, k)
        f = logsf - target
        if f > 0:
            lo = x
        else:
            hi = x
        # d/dx log sf = -pdf / sf, pdf = x^(k/2-1) exp(-x/2) / (2^(k/2) Gamma(k/2))
        log_pdf = (0.5 * k - 1.0) * math.log(x) - 0.5 * x - 0.5 * k * math.log(2.0) - lg
        rate = math.exp(log_pdf - logsf)
        new = x + f / rate if rate > 0 and math.isfinite(rate) else -1.0
        if not lo < new < hi:
            new = 0.5 * (lo + hi) if math.isfinite(hi) else 2.0 * x + 1.0
        if abs(new - x) <= 4e-16 * max(x, 1e-300):
            return new
        x = new
    return x


def f_isf(q, dfn, dfd):
    """The F value exceeded with probability ``q`` (``scipy.stats.f.isf``), through the
    incomplete beta function: ``Y = dfd / (dfd + dfn F)`` is Beta(dfd/2, dfn/2) and
    ``P(F > f) = I_y(dfd/2, dfn/2)``, exact in the far tail where ``1 - q`` would round.

    Parameters
    ----------
    q : float or array_like
        Upper-tail probability (0 < q < 1).
    dfn, dfd : float or array_like
        Numerator and denominator degrees of freedom.

    Returns
    -------
    float or numpy.ndarray
        The value ``f`` with ``P(F > f) = q``.
    """
    from scipy import special

    dfn, dfd = np.asarray(dfn, float), np.asarray(dfd, float)
    y = special.betaincinv(dfd / 2.0, dfn / 2.0, np.asarray(q, float))
    return dfd * (1.0 - y) / (dfn * y)
