"""Marker sets: protocols (which label is which landmark on which segment), matching a capture's
labels to a protocol, drafting a protocol for an unknown marker set, and inspecting a capture."""
