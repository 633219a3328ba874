"""The forward reference's heading correction (:func:`forward_offsets`): a capture in which the
subject walks forwards turns the heading of the neutral static that shows its subject.

Angles in radians inside; the limits below in degrees, as people read them.
"""


from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np

from ..errors import CalibrationError, MocapError
from ..gait.qc import qc_failures
from ..model.fitting import StageClock
from ..statics import static_names
from .settings import BuildSettings
from .workflow import CaptureResult, cut_capture

#: A forward reference whose subject faces further than this (degrees) from the direction of
#: travel is refused: that is a side-step or a diagonal (the paper's diagonals start at 60°),
#: not a forward walk. Measured uncorrected: 0.23° on the samples (placement error alone), up
#: to 7.7° on lab walks with their static taken as neutral (docs/guide/patterns.md).
FORWARD_LIMIT_DEG = 15.0


#: A forward reference's cycles slower than this (m/s) show no direction of travel.
MIN_FORWARD_SPEED = 0.3


#: The QC metrics a forward reference's cycles must pass (at the build's thresholds): the
#: marker fit, the gaps and the events, which speak for the shoulder line and the cycle. The
#: marker maximum and the Fourier metrics judge the encoding and would leave out every lab walk
#: at hand with its static taken as neutral (non-periodic arms, one marker 52-60 mm off).
FORWARD_QC = ("marker_rms_m", "gap_fraction", "event_quality")


#: A forward reference's heading correction is repeated until the reference faces its path
#: within this (degrees), at most FORWARD_PASSES times.
FORWARD_TOLERANCE_DEG = 0.01


FORWARD_PASSES = 4


def forward_offsets(settings: BuildSettings) -> tuple[float, ...]:
    """Per static of ``settings``, the heading correction (radians) that its forward references
    measure; 0 for a static that none shows.

    A neutral static fixes the heading of every segment frame by fitting the root to all
    markers at their catalogue positions, so the placement error turns it by a fraction of a
    degree, and v̂_l of every capture is off by about −v̂ times that angle
    (docs/guide/patterns.md). A forward reference — a capture in which the subject walks
    forwards — measures the angle: it is taken through the build's stages with the static that
    shows its subject (:func:`cut_capture`), and the mean of atan2(v̂_l, v̂_f) over its cycles
    (:func:`_facing_angles`) is how far the static's heading must turn for the subject to
    face where they walk. Several references of one static are averaged. The turn is repeated
    on the turned static until each reference faces its path within
    :data:`FORWARD_TOLERANCE_DEG` (one turn leaves 4 % on the samples, 5 % on a lab walk,
    whose poses are further from the static's); the offset is the sum of the turns.
    Raises :class:`~mocaplib.errors.CalibrationError` naming a reference that cannot be
    processed, shows no walking cycle, or faces further than :data:`FORWARD_LIMIT_DEG` from
    its path, or the references when :data:`FORWARD_PASSES` turns do not settle it.
    """

    offsets = tuple(0.0 for _ in settings.statics)
    for _ in range(FORWARD_PASSES):
        residuals = _facing_angles(replace(settings, heading_offsets=offsets))
        offsets = tuple(offset + residual for offset, residual in zip(offsets, residuals))
        if max(map(abs, residuals)) < np.deg2rad(FORWARD_TOLERANCE_DEG):
            return offsets
    unsettled = ", ".join(f"{name} {np.rad2deg(r):+.3f}°" for name, r in
                          zip(static_names(settings.statics), residuals)
                          if abs(r) >= np.deg2rad(FORWARD_TOLERANCE_DEG))
    raise CalibrationError(f"the forward references do not settle the heading of the static: "
                           f"turn {FORWARD_PASSES} of {FORWARD_PASSES} was still {unsettled} "
                           f"(the turns stop below {FORWARD_TOLERANCE_DEG:g}°)",
                           path=", ".join(settings.forward_references),
                           hint="give references whose cycles pass QC steadily (more cycles, "
                                "a better fit), or build without --forward-reference")


def _facing_angles(settings: BuildSettings) -> tuple[float, ...]:
    """Per static, the mean over its forward references of where the subject moves relative
    to where they face (radians, to the left; 0 for a static without a reference): the mean
    atan2(v̂_l, v̂_f) of each reference's complete cycles that are at least
    :data:`MIN_FORWARD_SPEED` fast and pass the build's QC of :data:`FORWARD_QC`. A reference
    is calibrated with the static that shows its subject, never from itself
    (``require_static``)."""

    names = static_names(settings.statics)
    found: list[list[float]] = [[] for _ in names]
    hint = "give a capture in which the subject walks forwards, straight or curving"
    limits = {name: settings.qc_thresholds.get(name) for name in FORWARD_QC}
    for reference in settings.forward_references:
        result = CaptureResult(source=reference)
        try:
            processed = cut_capture(Path(reference), replace(settings, require_static=True),
                                     result, StageClock())
        except OSError as exc:
            raise CalibrationError(f"cannot read the forward reference: {exc.strerror or exc}",
                                   path=reference, hint="check the path") from None
        except MocapError as exc:
            where = "" if exc.path in (None, reference) else f"{exc.path}: "
            own = ("give a forward walk of a subject whose static you pass with --static"
                   if isinstance(exc, CalibrationError) else exc.hint)
            raise CalibrationError(f"the forward reference cannot be processed: "
                                   f"{where}{exc.message}", path=reference,
                                   hint=own or hint) from None
        qcs = processed.qc
        walking = [c for c in processed.cycles if not c.rest and c.velocities.v >= MIN_FORWARD_SPEED]
        failures = {c.index: qc_failures({name: qcs[c.index][name] for name in FORWARD_QC},
                                         limits) for c in walking}
        moving = [c.velocities for c in walking if not failures[c.index]]
        if not moving:
            why = "; ".join(f"cycle {i}: {', '.join(f)}" for i, f in failures.items())
            raise CalibrationError(
                f"the forward reference has no complete gait cycle at {MIN_FORWARD_SPEED} m/s "
                f"or faster that passes QC" + (f" ({why})" if why else ""), path=reference,
                hint="the fit of its markers must pass QC: check the static is this subject's "
                     "and the labels" if why else hint)
        angle = float(np.mean([np.arctan2(c.v_l, c.v_f) for c in moving]))
        if abs(np.rad2deg(angle)) > FORWARD_LIMIT_DEG:
            raise CalibrationError(
                f"in the forward reference the subject moves {abs(np.rad2deg(angle)):.1f}° to "
                f"the {'left' if angle > 0 else 'right'} of where they face (limit "
                f"{FORWARD_LIMIT_DEG:g}°): a side-step or a diagonal, not a forward walk",
                path=reference, hint=hint)
        found[names.index(result.static)].append(angle)
    return tuple(float(np.mean(angles)) if angles else 0.0 for angles in found)
