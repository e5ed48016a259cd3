"""Tail probabilities of the normal and chi-square laws through ``scipy.special`` alone.

``scipy.stats`` costs about 0.65 s to import; the episodes' thresholds and p-values need a
few of its functions, which ``scipy.special`` computes with the same code (equal to the last
bit, scipy 1.17). Importing them from here keeps ``cdprid identify``'s start-up short;
``scipy.special`` itself is imported on first use (the base layer is on every command's
``--help`` path, which imports no SciPy).
"""

from __future__ import annotations

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
        The value ``z`` with ``P(Z > z) = q``, same shape as ``q``.
    """
    from scipy import special

    return -special.ndtri(np.asarray(q, float))


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
    from scipy import special

    return special.chdtri(np.asarray(k, float), np.asarray(q, float))


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
