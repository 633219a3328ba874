"""Reading and writing files: C3D import, exports, atomic writes."""
