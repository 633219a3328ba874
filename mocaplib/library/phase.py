"""A library entry's cycle seen from a later instant of it: :func:`start_later`, and
:func:`from_left_toe_off` for entries whose cycle starts at another event than a left toe-off.

An entry's Fourier series are periodic in its period T and start (phase 0) at the cycle's
start. The same cycle seen from τ seconds later has the series q(t + τ): each harmonic k turns
by 2πkτ/T. Root channels are then re-anchored so that the path frame starts, as in every
entry, at the root's pose (up to the series' value at t = 0, L(0)): with L(s) the encoded root
pose (pelvis_tx, pelvis_ty, pelvis_rotation) as an element of SE(2) and c = L(0)·L(τ)⁻¹, the new
root channels are c·L(τ + t) and the path frame's body velocity (u_f, u_l, ω) is carried by c's
adjoint (u' = R(θ_c)·u + ω·(c_y, −c_x)). Velocities (v̂, ω̂, v̂_l, v̂_f) and the pattern are
averages over the whole cycle and do not change; the poulaine's phases shift by −τ/T. The
ramp (``fourier.ramp``, the captured cycle's start-to-end change, put back as ramp·t/T) is kept
as it is: the periodic series carry the cycle, the ramp only its small failure to close.

Consumers that take phase 0 as the left toe-off (the control space's blending of Fourier
series, the mirror image of an entry) read an entry flagged with ``cycle_start`` through
:func:`from_left_toe_off`: the cycle from its left toe-off (``left_toe_off_s`` in), which is
exact for the periodic series (docs/guide/events-cycles.md).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..gait.fourier import synthesize
from ..gait.poulaine import AnklePath, Poulaine
from ..skeleton import ROOT_HEADING, ROOT_X, ROOT_Y
from .entry import EntryDrift, EntryFourier, EntryPoulaine


def shifted_series(entry, tau: float, /) -> tuple[np.ndarray, np.ndarray, float, float]:
    """The entry's Fourier coefficients ``a``, ``b`` (D, N+1) from ``tau`` seconds into its
    cycle on, root channels re-anchored (module docstring), and the path frame's forward and
    lateral velocities (u_f, u_l) m/s carried with them."""

    period = float(entry.T)
    a, b = entry.fourier.a.copy(), entry.fourier.b.copy()
    root = [ROOT_X, ROOT_Y, ROOT_HEADING]
    (x0, y0, heading0), (xt, yt, heading_t) = synthesize(a[root], b[root], period, [0.0, tau])
    phase = 2 * np.pi * np.arange(a.shape[1]) * tau / period      # q(t + tau)
    a, b = a * np.cos(phase) + b * np.sin(phase), b * np.cos(phase) - a * np.sin(phase)
    turn = heading0 - heading_t                # c = L(0)·L(tau)^-1 in SE(2)
    rotation = np.array([[np.cos(turn), -np.sin(turn)], [np.sin(turn), np.cos(turn)]])
    shift = np.array([x0, y0]) - rotation @ [xt, yt]
    for coefficients in (a, b):
        coefficients[[ROOT_X, ROOT_Y]] = rotation @ coefficients[[ROOT_X, ROOT_Y]]
    a[[ROOT_X, ROOT_Y], 0] += shift
    a[ROOT_HEADING, 0] += turn
    drift = entry.root_drift
    u_f, u_l = rotation @ [drift.u_f_m_s, drift.u_l_m_s] + float(drift.omega_rad_s) * np.array(
        [shift[1], -shift[0]])
    return a, b, float(u_f), float(u_l)


def shifted_poulaine(poulaine, start: float, /, *, reflect: bool = False):
    """A poulaine as an entry stores it (:class:`mocaplib.library.entry.EntryPoulaine`) from phase
    ``start`` (t/T) of its cycle on: phases shift by ``-start`` (points rolled to keep their
    order); with ``reflect`` also seen in the mirror (y → −y): the left ankle's path becomes
    the right one's with y negated (points and tangents), the travel direction negated. The fit
    errors and the step parameters are unchanged."""

    flip = np.array([1.0, -1.0 if reflect else 1.0, 1.0])

    def path(ankle: AnklePath) -> AnklePath:
        phases = np.mod(ankle.phases - start, 1.0)
        order = np.roll(np.arange(4), -int(np.argmin(phases)))
        return AnklePath(tuple(ankle.kinds[k] for k in order), phases[order],
                         ankle.points[order] * flip, ankle.tangents[order] * flip,
                         ankle.timing[order], ankle.fit_rms, ankle.fit_max, ankle.timed_rms)

    model = poulaine.model()
    if reflect:
        return EntryPoulaine.of(Poulaine(-model.travel, path(model.right), path(model.left)))
    return EntryPoulaine.of(Poulaine(model.travel, path(model.left), path(model.right)))


def start_later(entry, tau: float, /, *, cycle_start: str | None, left_toe_off_s=None):
    """The :class:`~mocaplib.library.entry.LibraryEntry` ``entry`` with its cycle starting ``tau``
    seconds later (0 ≤ tau < T), at the event ``cycle_start`` (None: a left toe-off;
    ``left_toe_off_s`` then None, else the left toe-off's time from the new start): series,
    root drift, window, right toe-off and poulaine re-expressed (module docstring); the QC
    metrics, pattern and velocities are the entry's."""

    period = float(entry.T)
    a, b, u_f, u_l = shifted_series(entry, tau)
    drift = entry.root_drift
    right = None if entry.right_toe_off_s is None else \
        float(np.mod(entry.right_toe_off_s - tau, period))
    return replace(
        entry, start_s=float(entry.start_s) + tau, end_s=float(entry.start_s) + tau + period,
        right_toe_off_s=right, cycle_start=cycle_start, left_toe_off_s=left_toe_off_s,
        fourier=EntryFourier(entry.fourier.n, a, b, entry.fourier.ramp),
        poulaine=None if entry.poulaine is None else shifted_poulaine(entry.poulaine,
                                                                      tau / period),
        root_drift=EntryDrift.moving(u_f, u_l, float(drift.omega_rad_s), period))


def from_left_toe_off(entry, /):
    """The entry expressed from its left toe-off: itself when its cycle starts there
    (``cycle_start`` None), else :func:`start_later` by its ``left_toe_off_s``; its window
    (``start_s``, ``end_s``) then starts at that toe-off and runs one period on."""
    if entry.cycle_start is None:
        return entry
    return start_later(entry, float(entry.left_toe_off_s), cycle_start=None)
