"""MkDocs hook: ``<!-- landmark-catalogue -->`` in a page becomes the table of every landmark
of the shipped catalogue (``landmarks.toml``): its name, its mirrored partner, the segment it
sits on, where it sits (the catalogue's description and nominal position), the role the code
reads it for and the label names that point to it (``label_names.toml``), so that the page
cannot drift from the catalogue ``mocaplib protocol draft`` and the protocols use."""

from __future__ import annotations

PLACEHOLDER = "<!-- landmark-catalogue -->"


def on_page_markdown(markdown: str, page, config, files) -> str:
    if PLACEHOLDER not in markdown:
        return markdown
    return markdown.replace(PLACEHOLDER, catalogue_table())


def catalogue_table() -> str:
    """The catalogue as a Markdown table, one row per landmark (a sided pair's left one names
    its right partner); positions in mm in the segment's frame of the 1.75 m subject."""
    from mocaplib.markersets.draft import names
    from mocaplib.markersets.protocols import load_landmarks

    aliases: dict[str, list[str]] = {}
    for stem, keys in names().items():
        for key in keys:
            aliases.setdefault(key, []).append(stem)
    rows = ["| landmark | mirrored partner | segment | where it sits | position x, y, z (mm) "
            "| role | label names |", "|---|---|---|---|---|---|---|"]
    for name, lm in load_landmarks().items():
        sided = name[:2] in ("L_", "R_")
        if name.startswith("R_"):
            continue                                  # the left row names its right partner
        key = name[2:] if sided else name
        position = ", ".join(f"{1000 * v:.0f}" for v in lm.position)
        stems = ", ".join(f"`{s}`" for s in sorted(aliases.get(key, [])))
        rows.append(f"| `{name}` | {f'`R_{key}`' if sided else ''} | {lm.segment} | "
                    f"{lm.description} | {position} | {lm.role or ''} | {stems} |")
    return "\n".join(rows)
