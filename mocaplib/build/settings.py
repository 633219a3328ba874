"""The settings of a library build (:class:`BuildSettings`): everything besides the captures
that decides a library's content."""


from __future__ import annotations

import os
from dataclasses import asdict, dataclass, field

from ..errors import MocapError
from ..gait.events import TOE_OFF_DEFINITIONS, EventSettings
from ..gait.qc import DEFAULT_QC_THRESHOLDS
from ..io import unique_paths
from ..library.format import to_json_data
from ..statics import static_names

#: Where a capture's static comes from: named on the command line (``--static``, or the
#: ``static`` of :class:`BuildSettings`), by a ``session.toml``, or found standing among the
#: inputs (:func:`mocaplib.build.sessions.plan_captures`).
STATIC_SOURCES = ("command line", "session.toml", "found among the inputs")

#: The settings a session sets per capture (``[capture."NAME.c3d"]`` in ``session.toml``).
CAPTURE_CHOICE = ("trim", "cycles", "drop_cycles")

#: Largest ``max_gap_s`` (s): an hour, longer than any capture (beyond, the gap's frame count
#: overflows).
MAX_GAP_LIMIT_S = 3600.0


@dataclass(frozen=True)
class BuildSettings:
    """Everything besides the captures that decides a library's content.

    protocol : ``"auto"`` or a protocol name / TOML path (see :mod:`mocaplib.markersets.protocols`).
    static : a static calibration capture, several (one per subject or session: each capture
        is calibrated with the one showing its subject, :func:`mocaplib.model.calibration_checks.choose_static`;
        one that none shows is calibrated from itself, with a warning), or None to calibrate
        from each motion capture. :func:`~mocaplib.build.pipeline.build_library` adds the standing files among its inputs and
        takes a folder's ``session.toml`` for the captures beside it (:mod:`mocaplib.build.sessions`).
    static_window : (start, end) seconds of each static to calibrate on, or None: the whole
        static when it stands still, else its quietest second
        (:func:`mocaplib.statics.standing_part`).
    require_static : a capture that no static shows fails instead of being calibrated from
        itself.
    static_pose : ``"free"`` or ``"neutral"`` (the static subject stands with every joint
        angle 0; see :func:`mocaplib.model.calibration.calibrate`).
    forward_reference : one or several captures in which the subject walks forwards (straight
        or curving, not side-stepping), or None: each turns the heading of the neutral static
        that shows its subject (see :func:`forward_offsets`).
    heading_offsets : per static, the heading correction (radians) the forward references
        measured; None: not measured (:func:`~mocaplib.build.pipeline.build_library` measures it when references are given).
    cutoff : marker low-pass before calibration and fit (:mod:`mocaplib.model.filtering`): Hz,
        ``"auto"`` (Winter's residual analysis per capture) or None (unfiltered).
    toe_off : the toe-off definition that cuts the cycles, ``"foot_velocity"`` (feet that roll
        over their toes, real and synthetic) or ``"lift"`` (rigid feet); see :mod:`mocaplib.gait.events`.
    max_gap_s : the longest gap (s) filled by interpolation: in the foot markers the gait
        events read (:class:`mocaplib.gait.events.EventSettings`) and in the frames the fit could
        not solve inside a cycle (:mod:`mocaplib.gait.cycles`).
    all_cycles : keep every complete cycle, not only the one chosen per activity segment.
    mirror : also add each capture's left-right mirror image (:func:`mirror_entries`).
    qc_policy : ``"drop"`` leaves cycles failing a QC threshold out of the library (with a
        warning); ``"waive"`` keeps them and records the waiver and its reason in the entry.
    qc_thresholds : QC metric -> limit (None = reported only); see
        :data:`mocaplib.gait.qc.QC_LIMITS`.
    measurements : subject measurements (metres, kilograms) overriding those each
        calibration file stores (see :func:`mocaplib.model.calibration.calibrate`).
    keep_non_level : keep the cycles on stairs or slopes (:func:`mocaplib.gait.activity.non_level`),
        flagged in the build's warnings and the cycles' diagnostics (``activity``,
        ``rise_per_step_m``), instead of leaving them out of a level-locomotion library.
    static_sources : per static, where it came from (:data:`STATIC_SOURCES`); None: the
        command line (:func:`mocaplib.build.sessions.plan_captures` sets the others).
    trim : a session's time windows ((start, end) s from the capture's first frame) the
        capture's cycles must lie in, or None for the whole capture.
    cycles : a session's choice of the capture's cycles (indices), replacing the rule of one
        per activity segment; None: the rule.
    drop_cycles : indices of cycles a session leaves out.
    """

    protocol: str = "auto"
    static: str | tuple[str, ...] | None = None
    static_pose: str = "free"
    static_window: tuple[float, float] | None = None
    require_static: bool = False
    forward_reference: str | tuple[str, ...] | None = None
    heading_offsets: tuple[float, ...] | None = None
    cutoff: float | str | None = "auto"
    toe_off: str = "foot_velocity"
    max_gap_s: float = EventSettings.max_gap_s     # mocaplib.gait.cycles.MAX_GAP_S
    all_cycles: bool = False
    mirror: bool = False
    qc_policy: str = "drop"
    qc_thresholds: dict = field(default_factory=lambda: dict(DEFAULT_QC_THRESHOLDS))
    measurements: dict = field(default_factory=dict)
    keep_non_level: bool = False
    static_sources: tuple[str, ...] | None = None
    trim: tuple[tuple[float, float], ...] | None = None
    cycles: tuple[int, ...] | None = None
    drop_cycles: tuple[int, ...] = ()

    def __post_init__(self):
        for name in ("static", "forward_reference"):
            object.__setattr__(self, name, _files(getattr(self, name)))
        if self.static_window is not None:
            window = tuple(map(float, self.static_window))
            if len(window) != 2 or not 0 <= window[0] <= window[1]:
                raise MocapError(f"static_window must be (start, end) seconds with 0 <= start "
                                 f"<= end, got {self.static_window!r}")
            object.__setattr__(self, "static_window", window)
        if self.static_sources is not None:
            object.__setattr__(self, "static_sources", tuple(self.static_sources))
            if len(self.static_sources) != len(self.statics) \
                    or not set(self.static_sources) <= set(STATIC_SOURCES):
                raise MocapError(f"static_sources needs one of {', '.join(STATIC_SOURCES)} per "
                                 f"static ({len(self.statics)}), got {self.static_sources!r}")
        if self.heading_offsets is not None:
            object.__setattr__(self, "heading_offsets", tuple(map(float, self.heading_offsets)))
            if len(self.heading_offsets) != len(self.statics):
                raise MocapError(f"heading_offsets needs one angle per static "
                                 f"({len(self.statics)}), got {len(self.heading_offsets)}")
        if ((self.forward_reference is not None or self.heading_offsets is not None)
                and (not self.statics or self.static_pose != "neutral")):
            raise MocapError("a forward reference turns the heading of a static in the neutral "
                             "pose: give the static, with static_pose 'neutral'")
        if self.toe_off not in TOE_OFF_DEFINITIONS:
            raise MocapError(f"toe_off must be one of {', '.join(TOE_OFF_DEFINITIONS)}, "
                             f"got {self.toe_off!r}")
        if not (isinstance(self.max_gap_s, (int, float))
                and 0 <= self.max_gap_s <= MAX_GAP_LIMIT_S):
            raise MocapError(f"max_gap_s must be a number of seconds from 0 to "
                             f"{MAX_GAP_LIMIT_S:g}, got {self.max_gap_s!r}")
        if self.qc_policy not in ("drop", "waive"):
            raise MocapError(f"qc_policy must be 'drop' or 'waive', got {self.qc_policy!r}")

    @property
    def statics(self) -> tuple[str, ...]:
        """The static trials given: none, one, or one per subject or session."""
        return (self.static,) if isinstance(self.static, str) else self.static or ()

    @property
    def forward_references(self) -> tuple[str, ...]:
        """The forward references given (none, one or several)."""
        return ((self.forward_reference,) if isinstance(self.forward_reference, str)
                else self.forward_reference or ())

    def static_source(self, static: int) -> str:
        """Where static number ``static`` came from (:data:`STATIC_SOURCES`)."""
        return STATIC_SOURCES[0] if self.static_sources is None else self.static_sources[static]

    def heading_offset(self, static: int) -> float:
        """The heading correction (radians) of static number ``static``; 0 when unmeasured."""
        return 0.0 if self.heading_offsets is None else self.heading_offsets[static]

    def to_dict(self) -> dict:
        """The settings as JSON data, as stored in the library (static files and forward
        references by name only: one name, a list of names when several were given, or None;
        a session's per-capture choice, :data:`CAPTURE_CHOICE`, is the capture's provenance's)."""
        data = {key: value for key, value in asdict(self).items() if key not in CAPTURE_CHOICE}

        for key, paths in (("static", self.statics),
                           ("forward_reference", self.forward_references)):
            names = static_names(paths)
            data[key] = names if len(names) > 1 else names[0] if names else None
        return to_json_data(data)


def _files(given) -> str | tuple[str, ...] | None:
    """One path, several (each file once: :func:`mocaplib.io.unique_paths`), or None for none
    or an empty one."""
    if given is None or isinstance(given, (str, os.PathLike)):
        given = () if given is None else (given,)
    paths = tuple(unique_paths(given))
    return paths[0] if len(paths) == 1 else paths or None
