"""The Continuum Delta Robot: three translator legs and a platform (statics, inverse, atlas)."""
