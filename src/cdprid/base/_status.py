"""One status for every iterative solver of the package (as optimistix's ``RESULTS``)."""

from __future__ import annotations

import enum

__all__ = ["Status"]


class Status(str, enum.Enum):
    """How an iterative solve ended: ``converged``, ``max steps`` (stopped at its step budget)
    or ``failed`` (any other solver failure). A ``str`` enum: it serialises to its value."""

    CONVERGED = "converged"
    MAX_STEPS = "max steps"
    FAILED = "failed"

    @classmethod
    def of_optimistix(cls, result) -> Status:
        """The status of an optimistix solution's ``result`` (``optx.RESULTS``).

        Parameters
        ----------
        result : optimistix.RESULTS
            The ``result`` field of an optimistix solution.

        Returns
        -------
        Status
            ``CONVERGED`` on success, ``MAX_STEPS`` at the step limit, else ``FAILED``.
        """
        import optimistix as optx

        if result == optx.RESULTS.successful:
            return cls.CONVERGED
        if result == optx.RESULTS.nonlinear_max_steps_reached:
            return cls.MAX_STEPS
        return cls.FAILED

    @property
    def ok(self) -> bool:
        """True for :attr:`CONVERGED`."""
        return self is Status.CONVERGED
