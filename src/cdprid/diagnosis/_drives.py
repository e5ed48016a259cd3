"""The diagnosis on the winch drives' currents (``diagnose --source currents``, issue 41 item 4).

Without load cells the force stream is each drive's **datasheet tension** ``k_nom i``
(``currents.csv`` times ``k_nom = torque_constant gear_ratio / drum_radius`` of robot.toml,
format 1.2), on the currents' own clock. Against the true tension of the drive model
(docs/drives.md), ``tau = k i + J l'' + f_v l' + f_c sign(l') - k i_0``, what the datasheet
model misses is the vocabulary's drive-side effects, found like every other effect:
``torque_constant_error`` (``k / k_nom``), ``current_offset`` (``i_0``), ``drive_friction``
(``f_c``, ``f_v``; with the pulleys' own) and ``drive_inertia`` (``J``). Their diagnosis forms
share the load cell's offset, gain and pulley-friction blocks (the same algebra on the
reading); the load cell's own effects (its offset, gain, drift, hysteresis, the pulley friction
in front of it) are not candidates.

The scale: the motion equations and the drive model scale together, so one drive's torque
constant is taken as exact (the scale reference, never a ``torque_constant_error``
candidate): ``--reference drive:K``, else robot.toml's ``drive_reference = true``, else the
drive stated calibrated (``torque_constant_tolerance = 0``). Without one the diagnosis still
runs, every drive a candidate, and a note says the mass and the torque constants are then on
the datasheets' common scale.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from cdprid.base import InputError
from cdprid.io import Dataset, read_drives, read_stream

__all__ = ["DriveSource", "SOURCES", "drive_dataset"]

#: the force streams ``diagnose --source`` takes
SOURCES = ("tensions", "currents")


@dataclasses.dataclass(frozen=True)
class DriveSource:
    """How a current stream became the diagnosis's force stream.

    Attributes
    ----------
    k_nominal : numpy.ndarray (m,)
        The datasheet current-to-force constants, N/A.
    reference_cable : int or None
        The drive whose torque constant is the scale (1-based), None without one.
    reference_source : str
        Where it comes from (one phrase).
    """

    k_nominal: np.ndarray
    reference_cable: int | None
    reference_source: str

    def note(self) -> str:
        """The note every diagnosis on currents carries.

        Returns
        -------
        str
        """
        ks = ", ".join(f"{k:.4g}" for k in self.k_nominal)
        text = ("source currents: the force stream is each drive's datasheet tension k i "
                f"(currents.csv; k = torque_constant gear_ratio / drum_radius = {ks} N/A); "
                "the drive-side effects (torque_constant_error, current_offset, drive_friction, "
                "drive_inertia) are candidates, the load cell's are not")
        if self.reference_cable is None:
            return text + ("; no drive is the scale reference (" + self.reference_source
                           + "): the mass and every torque constant are on the datasheets' "
                           "common scale, as good as their torque constants")
        return text + (f"; drive {self.reference_cable} is the scale reference "
                       f"({self.reference_source}): its torque constant is taken as exact")

    def as_json(self) -> dict:
        """``info["source_currents"]`` of the diagnosis JSON.

        Returns
        -------
        dict
            ``k_nominal_N_per_A``, ``reference_cable``, ``reference_source``.
        """
        return {"k_nominal_N_per_A": [float(k) for k in self.k_nominal],
                "reference_cable": self.reference_cable,
                "reference_source": self.reference_source}


def _reference(spec: str | None, drives) -> tuple[int | None, str]:
    """The scale reference drive and where it comes from."""
    m = drives.n
    if spec not in (None, "auto"):
        if not spec.startswith("drive:"):
            raise InputError(f"--reference {spec!r}: diagnose --source currents takes "
                             "drive:K (the diagnosis fits the mass; one drive's torque "
                             "constant fixes the scale).")
        try:
            cable = int(spec.split(":", 1)[1])
        except ValueError:
            raise InputError(f"--reference {spec}: expected drive:K with K a cable "
                             "number.") from None
        if not 1 <= cable <= m:
            raise InputError(f"--reference {spec}: K must be a cable number 1..{m}.")
        return cable, "--reference"
    if drives.reference.any():
        return int(np.flatnonzero(drives.reference)[0]) + 1, "drive_reference = true"
    exact = np.flatnonzero(drives.tolerance == 0.0)
    if exact.size:
        return int(exact[0]) + 1, "torque_constant_tolerance = 0 in robot.toml"
    return None, "robot.toml marks none: drive_reference = true or torque_constant_tolerance = 0"


def drive_dataset(ds: Dataset, reference: str | None = None) -> tuple[Dataset, DriveSource]:
    """The dataset with its current stream as the force stream (the datasheet's ``k i``).

    Parameters
    ----------
    ds : Dataset
        Read with ``require_tensions=False`` from a folder with ``currents.csv`` and
        robot.toml's drive fields (format 1.2); a tensions.csv beside them is not used.
    reference : str, optional
        ``drive:K`` or ``auto``/None (see the module).

    Returns
    -------
    (Dataset, DriveSource)

    Raises
    ------
    InputError
        One sentence naming the file or option: no dataset folder, no drive fields, no
        currents.csv, a malformed one, a reference that is not a drive.
    """
    if ds.path is None:
        raise InputError("diagnose --source currents reads currents.csv from a dataset folder.")
    m = ds.robot.n_cables
    drives = read_drives(ds.path)
    if drives is None:
        raise InputError(f"{ds.path / 'robot.toml'}: --source currents needs the drive fields "
                         "drum_radius, gear_ratio and torque_constant on every [[cable]] "
                         "(docs/drives.md).")
    cur = read_stream(ds.path, "currents", "i", m)
    if cur is None:
        raise InputError(f"{ds.path}: --source currents needs currents.csv (t,i_1..i_{m}, A).")
    cable, where = _reference(reference, drives)
    t, i = cur
    k = np.asarray(drives.k_nominal, float)
    out = dataclasses.replace(ds, tension_t=np.asarray(t, float),
                              tension=np.asarray(i, float) * k[None, :])
    return out, DriveSource(k, cable, where)
