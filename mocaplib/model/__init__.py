"""The subject's body: the fixed skeleton and its forward kinematics, anatomical joint centres,
anthropometry, calibration of a subject model from markers, the least-squares pose solver and the
fitted :class:`~mocaplib.model.motion.Motion`."""
