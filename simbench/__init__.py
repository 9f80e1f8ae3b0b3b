"""simbench: simulation-and-benchmark harness for robust GNSS and GNSS/INS estimation.

The notebook entry points are :func:`scenario` (any scenario, simulated or a real log),
:func:`simulate` (a simulated one) and :func:`run` (a study: estimators x seeds, scored,
with a report), all in :mod:`simbench.api`;
the command line is ``python -m simbench`` (:mod:`simbench.cli`, a Hydra app, configs
in the repository's ``conf/``).

Layers, bottom up, each importing only those below it (``tests/test_layering.py``):
``errors``/``typed``/``contract`` (the shared base), :mod:`simbench.core` (physics),
:mod:`simbench.gnss` (measurement model), :mod:`simbench.sim` beside :mod:`simbench.data`
(scenario sources), ``estimators``, :mod:`simbench.analysis`, :mod:`simbench.runs`,
:mod:`simbench.report`, then :mod:`simbench.api` and :mod:`simbench.cli`.
The attributes below load on first use (``lazy_loader``): importing
``simbench.core.frames`` must not load Hydra, GTSAM and every estimator.
"""

from __future__ import annotations

import lazy_loader

__getattr__, __dir__, __all__ = lazy_loader.attach(
    __name__,
    submod_attrs={
        "api": ["scenario", "simulate", "run", "StudyResult"],
        "contract": ["Scenario", "ReceiverData", "NavInfo"],
        "errors": ["SimbenchError"],
    },
)
