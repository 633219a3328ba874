"""Files other programs read: joint angles as CSV, BVH for animation software, and the OpenSim
model and motion."""
