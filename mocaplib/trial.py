"""The :class:`Trial` container: one capture's labelled marker cloud.

Conventions (see DESIGN.md): SI units (metres, seconds), world frame right-handed with **Z up**,
time on axis 0, markers ``(F, M, 3)`` float64 with NaN where a sample is missing (never 0).
"""

from __future__ import annotations

import os
import re
from dataclasses import dataclass, field

import numpy as np

from .errors import MocapError
from .runs import valid_runs

#: Frame rates (Hz) gait can be analysed at. Below, a stride spans too few frames to find its
#: events; above, no optical system records whole-body markers: POINT:RATE is then corrupt.
GAIT_RATES = (10.0, 10000.0)


def check_gait_rate(rate: float, source: str | os.PathLike | None,
                    error: type[MocapError] = MocapError) -> None:
    """Raise ``error`` naming ``source`` when ``rate`` (Hz) is outside :data:`GAIT_RATES`."""
    lo, hi = GAIT_RATES
    if not lo <= rate <= hi:
        raise error(f"frame rate {rate:g} Hz is outside the {lo:g}-{hi:g} Hz of gait "
                    "captures", path=source,
                    hint="the file's POINT:RATE is probably wrong: re-export the capture")


_PREFIX = re.compile(r"^.*:")
_SEPARATORS = re.compile(r"[\s_\-\.]+")


def subject_prefixes(labels: list[str], /) -> list[str]:
    """Each label's subject prefix: the text before its last ``:`` (``Subj01`` of
    ``Subj01:LASI``), ``""`` for a label without one (what :func:`normalise_label` drops)."""
    return [label.rpartition(":")[0] for label in labels]


#: Words that give a label's side when they begin or end it (:func:`written_side`).
_SIDES = {"L": "L", "LEFT": "L", "R": "R", "RIGHT": "R"}
#: The words of a label written in camel case (``Waist``, ``L``, ``Front`` of ``WaistLFront``;
#: capitals before a capitalised word are a word of their own), its digits one word.
_CAMEL_WORDS = re.compile(r"[A-Z]+(?=[A-Z][a-z])|[A-Z]?[a-z]+|[A-Z]+|[0-9]+")


def written_side(label: str) -> tuple[str | None, str]:
    """The side (``"L"`` or ``"R"``) ``label`` writes as a word of its own at either end
    (``ASI_L``, ``Left Knee``, ``knee.right``), as ``Left``/``Right`` joined to its start or
    end (``LeftASIS``, ``KneeRight``) or as the one side word inside it (``WaistLFront``,
    ``Waist_L_Front``: the animation marker sets' names), and the rest of it; (None, all of
    it) when it writes none so. Both without subject prefix, NULs, spaces or ``_ - .``, in
    upper case."""
    text = _PREFIX.sub("", label.replace("\x00", "").strip())
    words = [w.upper() for w in _SEPARATORS.split(text) if w]
    if len(words) > 1 and words[0] in _SIDES:
        return _SIDES[words[0]], "".join(words[1:])
    if len(words) > 1 and words[-1] in _SIDES:
        return _SIDES[words[-1]], "".join(words[:-1])
    joined = "".join(words)
    for word in ("LEFT", "RIGHT"):
        if len(joined) > len(word) and joined.startswith(word):
            return _SIDES[word], joined[len(word):]
        if len(joined) > len(word) and joined.endswith(word):
            return _SIDES[word], joined[:-len(word)]
    camel = [w.upper() for w in _CAMEL_WORDS.findall(text)]
    inner = [i for i, w in enumerate(camel[1:-1], 1) if w in _SIDES]
    if len(inner) == 1:
        return _SIDES[camel[inner[0]]], "".join(camel[:inner[0]] + camel[inner[0] + 1:])
    return None, joined


def normalise_label(label: str) -> str:
    """Label as compared by protocols: subject prefix, NULs, spaces, ``_ - .`` removed, upper
    case, and the side in front as ``L`` or ``R`` where the label writes it as a word or as
    Left/Right (:func:`written_side`): ``ASI_L``, ``Left ASI`` and ``LeftASI`` are ``LASI``,
    so that labs' side conventions match one protocol.

    >>> normalise_label("Bastian:L_Sho ")
    'LSHO'
    >>> normalise_label("ASI_R"), normalise_label("LeftKnee")
    ('RASI', 'LKNEE')
    """
    side, rest = written_side(label)
    return (side or "") + rest


@dataclass(frozen=True)
class Event:
    """One gait event as stored in a C3D EVENT group (or detected).

    ``context`` is the side as written by the lab ("Left", "Right", "General"); ``label`` the
    event name ("Foot Strike", "Foot Off", ...); ``time_s`` seconds from the start of the
    recording as the lab's software counts it (frame ``first_frame`` is at
    ``(first_frame-1)/rate``).
    """

    context: str
    label: str
    time_s: float


@dataclass
class Trial:
    """One capture: labelled markers over time.

    Attributes
    ----------
    markers : ndarray, shape (F, M, 3), float64
        Marker positions in metres, world frame Z up; NaN where missing.
    labels : list[str], length M
        Labels as found in the file (NULs and padding stripped).
    rate : float
        Frame rate in Hz (> 0).
    first_frame : int
        Number of the first frame as stored in the file (usually 1).
    units : str
        POINT:UNITS as found in the file (``"mm"``, ``"m"``...), before conversion.
    vertical_axis : str
        The file's vertical axis as detected: ``"Z"``, ``"Y"`` or ``"X"`` (``markers`` is
        always Z up).
    events : list[Event]
        Events from the file's EVENT group, sorted by time.
    source : str or None
        Path of the file the trial was read from.
    warnings : list[str]
        Things a technician should know (duplicate labels, dropped points, axis rotation...).
    measurements : dict[str, float]
        Subject measurements the file stores (metres, kilograms), keys of
        :data:`mocaplib.model.anatomy.MEASUREMENTS` (``knee_width_l``, ``marker_diameter``...).
    analog_channels : int
        Analog channels the file stores beside the markers (force plates, EMG): only the
        force plates' channels are read, into ``force_plates``.
    force_plates : list[ForcePlate]
        The force plates read from the file (:class:`~mocaplib.io.c3d_analog.ForcePlate`:
        vertical force in newtons at the analog rate, corners in metres in this frame); empty
        for files without plates and for synthetic captures.

    A trial may hold no markers (M = 0: a file of analog channels only); every stage after
    import refuses it (:func:`require_markers`).
    """

    markers: np.ndarray
    labels: list[str]
    rate: float
    first_frame: int = 1
    units: str = "m"
    vertical_axis: str = "Z"
    events: list[Event] = field(default_factory=list)
    source: str | None = None
    warnings: list[str] = field(default_factory=list)
    measurements: dict[str, float] = field(default_factory=dict)
    analog_channels: int = 0
    force_plates: list = field(default_factory=list)

    def __post_init__(self):
        where = self.source
        markers = np.asarray(self.markers, dtype=np.float64)
        if markers.ndim != 3 or markers.shape[2] != 3:
            raise MocapError(f"markers must have shape (F, M, 3), got {markers.shape}", path=where)
        self.labels = [str(label) for label in self.labels]
        if len(self.labels) != markers.shape[1]:
            raise MocapError(
                f"{len(self.labels)} labels for {markers.shape[1]} markers", path=where)
        if not np.isfinite(self.rate) or self.rate <= 0:
            raise MocapError(f"frame rate must be > 0 Hz, got {self.rate}", path=where)
        if self.vertical_axis not in ("Z", "Y", "X"):
            raise MocapError("vertical_axis must be 'Z', 'Y' or 'X', got "
                             f"{self.vertical_axis!r}",
                             path=where)
        if np.isinf(markers).any():
            raise MocapError("markers contain infinite values; missing samples must be NaN",
                             path=where)
        self.markers = markers
        self.rate = float(self.rate)
        self.first_frame = int(self.first_frame)
        self.analog_channels = int(self.analog_channels)
        if self.analog_channels < 0:
            raise MocapError(f"analog_channels must be >= 0, got {self.analog_channels}",
                             path=where)
        self.events = sorted(self.events, key=lambda e: e.time_s)
        if self.source is not None:
            self.source = os.fspath(self.source)

    # ----------------------------------------------------------------- shape and time
    @property
    def n_frames(self) -> int:
        return self.markers.shape[0]

    @property
    def n_markers(self) -> int:
        return self.markers.shape[1]

    @property
    def duration(self) -> float:
        """Seconds from the first to the last frame."""
        return max(self.n_frames - 1, 0) / self.rate

    @property
    def time(self) -> np.ndarray:
        """Time of each frame in seconds from the first frame of the trial, shape (F,)."""
        return np.arange(self.n_frames) / self.rate

    @property
    def start_time(self) -> float:
        """Time of the trial's first frame on the lab's clock (that of ``events``), seconds."""
        return (self.first_frame - 1) / self.rate

    # ----------------------------------------------------------------- labels
    @property
    def names(self) -> list[str]:
        """Normalised labels (see :func:`normalise_label`), length M, not necessarily unique."""
        return [normalise_label(label) for label in self.labels]

    def index(self, label: str) -> int:
        """Index of the first marker whose normalised label equals ``normalise_label(label)``."""
        key = normalise_label(label)
        try:
            return self.names.index(key)
        except ValueError:
            raise MocapError(f"no marker labelled {label!r}", path=self.source,
                             hint=f"labels are: {', '.join(self.labels[:40])}") from None

    def marker(self, label: str) -> np.ndarray:
        """Positions of one marker, shape (F, 3), metres."""
        return self.markers[:, self.index(label), :]

    def gap_fraction(self) -> np.ndarray:
        """Fraction of frames each marker is missing, shape (M,)."""
        if self.n_frames == 0:
            return np.zeros(self.n_markers)
        return np.isnan(self.markers[:, :, 0]).mean(axis=0)

    def longest_gap(self) -> np.ndarray:
        """Longest run of missing frames per marker, shape (M,), in frames."""

        missing = np.isnan(self.markers[:, :, 0])
        return np.array([max((stop - start for start, stop in valid_runs(missing[:, m])),
                             default=0) for m in range(self.n_markers)], dtype=int)


#: Events a cycle may start at besides a left toe-off (``cycle_start``): the other events of
#: one stride, :data:`mocaplib.gait.cycles.STRIDE_EVENTS`.
CYCLE_STARTS = ("left_heel_strike", "right_toe_off", "right_heel_strike")


def require_markers(trial: Trial, /) -> None:
    """Raise :class:`MocapError` naming the trial's file when it holds no marker points
    (M = 0): protocols, calibration, fitting, events and drafts all need markers."""
    if trial.n_markers:
        return
    holds = (f"{trial.analog_channels} analog channels and no marker trajectories: this "
             "looks like an analog-only/force-plate file" if trial.analog_channels else
             "no marker trajectories and no analog channels")
    raise MocapError(f"no marker points: the file holds {holds}", path=trial.source,
                     hint="give the capture's marker file, the C3D holding its POINT data; "
                          "`mocaplib inspect FILE` shows what a file holds")
