"""Building a library: one capture through every stage (:mod:`.workflow`), the batch over many
(:mod:`.pipeline`: local worker processes or Dask), the per-capture cache, session files and the
build's settings."""
