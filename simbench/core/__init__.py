"""Physics core: constants, frames, GPS time, orbits of every system, atmosphere models.

The bottom layer of simbench: pure functions and small data classes, no file
I/O and no simulation. Everything above (the GNSS measurement model, the
generator, the log readers, the estimators) builds on it.
"""
