"""One library entry, typed: :class:`LibraryEntry`, the one definition of an entry's fields.

The library writer (:func:`mocaplib.library.format.assemble_library`) stores ``entry.to_json()`` as
``entries[i]`` of the file, the reader (:class:`mocaplib.library.format.Library`) gives
``LibraryEntry.from_json(entries[i])``, and ``tests/test_entry.py`` checks that the fields are
the properties of the JSON Schema's entry (``mocaplib/schema/library.schema.json``): required
properties are fields without a default, optional ones default to None (or an empty mapping).
Units and meanings are those of ``docs/library-format.md``: SI units (m, s, rad, m/s, rad/s).

``to_json`` gives plain JSON values at full precision (the library file rounds them to 10
significant digits when it is written) and leaves out what the file leaves out: optional keys
that are None or empty, ``mirrored`` unless the entry is a mirror image. ``from_json`` reads
format versions 1 to 3 (version 1 lacks the optional keys, and may lack ``chosen``: read as
True) and ignores the keys it does not know in the objects the format leaves open (an entry,
its ``pattern`` and ``poulaine``: ``open_object``); an unknown key of a closed one is an
error. Numbers are kept as read (an integer stays an integer), lists become tuples, and the
Fourier coefficients numpy arrays.
"""

from __future__ import annotations

from dataclasses import MISSING, dataclass, field, fields

import numpy as np

from ..errors import LibraryError
from ..gait.fourier import RootDrift
from ..gait.poulaine import Poulaine
from ..gait.qc import QC_NAMES
from ..io.jsonvalues import float_or_nan, json_values
from ..trial import CYCLE_STARTS

#: How a mirror image was made: ``capture``, from the capture's fitted motion reflected and cut
#: at its right toe-offs (``build --mirror``: every value measured again); ``series``, from the
#: source entry's stored series shifted to its right toe-off (``mocaplib mirror``: velocities
#: reflected, QC the source's). See :mod:`mocaplib.library.mirror`.
MIRROR_METHODS = ("capture", "series")
#: Keys of an entry's ``root_drift``: the path frame's velocities and its displacement over one
#: cycle (derived from them and T: :meth:`EntryDrift.moving`).
DRIFT_VELOCITIES = ("u_f_m_s", "u_l_m_s", "omega_rad_s")
DRIFT_DISPLACEMENT = ("dx_m", "dy_m", "dheading_rad")


def _tuples(value):
    """JSON lists (and arrays) as nested tuples, other values as they are."""
    if isinstance(value, (list, tuple, np.ndarray)):
        return tuple(_tuples(v) for v in value)
    return value


def _array(values, what: str) -> np.ndarray:
    """Numbers (nested lists or an array; null read as NaN) as a float64 array."""
    try:
        return np.asarray(values, dtype=np.float64)
    except (TypeError, ValueError):
        raise LibraryError(f"Fourier {what} must be rows of numbers of one length") from None


def _keys(data: dict, cls, where: str) -> dict:
    """``data``'s values for ``cls``'s fields; LibraryError naming ``where`` for a required
    key missing or, when ``cls.open_object`` is False, a key the format does not have (an open
    object's unknown keys, a later version's additions, are left out)."""
    names = {f.name: f for f in fields(cls)}
    unknown = [] if cls.open_object else sorted(set(data) - set(names))
    required = [name for name, f in names.items()
                if f.default is MISSING and f.default_factory is MISSING]
    missing = [name for name in required if name not in data]
    if unknown or missing:
        raise LibraryError(f"{where}: " + "; ".join(
            ([f"unknown keys {', '.join(unknown)}"] if unknown else [])
            + ([f"missing keys {', '.join(missing)}"] if missing else [])),
            hint="see docs/library-format.md for an entry's keys")
    return {name: data[name] for name in names if name in data}


class _Record:
    """A record whose fields are its JSON keys: ``to_json`` and ``from_json`` as they are."""

    #: Whether later format versions may add keys to the object (docs/library-format.md,
    #: *Unknown keys*): read ignoring them; a closed object's unknown key is refused.
    open_object = False

    def to_json(self) -> dict:
        return json_values({f.name: getattr(self, f.name) for f in fields(self)})

    @classmethod
    def from_json(cls, data: dict, *, where: str | None = None):
        """The record of ``data``; LibraryError naming ``where`` for a key missing or unknown."""
        return cls(**_keys(data, cls, where or cls.__name__))


@dataclass(frozen=True)
class EntryPattern(_Record):
    """The line, arc or point fitted to the shoulder-midpoint path of the cycle
    (``entries[i].pattern``; :class:`mocaplib.gait.patterns.Pattern` as stored).

    Attributes
    ----------
    type : str
        ``"line"``, ``"arc"`` or ``"point"`` (turning on the spot).
    parameters : dict
        line: ``point`` [x, y] m, ``direction`` [x, y] unit vector along the motion, ``length``
        m; arc: ``centre`` [x, y] m, ``radius`` m, ``turn`` +1 counter-clockwise / −1 clockwise,
        ``length`` m; point: ``point`` [x, y] m, ``length`` m.
    residual_m : float | None
        RMS distance of the path from the pattern, m (None: not computed).
    arc_angle_rad : float | None
        Signed angle turned along the pattern, rad (0 for line and point; None: not computed).
    """

    open_object = True

    type: str
    parameters: dict
    residual_m: float | None
    arc_angle_rad: float | None


@dataclass(frozen=True, eq=False)
class EntryFourier(_Record):
    """The cycle's Fourier series (``entries[i].fourier``): ``q_d(t) = a[d, 0] + Σ_k a[d, k]
    cos(2πkτ/T) + b[d, k] sin(2πkτ/T) + ramp[d]·τ/T``, τ = t mod T with t in s from the cycle
    start, in the DOF's unit (rad, m for ``pelvis_t*``); ``ramp`` 0 when not stored
    (:meth:`mocaplib.library.format.Library.angles`).

    Attributes
    ----------
    n : int
        The order fitted: columns after ``n`` are zero padding.
    a : np.ndarray
        Cosine coefficients, shape (D, N+1), row d the DOF ``skeleton.dof_names[d]``.
    b : np.ndarray
        Sine coefficients, shape (D, N+1), ``b[:, 0] = 0``.
    ramp : np.ndarray | None
        Each DOF's change (D,) from the cycle's start to its end, taken out before encoding
        (:class:`mocaplib.gait.fourier.CycleEncoding`); None when not stored (older files).
    """

    n: int
    a: np.ndarray
    b: np.ndarray
    ramp: np.ndarray | None = None

    def __post_init__(self):
        a, b = _array(self.a, "a"), _array(self.b, "b")
        if a.ndim != 2 or a.shape != b.shape or a.shape[1] < 1:
            raise LibraryError(f"Fourier a and b must both have shape (D, N+1), got {a.shape} "
                               f"and {b.shape}")
        object.__setattr__(self, "a", a)
        object.__setattr__(self, "b", b)
        if self.ramp is not None:
            object.__setattr__(self, "ramp", _array(self.ramp, "ramp"))

    @classmethod
    def of(cls, a: np.ndarray, b: np.ndarray, *, ramp: np.ndarray | None = None
           ) -> "EntryFourier":
        """The series of coefficients ``a``, ``b`` (D, N+1) fitted to order N."""
        return cls(np.shape(a)[1] - 1, a, b, ramp)

    def padded(self, n_harmonics: int) -> "EntryFourier":
        """The same series as ``n_harmonics + 1`` columns (``n_harmonics`` >= ``n``): zero
        columns added, or the zero columns beyond ``n`` dropped (an entry taken from a library
        of larger N); exact: a file's entries share one N."""
        width = n_harmonics + 1
        extra = ((0, 0), (0, max(0, width - self.a.shape[1])))
        return EntryFourier(self.n, np.pad(self.a, extra)[:, :width],
                            np.pad(self.b, extra)[:, :width], self.ramp)

    def __eq__(self, other) -> bool:
        if not isinstance(other, EntryFourier):
            return NotImplemented
        same = (self.ramp is None) == (other.ramp is None) and (
            self.ramp is None or np.array_equal(self.ramp, other.ramp, equal_nan=True))
        return (self.n == other.n and same and np.array_equal(self.a, other.a, equal_nan=True)
                and np.array_equal(self.b, other.b, equal_nan=True))

    def to_json(self) -> dict:
        data = {"n": self.n, "a": self.a, "b": self.b}
        if self.ramp is not None:
            data["ramp"] = self.ramp
        return json_values(data)


@dataclass(frozen=True)
class EntryDrift(_Record):
    """The path frame's motion over one cycle (``entries[i].root_drift``; the root's horizontal
    channels are stored in that frame: :class:`mocaplib.gait.fourier.RootDrift`).

    Attributes
    ----------
    dx_m : float
        Displacement over one cycle, forward, in the frame at the cycle start, m.
    dy_m : float
        Displacement over one cycle, to the left, in the frame at the cycle start, m.
    dheading_rad : float
        Heading change over one cycle (= ``omega_rad_s``·T), rad, > 0 turns left.
    u_f_m_s : float
        The frame's constant forward velocity in its own axes, m/s.
    u_l_m_s : float
        The frame's constant leftward velocity in its own axes, m/s.
    omega_rad_s : float
        The frame's constant turn rate, rad/s.
    """

    dx_m: float
    dy_m: float
    dheading_rad: float
    u_f_m_s: float
    u_l_m_s: float
    omega_rad_s: float

    @property
    def velocities(self) -> tuple[float, float, float]:
        """The frame's (u_f m/s, u_l m/s, ω rad/s): :data:`DRIFT_VELOCITIES`."""
        return self.u_f_m_s, self.u_l_m_s, self.omega_rad_s

    @classmethod
    def moving(cls, u_f_m_s: float, u_l_m_s: float, omega_rad_s: float, T: float
               ) -> "EntryDrift":
        """The drift of a frame moving with these velocities for ``T`` s (its displacement:
        :func:`drift_displacement`)."""
        velocities = {"u_f_m_s": u_f_m_s, "u_l_m_s": u_l_m_s, "omega_rad_s": omega_rad_s}
        return cls(**drift_displacement(velocities, T), **velocities)


def drift_displacement(drift: dict, T: float) -> dict:
    """``dx_m``, ``dy_m`` (m, forward and left in the frame at the cycle start) and
    ``dheading_rad`` of the path frame moving for ``T`` s with an entry's root-drift velocities
    (:data:`DRIFT_VELOCITIES`; see :class:`mocaplib.gait.fourier.RootDrift`)."""

    velocities = [[float_or_nan(drift[key]) for key in DRIFT_VELOCITIES]]
    moved = drift_displacements(velocities, [float_or_nan(T)])[0]
    return {key: float(value) for key, value in zip(DRIFT_DISPLACEMENT, moved)}


def drift_displacements(velocities, T, /) -> np.ndarray:
    """:func:`drift_displacement` of many entries at once: (E, 3) in
    :data:`DRIFT_DISPLACEMENT` order (m, m, rad), for velocities (E, 3) in
    :data:`DRIFT_VELOCITIES` order (m/s, m/s, rad/s) and periods ``T`` (E,) s."""
    velocities = np.asarray(velocities, dtype=np.float64).reshape(-1, 3)
    return np.column_stack(RootDrift(0.0, 0.0, 0.0, *velocities.T).frame(
        np.asarray(T, dtype=np.float64)))


@dataclass(frozen=True)
class EntryAnkle(_Record):
    """One ankle's poulaine model as stored (``poulaine.left`` / ``poulaine.right``;
    :class:`mocaplib.gait.poulaine.AnklePath`).

    Attributes
    ----------
    kinds : tuple[str, ...]
        The four characteristic points in the order the ankle meets them (``highest``,
        ``foremost``, ``under_pelvis``, ``rearmost``, each once).
    phases : tuple[float, ...]
        Phase t/T of each point, (4,), in [0, 1), increasing.
    points_m : tuple[tuple[float, ...], ...]
        The points, (4, 3) m, in the travel frame.
    tangents_m : tuple[tuple[tuple[float, ...], ...], ...]
        Segment k's start and end tangents, (4, 2, 3) m.
    timing : tuple[tuple[float, ...], ...]
        Segment k's speed profile, (4, J) numbers in [0, 1] rising.
    fit_rms_m : float | None
        RMS distance from the measured ankle positions to the curve, m.
    fit_max_m : float | None
        Largest distance from the measured ankle positions to the curve, m.
    timed_rms_m : float | None
        RMS distance between each measured position and the model at its phase, m.
    """

    kinds: tuple[str, ...]
    phases: tuple[float, ...]
    points_m: tuple[tuple[float, ...], ...]
    tangents_m: tuple[tuple[tuple[float, ...], ...], ...]
    timing: tuple[tuple[float, ...], ...]
    fit_rms_m: float | None
    fit_max_m: float | None
    timed_rms_m: float | None

    @classmethod
    def from_json(cls, data: dict, *, where: str | None = None) -> "EntryAnkle":
        return cls(**{k: _tuples(v) for k, v in _keys(data, cls, where or "ankle").items()})


@dataclass(frozen=True)
class EntryPoulaine(_Record):
    """Each ankle centre's path over the cycle in the pelvis-centred travel frame
    (``entries[i].poulaine``; :class:`mocaplib.gait.poulaine.Poulaine` as stored).

    Attributes
    ----------
    travel_rad : float
        β, the direction of travel in the path frame, rad counter-clockwise.
    step_length_m : float
        Mean over both ankles of x(foremost) − x(rearmost), m.
    foot_spacing_m : float
        y(under_pelvis) of the left ankle minus that of the right one, m.
    stance_m : float
        −mean z(under_pelvis) of both ankles: the pelvis-to-ankle height in support, m.
    left, right : EntryAnkle
        Each ankle's model.
    """

    open_object = True

    travel_rad: float
    step_length_m: float
    foot_spacing_m: float
    stance_m: float
    left: EntryAnkle
    right: EntryAnkle

    @classmethod
    def of(cls, poulaine) -> "EntryPoulaine":
        """The record of a :class:`mocaplib.gait.poulaine.Poulaine`."""
        return cls.from_json(json_values(poulaine.to_dict()))

    def model(self):
        """The :class:`mocaplib.gait.poulaine.Poulaine` this record stores."""

        return Poulaine.from_dict(self.to_json())

    def to_json(self) -> dict:
        return json_values({"travel_rad": self.travel_rad, "step_length_m": self.step_length_m,
                            "foot_spacing_m": self.foot_spacing_m, "stance_m": self.stance_m,
                            "left": self.left.to_json(), "right": self.right.to_json()})

    @classmethod
    def from_json(cls, data: dict, *, where: str | None = None) -> "EntryPoulaine":
        where = where or "poulaine"
        values = _keys(data, cls, where)
        for side in ("left", "right"):
            values[side] = EntryAnkle.from_json(values[side], where=f"{where}.{side}")
        return cls(**values)


@dataclass(frozen=True, kw_only=True)
class LibraryEntry:
    """One entry of a motion library: a locomotion cycle, its average velocities (its point
    in the control space) and the Fourier series of every DOF, with the quality metrics that
    justify keeping it (``entries[i]`` of the file; ``docs/library-format.md``).

    Fields without a default are the schema's required keys; the others are optional in the
    file. Construction checks what the schema cannot hold together (raises
    :class:`~mocaplib.errors.LibraryError` naming the entry): QC metric names, a mirror
    image's ``mirror_of`` with its ``mirror_method``.

    Attributes
    ----------
    id : str
        Unique id, ``<capture stem>_c<cycle index>`` (``_mirror`` before ``_c`` for a mirror
        image, ``@<sha256 prefix>`` after it when two captures share a name).
    locomotion_class : str | None
        The planned class of locomotion (``"rest"`` for a standing capture), or None.
    source_file : str
        The capture's file name, without its folder.
    source_sha256 : str
        SHA-256 of the capture's bytes, 64 lower-case hex digits.
    cycle_index : int
        The cycle's index among the capture's complete cycles (the id's ``_c<k>``).
    start_s : float
        Cycle start, s from the capture's first frame (a left toe-off; 0 for rest).
    end_s : float
        Cycle end, s from the capture's first frame (the next left toe-off).
    T : float | None
        Period, s (``end_s − start_s``; 1 s nominal for rest).
    pattern : EntryPattern
        The path pattern of the cycle's shoulder midpoint.
    v : float | None
        Average tangential velocity v̂, m/s (≥ 0).
    omega : float | None
        Average angular velocity ω̂, rad/s, > 0 turns left.
    v_l : float | None
        Average lateral velocity v̂_l = v̂·sin(θ_T − θ_S), m/s, > 0 moves to the person's left.
    v_f : float | None
        Average forward velocity v̂_f = v̂·cos(θ_T − θ_S), m/s (< 0: walking backwards).
    fourier : EntryFourier
        The Fourier series of every DOF.
    root_drift : EntryDrift
        The path frame's motion over the cycle.
    qc : dict[str, float | None]
        QC metric (:data:`QC_NAMES`) -> value (None: not computable); a metric absent is not
        computed (older files).
    qc_waived : dict[str, str]
        QC metric -> why it is accepted outside its threshold.
    chosen : bool
        The capture's chosen cycle (the one a controller blends); missing in a file reads True.
    rate_hz : float | None
        The capture's frame rate, Hz.
    first_frame : int | None
        The capture's first C3D frame number: time t is frame ``first_frame + t·rate_hz``.
    right_toe_off_s : float | None
        The first right toe-off inside the cycle, s from its start (where its mirror image
        starts).
    cycle_start : str | None
        The event the cycle starts and ends at when it is not a left toe-off
        (:data:`mocaplib.gait.cycles.STRIDE_EVENTS`: the protocol's fallback for a capture that
        shows fewer than two left toe-offs); None: a left toe-off.
    left_toe_off_s : float | None
        With ``cycle_start``: the left toe-off inside the cycle, s from its start (the phase
        the series reach the left toe-off at is ``left_toe_off_s / T``:
        :func:`mocaplib.library.phase.from_left_toe_off`).
    mirror_of : str | None
        For a mirror image: the id of the entry it mirrors (:mod:`mocaplib.library.mirror`).
    mirror_method : str | None
        How the mirror image was made (:data:`MIRROR_METHODS`).
    segment_lengths_m : dict[str, float] | None
        The subject's segment lengths, name -> m (:attr:`mocaplib.skeleton.Skeleton.lengths`).
    poulaine : EntryPoulaine | None
        Each ankle's path over the cycle (None: rest, or a file written before poulaines).
    joint_shifts_m : dict[str, tuple[float, float, float]]
        Segment -> (x, y, z) m its joint centre lies from where the lengths put it.
    held_dofs : dict[str, float]
        DOF held at 0 -> the standard deviation (rad) one frame's markers would leave it at.
    dofs_at_limit : dict[str, float | None]
        DOF -> share of the cycle's frames it spends at a joint limit.
    """

    #: Later format versions may add keys to an entry: they are read ignoring them.
    open_object = True

    id: str
    locomotion_class: str | None
    source_file: str
    source_sha256: str
    cycle_index: int
    start_s: float
    end_s: float
    T: float | None
    pattern: EntryPattern
    v: float | None
    omega: float | None
    v_l: float | None
    v_f: float | None
    fourier: EntryFourier
    root_drift: EntryDrift
    qc: dict[str, float | None]
    qc_waived: dict[str, str]
    chosen: bool = True
    rate_hz: float | None = None
    first_frame: int | None = None
    right_toe_off_s: float | None = None
    cycle_start: str | None = None
    left_toe_off_s: float | None = None
    mirror_of: str | None = None
    mirror_method: str | None = None
    segment_lengths_m: dict[str, float] | None = None
    poulaine: EntryPoulaine | None = None
    joint_shifts_m: dict[str, tuple[float, float, float]] = field(default_factory=dict)
    held_dofs: dict[str, float] = field(default_factory=dict)
    dofs_at_limit: dict[str, float | None] = field(default_factory=dict)

    def __post_init__(self):
        unknown = sorted(set(self.qc) - set(QC_NAMES) | set(self.qc_waived) - set(QC_NAMES))
        if unknown:
            raise LibraryError(f"entry {self.id}: unknown QC metrics {unknown}; known are "
                               f"{', '.join(QC_NAMES)}")
        if (self.mirror_of is None) != (self.mirror_method is None) or \
                self.mirror_method not in (None, *MIRROR_METHODS):
            raise LibraryError(f"entry {self.id}: a mirror image needs both mirror_of and "
                               f"mirror_method (one of {', '.join(MIRROR_METHODS)}), got "
                               f"{self.mirror_of!r} and {self.mirror_method!r}")
        if (self.cycle_start is None) != (self.left_toe_off_s is None) or \
                self.cycle_start not in (None, *CYCLE_STARTS):
            raise LibraryError(f"entry {self.id}: a cycle that does not start at a left toe-off "
                               f"needs both cycle_start (one of {', '.join(CYCLE_STARTS)}) and "
                               f"left_toe_off_s, got {self.cycle_start!r} and "
                               f"{self.left_toe_off_s!r}")
        object.__setattr__(self, "joint_shifts_m",
                           {k: _tuples(v) for k, v in self.joint_shifts_m.items()})

    @property
    def mirrored(self) -> bool:
        """Whether the entry is a left-right mirror image (of ``mirror_of``)."""
        return self.mirror_of is not None

    @property
    def velocity(self) -> tuple[float | None, float | None, float | None]:
        """The entry's point in the control space: (v̂ m/s, ω̂ rad/s, v̂_l m/s)."""
        return self.v, self.omega, self.v_l

    def to_json(self) -> dict:
        """The entry as the file stores it (plain JSON values, full precision)."""
        data = {f.name: getattr(self, f.name) for f in fields(self)}
        for key in ("pattern", "fourier", "root_drift", "poulaine"):
            data[key] = None if data[key] is None else data[key].to_json()
        data = {key: value for key, value in data.items()
                if value is not None or key in _NULLABLE_REQUIRED}
        data = {key: value for key, value in data.items()
                if key not in ("joint_shifts_m", "held_dofs", "dofs_at_limit") or value}
        if self.mirrored:
            data["mirrored"] = True
        return json_values(data)

    @classmethod
    def from_json(cls, data: dict) -> "LibraryEntry":
        """The entry of ``entries[i]`` of a library file (format versions 1 to 3), ignoring
        keys of a later version in the open objects; raises
        :class:`~mocaplib.errors.LibraryError` naming the entry for a key missing, or unknown
        in a closed object (``fourier``, ``root_drift``, an ankle's path)."""
        where = f"entry {data.get('id', '(no id)')}"
        data = dict(data)
        mirrored = data.pop("mirrored", False)
        values = _keys(data, cls, where)
        if bool(mirrored) != (values.get("mirror_of") is not None):
            raise LibraryError(f"{where}: mirrored is {mirrored!r} but mirror_of is "
                               f"{values.get('mirror_of')!r}",
                               hint="a mirror image has both, any other entry neither")
        values["pattern"] = EntryPattern.from_json(values["pattern"], where=f"{where}.pattern")
        values["fourier"] = EntryFourier.from_json(values["fourier"], where=f"{where}.fourier")
        values["root_drift"] = EntryDrift.from_json(values["root_drift"],
                                                    where=f"{where}.root_drift")
        if values.get("poulaine") is not None:
            values["poulaine"] = EntryPoulaine.from_json(values["poulaine"],
                                                         where=f"{where}.poulaine")
        return cls(**values)


#: Required keys whose value may be null (written even when None).
_NULLABLE_REQUIRED = ("locomotion_class", "T", "v", "omega", "v_l", "v_f")
