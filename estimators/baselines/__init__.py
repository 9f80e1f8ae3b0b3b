"""Per-epoch single-point baselines: weighted least squares and its robust variants (:mod:`.spp`),
and RTKLIB's ``rnx2rtkp`` (:mod:`.rtklib_spp`)."""
