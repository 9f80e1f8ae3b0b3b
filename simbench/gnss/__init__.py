"""The one GNSS measurement core shared by the simulator, the log readers and the estimators.

- :mod:`simbench.gnss.geometry`: range with the Earth-rotation (Sagnac) term and
  its gradient, elevation and azimuth.
- :mod:`simbench.gnss.troposphere`: the modelled slant troposphere terms.
- :mod:`simbench.gnss.doppler`: range rate with the Earth's rotation and its
  gradients, and a Doppler-only velocity and clock-drift fix.
- :mod:`simbench.gnss.arcs`: continuous carrier-phase arcs (gaps and loss-of-lock flags).
- :mod:`simbench.gnss.spp`: weighted single-point solutions of many epochs at
  once, with per-system clocks and a trust check.

Nothing here imports :mod:`estimators`; everything is vectorised over rows
(satellite-epochs) and epochs.
"""
