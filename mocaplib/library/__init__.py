"""The motion library: entries, the library file (format, schema, checksum), the control space and
blending, mirroring and retargeting."""
