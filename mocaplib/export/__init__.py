"""Files other programs read, one registry by suffix (:mod:`mocaplib.export.formats`): joint
angles as CSV, BVH for animation software, glTF 2.0 for game engines, and the OpenSim model,
markers and motion."""
