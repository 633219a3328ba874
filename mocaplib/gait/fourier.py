"""Fourier encoding of one cycle's joint coordinates (the paper's equation (3)).

Convention (fixed for the whole library)::

    q_d(t) = a[d, 0] + Σ_{k=1..N} ( a[d, k]·cos(2πkt/T) + b[d, k]·sin(2πkt/T) ),   t ∈ [0, T)

with t measured from the cycle's start (a left toe-off) and ``b[:, 0] = 0``. The paper prints
``kπt/T``; with that argument the first harmonic has period 2T, so a series of it is not
T-periodic and a blended cycle would not join its own start. ``2πkt/T`` makes T the base period,
so every stored channel repeats exactly each cycle, which is what blending and looping need.

Periodic channels: every angle is unwrapped over the cycle. The root's horizontal pose
(``pelvis_tx``, ``pelvis_ty``, ``pelvis_rotation``) drifts over a cycle, so it is stored in a frame
moving along the cycle's path (see :class:`RootDrift`): what is encoded is the root pose relative
to that frame, which is periodic; the drift itself (start pose and the frame's constant
body-frame velocity and turn rate) is stored apart and :meth:`RootDrift.restore` puts it back.
A real cycle never closes exactly either (an arm swings a little further, a stride ends a little
differently: 5-25° on some DOF of every lab walk at hand), and a series forced through that
step needs every harmonic it is allowed. So each channel's change from the cycle's start to its
end (its *ramp*, D numbers, 0 for the three root channels the drift carries) is taken out as a
straight line, ``q_d(t) - ramp_d·t/T``, and stored beside the series: the series is the
periodic cycle a controller loops, series + ramp·t/T the captured one.

**Order (the rule).** The smallest N whose reconstruction RMS at the samples is within each
channel's tolerance: ``tol_length`` (2 mm) for translations; for an angle, what its data
support: its *noise floor* — the RMS over the cycle of the fitted angle minus the angle
low-passed at :data:`mocaplib.model.filtering.WALKING_CUTOFF` (6 Hz; what a gait analysis keeps) —
clipped to [``tol_angle``, :data:`MAX_ANGLE_TOLERANCE`] = [0.5°, 1°]. A clean angle is encoded
within 0.5° (Skejø 2021: about 5 harmonic pairs); a noisy one within its own noise, never
looser than 1°, which is the library's Fourier QC limit (:data:`mocaplib.gait.qc.QC_LIMITS`):
a cycle fails it only when 20 harmonics cannot reach 1° on some angle. Measured orders:
docs/guide/fourier.md.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import FitError
from ..skeleton import DOF_NAMES, ROOT_HEADING, ROOT_X, ROOT_Y, TRANSLATION

#: The encoder's defaults: the reconstruction tolerance of angles (rad) and of translations (m),
#: and the highest order it may reach.
ANGLE_TOLERANCE, LENGTH_TOLERANCE, MAX_ORDER = float(np.deg2rad(0.5)), 0.002, 20
#: The loosest tolerance an angle's noise floor may give it (rad): the Fourier QC limit.
MAX_ANGLE_TOLERANCE = float(np.deg2rad(1.0))
#: Channels without a ramp: the root's horizontal pose, which :class:`RootDrift` carries.
ROOT_CHANNELS = np.isin(np.arange(len(DOF_NAMES)), [ROOT_X, ROOT_Y, ROOT_HEADING])


@dataclass(frozen=True)
class FourierSeries:
    """Truncated Fourier series of D channels over one period.

    Attributes
    ----------
    a, b : ndarray, shape (D, N+1)
        Cosine and sine coefficients; ``b[:, 0] == 0``. Units of the channels (rad or m).
    period : float
        T, seconds.
    rms : ndarray, shape (D,)
        Reconstruction RMS at the fitted samples, channel units.
    """

    a: np.ndarray
    b: np.ndarray
    period: float
    rms: np.ndarray

    @property
    def order(self) -> int:
        """N, the number of harmonics."""
        return self.a.shape[1] - 1

    def __call__(self, t) -> np.ndarray:
        """Values at times ``t`` (s from the cycle start), shape ``(*t.shape, D)``."""
        return synthesize(self.a, self.b, self.period, t)


def synthesize(a: np.ndarray, b: np.ndarray, period, t, /) -> np.ndarray:
    """Evaluate the series at times ``t``: vectorised over times and channels.

    ``a``, ``b``: (D, N+1); ``period``: T in seconds (> 0); ``t``: any shape, seconds from the
    cycle start (values outside [0, T) wrap around). Returns ``(*t.shape, D)``.
    """
    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    t = np.asarray(t, dtype=np.float64)
    if a.ndim != 2 or a.shape != b.shape:
        raise FitError(f"a and b must have the same shape (D, N+1), got {a.shape} and {b.shape}")
    if not np.all(np.asarray(period) > 0):
        raise FitError(f"the period must be > 0 s, got {period}")
    phase = 2 * np.pi * t[..., None] * np.arange(a.shape[1]) / period  # (*t, N+1)
    return np.cos(phase) @ a.T + np.sin(phase) @ b.T


def fit_series(values: np.ndarray, time_s: np.ndarray, period: float,
               order: int, /) -> FourierSeries:
    """Least-squares series of fixed ``order`` through samples ``values`` (n, D) at
    ``time_s`` (n,)."""
    values = np.asarray(values, dtype=np.float64)
    time_s = np.asarray(time_s, dtype=np.float64)
    phase = 2 * np.pi * np.outer(time_s, np.arange(1, order + 1)) / period
    design = np.column_stack([np.ones_like(time_s), np.cos(phase), np.sin(phase)])
    coef, *_ = np.linalg.lstsq(design, values, rcond=None)
    d = values.shape[1]
    a = np.vstack([coef[:1], coef[1:order + 1]]).T
    b = np.column_stack([np.zeros(d), coef[order + 1:].T])
    rms = np.sqrt(np.mean((design @ coef - values) ** 2, axis=0))
    return FourierSeries(a.reshape(d, order + 1), b.reshape(d, order + 1), float(period), rms)


def encode(values: np.ndarray, time_s: np.ndarray, period: float, /, *, tolerance,
           max_order: int = MAX_ORDER) -> FourierSeries:
    """Series of the smallest order N whose RMS is within ``tolerance`` for every channel.

    ``values`` (n, D) sampled at ``time_s`` (n,) in [0, period); ``tolerance`` scalar or (D,) in
    channel units. N is capped by ``max_order`` and by the samples ((2N+1) <= n); if no order
    meets the tolerance the capped one is returned and its ``rms`` shows by how much.
    """
    values = np.asarray(values, dtype=np.float64)
    time_s = np.asarray(time_s, dtype=np.float64)
    if values.ndim != 2 or len(values) != len(time_s):
        raise FitError(f"values must have shape (n, D) with n = len(time_s) = {len(time_s)}, "
                       f"got {values.shape}")
    if not np.isfinite(values).all():
        raise FitError("values to encode contain NaN or infinite samples")
    if not period > 0:
        raise FitError(f"the period must be > 0 s, got {period}")
    limit = max(0, min(max_order, (len(time_s) - 1) // 2))
    tolerance = np.broadcast_to(np.asarray(tolerance, dtype=np.float64), values.shape[1:])
    for order in range(limit + 1):
        series = fit_series(values, time_s, period, order)
        if np.all(series.rms <= tolerance):
            return series
    return series


# ----------------------------------------------------------------------------------- root drift
@dataclass(frozen=True)
class RootDrift:
    """The per-cycle drift of the root's horizontal pose, taken out before encoding.

    The moving frame starts at the root's pose at t = 0 (``x0``, ``y0`` metres, heading ``psi0``
    rad = ``pelvis_rotation``) and moves with constant velocity ``(u_f, u_l)`` m/s in its own
    axes (forward, left) and constant turn rate ``omega`` rad/s (model (2) of the paper), chosen
    so that it reaches the root's pose at t = T exactly: a line or circular arc through the
    cycle's start and end. Encoded root channels are the root pose in that frame:
    ``pelvis_tx``/``ty`` the position relative to the frame's origin in the frame's axes,
    ``pelvis_rotation`` the heading minus the frame's heading.
    """

    x0: float
    y0: float
    psi0: float
    u_f: float
    u_l: float
    omega: float

    def frame(self, t) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Moving frame's origin x, y (m) and heading (rad) at times ``t`` (s), each ``t.shape``."""
        t = np.asarray(t, dtype=np.float64)
        psi = self.psi0 + self.omega * t
        turned = self.omega * t
        # ∫0^t R(psi0 + ω s) ds, in closed form and stable as ω -> 0
        sinc = np.sinc(turned / np.pi)
        versine = np.where(np.abs(turned) < 1e-8, turned / 2,
                           (1 - np.cos(turned)) / np.where(turned == 0, 1, turned))
        fx = t * (sinc * self.u_f - versine * self.u_l)
        fy = t * (versine * self.u_f + sinc * self.u_l)
        c, s = np.cos(self.psi0), np.sin(self.psi0)
        return self.x0 + c * fx - s * fy, self.y0 + s * fx + c * fy, psi

    def remove(self, q: np.ndarray, time_s: np.ndarray) -> np.ndarray:
        """Joint coordinates (n, D) with the root pose expressed in the moving frame."""
        out = np.array(q, dtype=np.float64)
        x, y, psi = self.frame(time_s)
        dx, dy = out[:, ROOT_X] - x, out[:, ROOT_Y] - y
        out[:, ROOT_X] = np.cos(psi) * dx + np.sin(psi) * dy
        out[:, ROOT_Y] = -np.sin(psi) * dx + np.cos(psi) * dy
        out[:, ROOT_HEADING] -= psi
        return out

    def restore(self, q_local: np.ndarray, time_s: np.ndarray) -> np.ndarray:
        """Inverse of :meth:`remove`: world root pose from moving-frame coordinates (n, D)."""
        out = np.array(q_local, dtype=np.float64)
        x, y, psi = self.frame(time_s)
        lx, ly = out[:, ROOT_X].copy(), out[:, ROOT_Y].copy()
        out[:, ROOT_X] = x + np.cos(psi) * lx - np.sin(psi) * ly
        out[:, ROOT_Y] = y + np.sin(psi) * lx + np.cos(psi) * ly
        out[:, ROOT_HEADING] += psi
        return out

    def to_dict(self) -> dict:
        return {k: float(getattr(self, k)) for k in ("x0", "y0", "psi0", "u_f", "u_l", "omega")}


def root_drift(q_start: np.ndarray, q_end: np.ndarray, period: float, /) -> RootDrift:
    """The moving frame carrying the root pose ``q_start`` (D,) to ``q_end`` (D,) in ``period`` s.

    Headings must be unwrapped (``q_end``'s ``pelvis_rotation`` continuous with ``q_start``'s).
    """
    x0, y0, psi0 = (float(q_start[i]) for i in (ROOT_X, ROOT_Y, ROOT_HEADING))
    turned = float(q_end[ROOT_HEADING]) - psi0
    c, s = np.cos(psi0), np.sin(psi0)
    dx, dy = float(q_end[ROOT_X]) - x0, float(q_end[ROOT_Y]) - y0
    fx, fy = c * dx + s * dy, -s * dx + c * dy   # displacement in the start frame
    sinc = float(np.sinc(turned / np.pi))
    versine = turned / 2 if abs(turned) < 1e-8 else (1 - np.cos(turned)) / turned
    # [fx, fy] = T·[[sinc, -versine], [versine, sinc]]·[u_f, u_l]
    det = sinc ** 2 + versine ** 2
    u_f = (sinc * fx + versine * fy) / det / period
    u_l = (-versine * fx + sinc * fy) / det / period
    return RootDrift(x0, y0, psi0, float(u_f), float(u_l), turned / period)


@dataclass(frozen=True)
class CycleEncoding:
    """Fourier encoding of one cycle of a fitted motion.

    ``series`` holds the periodic channels (D = len(DOF_NAMES)), root in the moving frame,
    ramps taken out; ``drift`` the root drift; ``ramp`` (D,) each channel's change from the
    cycle's start to its end, taken out as ``ramp·t/T`` before encoding (rad or m; 0 for the
    root's horizontal channels); ``tolerance`` (D,) the reconstruction tolerance each channel
    was encoded to (module docstring); ``worst_dof`` the DOF with the largest RMS relative to
    its tolerance.
    """

    series: FourierSeries
    drift: RootDrift
    worst_dof: str
    ramp: np.ndarray
    tolerance: np.ndarray

    @property
    def order(self) -> int:
        return self.series.order

    @property
    def rms_deg(self) -> float:
        """Largest reconstruction RMS over the rotational DOFs, degrees."""
        return float(np.rad2deg(self.series.rms[~TRANSLATION].max()))

    def synthesize_cycle(self, t) -> np.ndarray:
        """The captured cycle's coordinates (n, D) at times ``t`` (n,) in [0, T], root in the
        moving frame: the series plus the ramps."""
        t = np.asarray(t, dtype=np.float64)
        return self.series(t) + np.outer(t / self.series.period, self.ramp)

    def synthesize_world(self, t) -> np.ndarray:
        """Joint coordinates (n, D) at times ``t`` (n,) in [0, T], ramps and drift put back
        (world frame)."""
        t = np.asarray(t, dtype=np.float64)
        return self.drift.restore(self.synthesize_cycle(t), t)


def channel_tolerance(noise: np.ndarray | None = None, /, *,
                      tol_angle: float = ANGLE_TOLERANCE,
                      tol_length: float = LENGTH_TOLERANCE) -> np.ndarray:
    """Each channel's encoding tolerance (D,) (module docstring's rule): ``tol_length`` for
    translations; for angles their ``noise`` floor (D,) rad clipped to [``tol_angle``,
    :data:`MAX_ANGLE_TOLERANCE`] (``tol_angle`` without one)."""
    angles = np.full(len(DOF_NAMES), tol_angle)
    if noise is not None:
        angles = np.clip(np.nan_to_num(np.asarray(noise, dtype=np.float64), nan=0.0),
                         tol_angle, max(tol_angle, MAX_ANGLE_TOLERANCE))
    return np.where(TRANSLATION, tol_length, angles)


def encode_cycle(q: np.ndarray, time_s: np.ndarray, period: float, q_end: np.ndarray, /, *,
                 tol_angle: float = ANGLE_TOLERANCE, tol_length: float = LENGTH_TOLERANCE,
                 noise: np.ndarray | None = None, max_order: int = MAX_ORDER) -> CycleEncoding:
    """Encode one cycle of joint coordinates.

    ``q`` (n, D) in :data:`DOF_NAMES` order (rad; ``pelvis_t*`` m) at ``time_s`` (n,) seconds
    from the cycle start, all in [0, period); ``q_end`` (D,) the coordinates at t = period (the
    next cycle's start), which fixes the drift and the ramps. Angles are unwrapped here.
    ``noise`` (D,): each channel's noise floor (rad), which sets its tolerance
    (:func:`channel_tolerance`).
    """
    q = np.asarray(q, dtype=np.float64)
    if q.ndim != 2 or q.shape[1] != len(DOF_NAMES):
        raise FitError(f"q must have shape (n, {len(DOF_NAMES)}), got {q.shape}")
    q_end = np.asarray(q_end, dtype=np.float64)
    time_s = np.asarray(time_s, dtype=np.float64)
    both = np.unwrap(np.vstack([q, q_end[None]]), axis=0)
    both[:, TRANSLATION] = np.vstack([q, q_end[None]])[:, TRANSLATION]
    drift = root_drift(both[0], both[-1], period)
    local = drift.remove(both, np.append(time_s, period))
    ramp = np.where(ROOT_CHANNELS, 0.0, local[-1] - local[0])
    tolerance = channel_tolerance(noise, tol_angle=tol_angle, tol_length=tol_length)
    series = encode(local[:-1] - np.outer(time_s / period, ramp), time_s, period,
                    tolerance=tolerance, max_order=max_order)
    worst = int(np.argmax(series.rms / tolerance))
    return CycleEncoding(series, drift, DOF_NAMES[worst], ramp, tolerance)
