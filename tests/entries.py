"""Library entries for tests, from plain values: a :class:`mocaplib.library.entry.LibraryEntry` with its
nested records built from arrays and dicts, as a test writes them."""

from __future__ import annotations

import numpy as np

from mocaplib.library.entry import EntryDrift, EntryFourier, EntryPattern, EntryPoulaine, LibraryEntry


def plain_entry(*, pattern: dict, a: np.ndarray, b: np.ndarray, root_drift: dict,
                ramp: np.ndarray | None = None, poulaine: dict | None = None,
                **fields) -> LibraryEntry:
    """A LibraryEntry of ``fields`` (its own keywords) with ``pattern`` a dict (``type``, and
    optionally ``parameters``, ``residual_m``, ``arc_angle_rad``), Fourier ``a``, ``b``
    (D, N+1) fitted to order N (and ``ramp``), ``root_drift`` the path frame's velocities
    ``u_f_m_s``, ``u_l_m_s``, ``omega_rad_s`` (its displacement over ``T`` derived) and
    ``poulaine`` as :meth:`mocaplib.gait.poulaine.Poulaine.to_dict` gives it."""
    fields.setdefault("qc_waived", {})
    fields.setdefault("locomotion_class", None)
    return LibraryEntry(
        poulaine=None if poulaine is None else EntryPoulaine.from_json(poulaine),
        pattern=EntryPattern(pattern["type"], dict(pattern.get("parameters", {})),
                             pattern.get("residual_m"), pattern.get("arc_angle_rad")),
        fourier=EntryFourier.of(a, b, ramp=ramp),
        root_drift=EntryDrift.moving(root_drift["u_f_m_s"], root_drift["u_l_m_s"],
                                     root_drift["omega_rad_s"], fields["T"]),
        **fields)
