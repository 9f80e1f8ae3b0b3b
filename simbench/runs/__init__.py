"""The run layer: config composition, one job (a scenario x every estimator), the result store, studies.

Imports the sources (:mod:`simbench.sim`, :mod:`simbench.data`), the estimator
registry and the analysis functions that score a solution; knows nothing of the
report or the command line.
"""
