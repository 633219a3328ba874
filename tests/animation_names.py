"""A marker set labelled as animation studios' systems label theirs, for the tests and the draft
benchmark: descriptive camel-case names with the side as a word of its own, in front
(``LKneeOut``) or inside (``WaistLFront``), as OptiTrack Motive's and Qualisys's animation
marker sets write them. No shipped protocol knows these labels: a build drafts one
(:mod:`mocaplib.build.drafting`) from the names (``protocols/label_names.toml``) and places.
"""

from __future__ import annotations

from pathlib import Path

#: The protocol such a lab would write by hand: each label on the landmark its name means.
PROTOCOL_NAME = "animation_names"
LANDMARKS = {
    "HeadFront": "FRONT_HEAD", "HeadBack": "BACK_HEAD", "BackTop": "C7", "Chest": "STRN",
    "ChestTop": "CLAV", "SpineThoracic10": "T10", "WaistFront": "ASIS", "WaistBack": "PSIS",
    "ShoulderTop": "ACROMION", "ShoulderBack": "SCAPULA", "UArmHigh": "UPPER_ARM",
    "ElbowOut": "ELBOW_LAT", "WristOut": "WRIST_RAD", "WristIn": "WRIST_ULN",
    "HandOut": "HAND_MC5", "Thigh": "THIGH", "KneeOut": "KNEE_LAT", "KneeIn": "KNEE_MED",
    "Shin": "SHIN", "AnkleOut": "ANKLE_LAT", "AnkleIn": "ANKLE_MED", "Heel": "HEEL",
    "ToeIn": "MT1", "ToeOut": "MT5", "ToeTip": "TOE2",
}
#: Names that carry their side inside them (the rest carry it in front).
INNER_SIDE = {"WaistFront": "Waist{}Front", "WaistBack": "Waist{}Back"}
CENTRAL = {"BackTop", "Chest", "ChestTop", "SpineThoracic10"}
REQUIRED = {"ASIS", "PSIS", "ACROMION", "HEEL"}


def protocol_labels() -> dict[str, str]:
    """{label: landmark} of the protocol (sided landmarks as ``L_``/``R_``)."""
    out = {}
    for name, landmark in LANDMARKS.items():
        if name in CENTRAL:
            out[name] = landmark
            continue
        for side in "LR":
            label = INNER_SIDE[name].format(side) if name in INNER_SIDE else side + name
            out[label] = f"{side}_{landmark}"
    return out


def protocol_toml() -> str:
    """The protocol file's text."""
    lines = [f'name = "{PROTOCOL_NAME}"',
             'description = "descriptive camel-case names of animation marker sets"', "",
             "[markers]"]
    for label, landmark in protocol_labels().items():
        required = ", required = true" if landmark[2:] in REQUIRED else ""
        lines.append(f'{label} = {{ landmark = "{landmark}"{required} }}')
    lines += ["", "[any_of]", 'left_forefoot = ["LToeIn", "LToeOut", "LToeTip"]',
              'right_forefoot = ["RToeIn", "RToeOut", "RToeTip"]', ""]
    return "\n".join(lines)


def write_protocol(folder: Path) -> Path:
    """Write the protocol into ``folder`` (a protocol folder: ``$MOCAPLIB_PROTOCOLS``)."""
    path = Path(folder) / f"{PROTOCOL_NAME}.toml"
    path.write_text(protocol_toml())
    return path


def write_session(folder: Path, *, prefix: str = "Actor:") -> list[Path]:
    """A synthetic session in the protocol (which :func:`write_protocol` must have put in a
    protocol folder): a straight walk, a curve and the static, written as C3D files into
    ``folder`` with ``prefix`` before every label (a subject name, as the systems export)."""
    from mocaplib.io.c3d_write import write_c3d
    from mocaplib.library.command import Command
    from mocaplib.synth.capture import synthesize_capture

    takes = (("walk", Command.from_kind("straight", speed=1.2), 4.0, 1),
             ("curve", Command(1.0, 0.5, 0.0), 5.0, 3),
             ("rest", Command.from_kind("rest"), 2.0, 2))
    paths = []
    for name, command, duration, seed in takes:
        take = synthesize_capture(command, duration=duration, seed=seed,
                                  protocol=PROTOCOL_NAME, session_seed=4)
        paths.append(write_c3d(Path(folder) / f"{name}.c3d", take.trial.markers,
                               [prefix + label for label in take.trial.labels], take.trial.rate))
    return paths
